"""Motor figures: a scripted episode's reversals, mean |duty|, duty variation and heat
counted by hand, in the single and the vector environment, and the shipped policy's
against `host-sim eval`'s row for the same seed and scenario."""

import json

import gymnasium as gym
import numpy as np
import pytest

import cartpole_ddqn

from conftest import run

NAMES = ("reversals_per_s", "mean_abs_duty", "duty_tv_per_s", "heat")
LEVELS = [-1.0, -0.2, -0.05, 0.0, 0.2, 1.0]
# Ten periods of 0.02 s that leave the pole up: the duties 1, 1, -0.2, 0, 0.2, -1, 0, -0.05,
# 0.2, 1.
SCRIPT = [5, 5, 1, 3, 4, 0, 3, 2, 4, 5]
# By hand: pushes of a tenth of full duty or more change direction at -0.2 (after 1), 0.2
# (after -0.2, the 0 between is no direction), -1, and 0.2 (after -1; -0.05 is too small
# to count): 4 reversals in 0.2 s. |duty| sums to 4.65 over 10 periods. The duty changes
# by 1, 0, 1.2, 0.2, 0.2, 1.2, 1, 0.05, 0.25, 0.8 (from 0 before the first): 5.9 in 0.2 s.
# Gymnasium's machine has no motor damping, so the current is the duty: heat is the mean
# of its squares, 4.1225 / 10.
BY_HAND = {"reversals_per_s": 20.0, "mean_abs_duty": 0.465, "duty_tv_per_s": 29.5, "heat": 0.41225}


def test_a_scripted_episodes_figures_are_the_hand_counted_ones():
    env = cartpole_ddqn.TwinEnv(levels=LEVELS, max_episode_steps=len(SCRIPT))
    env.reset(seed=0)
    for k, a in enumerate(SCRIPT):
        _, _, terminated, truncated, info = env.step(a)
        assert info["duty"] == pytest.approx(LEVELS[a], abs=1e-7)
        if k < len(SCRIPT) - 1:
            assert not (terminated or truncated) and not set(NAMES) & set(info)
    assert truncated and not terminated
    for name in NAMES:
        assert info[name] == pytest.approx(BY_HAND[name], rel=1e-6), name


def test_under_gymnasiums_time_limit_the_figures_are_the_envs_motor():
    """`gymnasium.make` truncates with its own wrapper, unseen by the environment: `info`
    has no figures then, `env.unwrapped.motor` has them."""
    env = gym.make("cartpole_ddqn/Twin-v0", levels=LEVELS, max_episode_steps=len(SCRIPT))
    env.reset(seed=0)
    for a in SCRIPT:
        _, _, terminated, truncated, info = env.step(a)
    assert truncated and not terminated and not set(NAMES) & set(info)
    motor = env.unwrapped.motor
    assert set(motor) == set(NAMES)
    for name in NAMES:
        assert motor[name] == pytest.approx(BY_HAND[name], rel=1e-6), name


def test_the_vector_env_reports_an_ended_worlds_figures_masked():
    venv = cartpole_ddqn.TwinVectorEnv(num_envs=2, levels=LEVELS, max_episode_steps=len(SCRIPT))
    venv.reset(seed=[0, 1])
    for k, a in enumerate(SCRIPT):
        # World 1 only coasts: no reversal, no duty, no heat.
        _, _, terminated, truncated, info = venv.step(np.array([a, 3]))
        assert info["duty"] == pytest.approx([LEVELS[a], 0.0], abs=1e-7)
        if k < len(SCRIPT) - 1:
            assert not set(NAMES) & set(info)
    assert list(truncated) == [True, True]
    for name in NAMES:
        assert list(info["_" + name]) == [True, True]
        assert info[name] == pytest.approx([BY_HAND[name], 0.0], rel=1e-6, abs=1e-12), name


def test_the_shipped_policys_figures_are_evals(tools):
    """Episode by episode through the environment, averaged, against the row of `host-sim
    eval --json` for the same seed and scenario (pushes, noise and dead time, so the motor
    reverses and varies)."""
    scenario, horizon, seed, count = "noise+delay=2+push", 400, 2, 8
    args = ["--scenario", scenario, "--episodes", count, "--horizon", horizon, "--seed", seed]
    row = json.loads(run(tools["host-sim"], "eval", "--controller", "policy", "--json", *args))["rows"][0]
    policy = cartpole_ddqn.shipped()
    env = cartpole_ddqn.TwinEnv(scenario=scenario, max_episode_steps=horizon)
    figures = []
    obs, _ = env.reset(seed=seed)
    for e in range(count):
        if e:
            obs, _ = env.reset()
        while True:
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            if terminated or truncated:
                break
        figures.append([info[name] for name in NAMES])
    means = np.mean(figures, axis=0)
    for k, name in enumerate(NAMES):
        assert means[k] == pytest.approx(row[name]["mean"], rel=1e-12), name
    assert row["reversals_per_s"]["mean"] > 0 and row["duty_tv_per_s"]["mean"] > 0
    # evaluate() gives the same row, motor figures included.
    got = cartpole_ddqn.evaluate(scenario=scenario, episodes=count, horizon=horizon, seed=seed)[0]
    assert {name: got[name] for name in NAMES} == {name: row[name] for name in NAMES}
