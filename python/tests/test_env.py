"""The single environment: Gymnasium's CartPole on Gymnasium's machine, the env checker,
seeding, the time limit and refused arguments."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import cartpole_ddqn  # noqa: F401  (registers the environment)

from conftest import REPO

ID = "cartpole_ddqn/Twin-v0"


@pytest.mark.parametrize("seed", [0, 1, 7, 42])
def test_nominal_is_gymnasiums_cartpole_bit_for_bit(seed):
    twin = gym.make(ID, scenario="nominal", max_episode_steps=500)
    gym_env = gym.make("CartPole-v1")
    obs, _ = twin.reset(seed=seed)
    gym_env.reset(seed=seed)
    gym_env.unwrapped.state = twin.unwrapped.state.copy()
    actions = np.random.default_rng(seed).integers(0, 2, size=500)
    steps = 0
    for a in actions:
        got = twin.step(int(a))
        want = gym_env.step(int(a))
        assert np.array_equal(got[0], want[0]) and got[0].dtype == want[0].dtype
        assert got[1:4] == want[1:4]
        assert np.array_equal(twin.unwrapped.state, np.asarray(gym_env.unwrapped.state, dtype=np.float64))
        steps += 1
        if got[2] or got[3]:
            break
    assert got[2], "a random policy lets the pole fall"
    assert steps > 5


@pytest.mark.parametrize("scenario", ["nominal", "noise+delay=2+push", "encoder=1024", "drop=5"])
def test_env_checker_passes(scenario):
    check_env(gym.make(ID, scenario=scenario).unwrapped, skip_render_check=True)


def trajectory(env, seed, n=200):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    rng = np.random.default_rng(123)
    for _ in range(n):
        obs, r, term, trunc, _ = env.step(int(rng.integers(2)))
        out.append(obs)
        if term or trunc:
            obs, _ = env.reset()
            out.append(obs)
    return np.array(out)


def test_same_seed_same_trajectory_other_seed_another():
    spec = dict(scenario="noise+delay=2+push", max_episode_steps=50)
    a = trajectory(gym.make(ID, **spec), 5)
    b = trajectory(gym.make(ID, **spec), 5)
    c = trajectory(gym.make(ID, **spec), 6)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_domain_and_rig_worlds_differ_per_episode_and_seed_reproducibly():
    spec = dict(domain="length=0.5..1.6+delay=0..3", max_episode_steps=30)
    assert np.array_equal(trajectory(gym.make(ID, **spec), 2), trajectory(gym.make(ID, **spec), 2))
    desk = trajectory(gym.make(ID, rig=REPO / "rigs" / "desk.toml", max_episode_steps=30), 2)
    gymnasium_machine = trajectory(gym.make(ID, max_episode_steps=30), 2)
    assert desk.shape == gymnasium_machine.shape and not np.array_equal(desk, gymnasium_machine)


def test_time_limit_truncates():
    env = gym.make(ID, scenario="nominal", max_episode_steps=5)
    env.reset(seed=0)
    flags = [env.step(i % 2)[2:4] for i in range(5)]
    assert flags[-1] == (False, True) and all(f == (False, False) for f in flags[:-1])


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(scenario="wobble=3"), "wobble"),
        (dict(scenario="delay=99"), "delay"),
        (dict(scenario="noise", domain="length=0.5..1"), "not both"),
        (dict(domain="length=0.0001..9"), "length"),
        (dict(max_episode_steps=0), "max_episode_steps"),
        (dict(rig="/nonexistent/rig.toml"), "rig.toml"),
    ],
)
def test_bad_arguments_raise_value_error_naming_them(kwargs, words):
    with pytest.raises(ValueError, match=words):
        cartpole_ddqn.TwinEnv(**kwargs)


def test_bad_action_raises_value_error():
    env = cartpole_ddqn.TwinEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="found 2"):
        env.step(2)


def test_gymnasium_does_not_import_the_namespace_itself():
    """Gymnasium 1.4 imports a module named before a colon in the id, and nothing else."""
    env = gym.make("cartpole_ddqn:cartpole_ddqn/Twin-v0")
    assert env.reset(seed=0)[0].shape == (4,)


@pytest.mark.parametrize("make", [cartpole_ddqn.TwinEnv, cartpole_ddqn.SwingUpEnv])
def test_a_seed_past_64_bits_or_a_float_is_refused_naming_seed(make):
    """Gymnasium takes any int of at least 0; the worlds take 64 bits (2**64 raised an
    OverflowError naming nothing)."""
    env = make()
    with pytest.raises(ValueError, match=r"seed must be in \[0, 18446744073709551615\]; found 18446744073709551616"):
        env.reset(seed=2**64)
    with pytest.raises(TypeError, match="seed must be an int"):
        env.reset(seed=1.7)
    assert np.array_equal(env.reset(seed=np.int64(7))[0], env.reset(seed=7)[0])
    assert env.reset(seed=2**64 - 1)[0].shape == env.observation_space.shape


@pytest.mark.parametrize(
    "make",
    [cartpole_ddqn.TwinEnv, cartpole_ddqn.SwingUpEnv, lambda: cartpole_ddqn.TwinVectorEnv(2)],
)
def test_reset_options_are_refused_not_ignored(make):
    env = make()
    with pytest.raises(ValueError, match="^options: expected None"):
        env.reset(seed=1, options={"low": -0.01, "high": 0.01})
    env.reset(seed=1, options=None)
    env.reset(seed=1, options={})


@pytest.mark.parametrize(
    "make, action",
    [
        (cartpole_ddqn.TwinEnv, 0),
        (cartpole_ddqn.SwingUpEnv, 0),
        (lambda: cartpole_ddqn.TwinVectorEnv(2), np.zeros(2, dtype=np.int64)),
    ],
)
def test_a_step_before_reset_or_after_close_is_refused(make, action):
    """As Gymnasium's CartPole asks for reset() first: the twin stepped on from the episode
    its constructor read the world from, or from the last state after close()."""
    env = make()
    with pytest.raises(RuntimeError, match="reset"):
        env.step(action)
    env.reset(seed=0)
    env.step(action)
    env.close()
    with pytest.raises(RuntimeError, match="reset"):
        env.step(action)
    env.reset(seed=0)
    env.step(action)


@pytest.mark.parametrize("make", [cartpole_ddqn.TwinEnv, cartpole_ddqn.SwingUpEnv])
def test_the_state_before_reset_is_refused_as_a_step_is(make):
    """SwingUpEnv raised ValueError where TwinEnv raised RuntimeError."""
    with pytest.raises(RuntimeError, match="reset"):
        make().state
