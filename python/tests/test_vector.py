"""The vector environment: Gymnasium's VectorEnv API with next-step autoreset, each world
the single environment's episodes of its seed."""

import re

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env  # noqa: F401
from gymnasium.vector import AutoresetMode

import cartpole_ddqn

ID = "cartpole_ddqn/Twin-v0"


def test_make_vec_gives_the_native_vector_env():
    env = gym.make_vec(ID, num_envs=8, vectorization_mode="vector_entry_point", scenario="noise")
    assert isinstance(env.unwrapped, cartpole_ddqn.TwinVectorEnv)
    assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    obs, _ = env.reset(seed=0)
    assert obs.shape == (8, 4) and obs.dtype == np.float32
    assert env.observation_space.contains(obs)


def test_autoreset_next_step_matches_single_envs_episode_by_episode():
    n, spec = 3, dict(scenario="noise+delay=2+push", max_episode_steps=20)
    venv = gym.make_vec(ID, num_envs=n, vectorization_mode="vector_entry_point", **spec)
    singles = [gym.make(ID, **spec) for _ in range(n)]
    obs, _ = venv.reset(seed=10)
    want = [s.reset(seed=10 + i)[0] for i, s in enumerate(singles)]
    assert np.array_equal(obs, np.array(want))
    rng = np.random.default_rng(0)
    done = np.zeros(n, dtype=bool)
    autoresets = 0
    for _ in range(120):
        actions = rng.integers(0, 2, size=n)
        obs, reward, term, trunc, _ = venv.step(actions)
        for i, s in enumerate(singles):
            if done[i]:
                # The step after a done: the next episode's first reading, reward 0, not done.
                want_obs, want_r, want_term, want_trunc = s.reset()[0], 0.0, False, False
                autoresets += 1
            else:
                want_obs, want_r, want_term, want_trunc, _ = s.step(int(actions[i]))
            assert np.array_equal(obs[i], want_obs)
            assert (reward[i], term[i], trunc[i]) == (want_r, want_term, want_trunc)
        done = term | trunc
    assert autoresets >= n


def test_same_seed_same_batches():
    def run(seed):
        env = cartpole_ddqn.TwinVectorEnv(num_envs=4, domain="length=0.5..1.6+noise=0..2", max_episode_steps=25)
        out = [env.reset(seed=seed)[0]]
        for k in range(60):
            out.append(env.step(np.full(4, k % 2))[0])
        return np.array(out)

    assert np.array_equal(run(3), run(3))
    assert not np.array_equal(run(3), run(4))


def test_wrong_number_of_actions_is_refused():
    env = cartpole_ddqn.TwinVectorEnv(num_envs=2)
    env.reset(seed=0)
    try:
        env.step(np.zeros(3, dtype=np.int64))
    except ValueError as e:
        assert "2" in str(e) and "3" in str(e)
    else:
        raise AssertionError("three actions for two worlds were taken")


def test_seeds_are_ints_as_gymnasium_takes_them_never_truncated():
    """Float seeds would replay the episodes of the seeds they truncate to, and str seeds
    parse: each is refused naming `seed`, as is a float alone (not a list of seeds) and
    a seed the worlds cannot take."""
    env = cartpole_ddqn.TwinVectorEnv(num_envs=2)
    refused = [([1.7, 2.9], "seed[0] must be an int"), (["5", "6"], "seed[0] must be an int")]
    refused.append(([3, np.float64(4.0)], "seed[1] must be an int"))
    refused += [(s, "seed must be None, an int or a list of 2 ints") for s in (1.7, "56", b"56", {5, 6})]
    for seed, found in refused:
        with pytest.raises(TypeError, match=re.escape(found)):
            env.reset(seed=seed)
    base = "seed (world i takes seed + i) must be in [0, 18446744073709551614]; found "
    for seed, found in ((-1, base + "-1"), (2**64 - 1, base + str(2**64 - 1)), ([0, 2**64], "seed[1] must be in")):
        with pytest.raises(ValueError, match=re.escape(found)):
            env.reset(seed=seed)
    # Exact integers are taken, NumPy's among them; None in a list draws that world's seed.
    want = env.reset(seed=[3, 4])[0]
    for seed in (3, np.int64(3), np.array([3, 4]), [np.uint64(3), 4], range(3, 5)):
        assert np.array_equal(env.reset(seed=seed)[0], want)
    assert np.array_equal(env.reset(seed=[None, 4])[0][1], want[1])
    assert env.reset(seed=2**64 - 2)[0].shape == (2, 4)
