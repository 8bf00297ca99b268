"""Duty levels in the environments: the action space, what each action drives (against
Gymnasium's CartPole pushed with the level's force), the checks `--levels` makes, and a
policy of five levels acting through the environment as `evaluate` runs it."""

import re
from decimal import Decimal
from fractions import Fraction

import gymnasium as gym
import numpy as np
import pytest

import cartpole_ddqn

from conftest import five_outputs, write_safetensors

FIVE = [-1.0, -0.2, 0.0, 0.2, 1.0]


def test_the_default_is_the_papers_two_levels():
    env = cartpole_ddqn.TwinEnv()
    assert env.action_space == gym.spaces.Discrete(2) and env.levels == [-1.0, 1.0]
    venv = cartpole_ddqn.TwinVectorEnv(num_envs=3)
    assert venv.single_action_space == gym.spaces.Discrete(2) and venv.levels == [-1.0, 1.0]


def test_levels_give_the_action_space():
    env = cartpole_ddqn.TwinEnv(levels=FIVE)
    assert env.action_space == gym.spaces.Discrete(5)
    assert env.levels == pytest.approx(FIVE)
    venv = cartpole_ddqn.TwinVectorEnv(num_envs=3, levels=np.array(FIVE))
    assert venv.single_action_space == gym.spaces.Discrete(5)
    assert venv.action_space.shape == (3,)


@pytest.mark.parametrize("seed", [0, 3])
def test_action_i_drives_level_i_as_gymnasiums_cartpole_pushed_with_its_force(seed):
    """On Gymnasium's machine a duty d (thousandths of the bridge's PWM) pushes with d times
    the full force: Gymnasium's CartPole with `force_mag` set to |d| times 10 N, pushing d's
    way, is the reference, bit for bit."""
    env = cartpole_ddqn.TwinEnv(levels=FIVE, max_episode_steps=60)
    ref = gym.make("CartPole-v1").unwrapped
    env.reset(seed=seed)
    ref.reset(seed=seed)
    actions = np.random.default_rng(seed).integers(0, 5, size=60)
    for a in actions:
        level = FIVE[a]
        ref.state = env.state.copy()
        ref.force_mag = 10.0 * abs(level)
        ref.step(int(level > 0))
        _, _, terminated, truncated, info = env.step(int(a))
        assert info["duty"] == np.float32(FIVE[a])
        assert np.array_equal(env.state, np.asarray(ref.state, dtype=np.float64)), a
        if terminated or truncated:
            break


@pytest.mark.parametrize(
    "levels, words",
    [
        ([], "levels.*too few|levels"),
        ([0.5], "levels"),
        ([0.5, 0.2], "levels"),
        ([-1.5, 1.0], "levels"),
        ([float("nan"), 1.0], "levels"),
        # Below float32's least subnormal: narrowed first, a zero that passed.
        ([-1.0, 5e-324], "found 5e-324"),
        ([-1.0, 1e-46], "found 1e-46"),
        # Beyond the full push as given, the full push once narrowed: it passed.
        ([-1.0, 1.0000000001], r"expected within \[-1, 1\], found 1.0000000001"),
    ],
)
def test_bad_levels_raise_value_error_naming_levels(levels, words):
    for make in (lambda: cartpole_ddqn.TwinEnv(levels=levels), lambda: cartpole_ddqn.TwinVectorEnv(2, levels=levels)):
        with pytest.raises(ValueError, match=words):
            make()


@pytest.mark.parametrize(
    "levels, found",
    [
        ("01", "found str '01'"),
        ("left,right", "found str"),
        (b"\x00\x01", "found bytes"),
        ({-1, 1}, "found set"),
        ({-1: "left", 1: "right"}, "found dict"),
        (1, "found int 1"),
        (["-1", "1"], "found the item '-1' (str)"),
        ([np.complex128(-1), 1], "(complex128)"),
    ],
)
def test_levels_that_are_no_list_of_numbers_raise_type_error_naming_levels(tmp_path, levels, found):
    """A str or bytes was read character by character ("01" gave the levels 0 and 1), a
    dict by its keys, a set in no order, and a str level parsed: refused by every entry
    point that takes levels, before anything is read or written."""
    out = tmp_path / "never.rs"
    calls = [
        lambda: cartpole_ddqn.TwinEnv(levels=levels),
        lambda: cartpole_ddqn.TwinVectorEnv(2, levels=levels),
        lambda: cartpole_ddqn.SwingUpEnv(levels=levels),
        lambda: cartpole_ddqn.load(tmp_path / "missing.safetensors", levels=levels),
        lambda: cartpole_ddqn.export(tmp_path / "missing.safetensors", out, levels=levels),
        lambda: cartpole_ddqn.evaluate(episodes=1, horizon=10, levels=levels),
    ]
    for call in calls:
        with pytest.raises(TypeError, match=r"^levels must be a list of duty levels, numbers .*" + re.escape(found)):
            call()
    assert not out.exists()


@pytest.mark.parametrize(
    "item, words",
    [
        (Decimal("1e-400"), "reads as 0 in a float"),
        (Fraction(1, 10**400), "reads as 0 in a float"),
        (10**400, "within float's range"),
    ],
)
def test_a_level_float_cannot_hold_raises_value_error_naming_levels(tmp_path, item, words):
    """Each became a level of 0 (or an OverflowError naming nothing) without a word."""
    out = tmp_path / "never.rs"
    calls = [
        lambda: cartpole_ddqn.TwinEnv(levels=[-1, item, 1]),
        lambda: cartpole_ddqn.load(tmp_path / "missing.safetensors", levels=[-1, item, 1]),
        lambda: cartpole_ddqn.export(tmp_path / "missing.safetensors", out, levels=[-1, item, 1]),
    ]
    for call in calls:
        with pytest.raises(ValueError, match=r"^levels.*" + re.escape(words)):
            call()
    assert not out.exists()


def test_an_action_beyond_the_levels_is_refused():
    env = cartpole_ddqn.TwinEnv(levels=FIVE)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="0 to 4.*found 5"):
        env.step(5)
    venv = cartpole_ddqn.TwinVectorEnv(num_envs=2, levels=FIVE)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="found -1"):
        venv.step(np.array([0, -1]))


def five_level_policy(tmp_path):
    path = tmp_path / "five.safetensors"
    write_safetensors(path, five_outputs(seed=4))
    return cartpole_ddqn.load(path, levels=FIVE)


def test_a_five_level_policy_through_the_env_is_evaluates_row(tmp_path):
    """The policy's choices through the environment, episode by episode, give the row
    `evaluate` (`host-sim eval`'s code) computes: the same periods, failures and motor
    figures, so each action drove the level eval drives for that output."""
    policy = five_level_policy(tmp_path)
    scenario, horizon, seed, count = "noise+delay=2", 300, 5, 6
    env = cartpole_ddqn.TwinEnv(scenario=scenario, max_episode_steps=horizon, levels=policy.levels)
    figures, steps, failures = [], [], 0
    obs, _ = env.reset(seed=seed)
    for e in range(count):
        if e:
            obs, _ = env.reset()
        n = 0
        while True:
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            n += 1
            if terminated or truncated:
                break
        figures.append([info[k] for k in ("reversals_per_s", "mean_abs_duty", "duty_tv_per_s", "heat")])
        steps.append(n)
        failures += terminated
    row = cartpole_ddqn.evaluate(policy, scenario, episodes=count, horizon=horizon, seed=seed)[0]
    assert (sum(steps) / count, failures) == (pytest.approx(row["mean_steps"], rel=1e-12), row["failures"])
    means = np.mean(figures, axis=0)
    for k, name in enumerate(("reversals_per_s", "mean_abs_duty", "duty_tv_per_s", "heat")):
        assert means[k] == pytest.approx(row[name]["mean"], rel=1e-12), name
    assert row["mean_abs_duty"]["mean"] > 0


def test_evaluate_takes_the_policys_levels_and_refuses_others(tmp_path):
    policy = five_level_policy(tmp_path)
    same = cartpole_ddqn.evaluate(policy, episodes=3, horizon=50, levels=FIVE)
    assert same == cartpole_ddqn.evaluate(policy, episodes=3, horizon=50)
    with pytest.raises(ValueError, match=r"levels \[-1, 0, 1\]: the policy drives the duty levels \[-1, -0.2, 0, 0.2, 1\]"):
        cartpole_ddqn.evaluate(policy, episodes=3, levels=[-1, 0, 1])
    with pytest.raises(ValueError, match="levels"):
        cartpole_ddqn.evaluate(episodes=3, levels=FIVE)
