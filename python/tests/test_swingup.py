"""The swing-up environment: the full circle against Gymnasium's CartPole equations and an
independent RK4 of a rig file's continuous world with its dead time, the end-stop margin,
the reward, seeding, the env checker and refused arguments."""

import math
import tomllib

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import cartpole_ddqn

from conftest import REPO

ID = "cartpole_ddqn/SwingUp-v0"
DESK = REPO / "rigs" / "desk.toml"


def test_gymnasiums_machine_swings_through_gymnasiums_equations_bit_for_bit():
    env = cartpole_ddqn.SwingUpEnv()
    gym_env = gym.make("CartPole-v1").unwrapped
    env.reset(seed=3)
    gym_env.reset(seed=3)
    assert math.cos(env.state[2]) < -0.99, "the pole starts hanging"
    gym_env.state = env.state.copy()
    # Gymnasium's CartPole keeps integrating past its angle limit (with a warning): the
    # same equations over the full circle. Pushes back and forth, the cart kept on the track.
    actions = ([1] * 8 + [0] * 16 + [1] * 8) * 4
    with pytest.warns(UserWarning):
        for a in actions:
            _, _, terminated, _, _ = env.step(a)
            gym_env.step(a)
            assert np.array_equal(env.state, np.asarray(gym_env.state, dtype=np.float64))
            assert not terminated
    assert abs(env.state[2] - math.pi) > 0.1, "the pole moved off hanging"


def rig_derivative(rig, s, duty):
    """Gymnasium's cart-pole accelerations with the rig's motor: its stall force times the
    duty less its damping times the cart's speed (frictionless rig)."""
    g, mc, mp = 9.8, rig["cart_mass_kg"], rig["pole_mass_kg"]
    l, act = rig["pole_com_m"], rig["actuator"]
    x, x_dot, th, th_dot = s
    force = act["stall_force_n"] * duty - act["damping_n_s_per_m"] * x_dot
    total = mc + mp
    temp = (force + mp * l * th_dot**2 * math.sin(th)) / total
    th_acc = (g * math.sin(th) - math.cos(th) * temp) / (l * (4 / 3 - mp * math.cos(th) ** 2 / total))
    x_acc = temp - mp * l * th_acc * math.cos(th) / total
    return np.array([x_dot, x_acc, th_dot, th_acc])


def rk4_period(rig, s, duty, substeps=200):
    h = rig["period_s"] / substeps
    for _ in range(substeps):
        k1 = rig_derivative(rig, s, duty)
        k2 = rig_derivative(rig, s + h / 2 * k1, duty)
        k3 = rig_derivative(rig, s + h / 2 * k2, duty)
        k4 = rig_derivative(rig, s + h * k3, duty)
        s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return s


def test_a_rig_swings_as_its_continuous_world_with_its_dead_time():
    rig = tomllib.loads(DESK.read_text())
    assert rig["friction"]["cart_coulomb"] == 0 and rig["friction"]["pivot_viscous_n_m_s"] == 0
    assert rig["dead_time_periods"] == 1
    levels = [-1, -0.4, 0, 0.4, 1]
    env = cartpole_ddqn.SwingUpEnv(rig=str(DESK), levels=levels)
    obs, _ = env.reset(seed=5)
    s = env.state
    assert np.allclose(obs, [s[0], s[1], math.cos(s[2]), math.sin(s[2]), s[3]], atol=1e-6)
    rng = np.random.default_rng(9)
    acting = 0.0  # the motor is off until the first command has crossed the dead time
    for k in range(150):
        a = int(rng.integers(len(levels)))
        obs, reward, terminated, truncated, info = env.step(a)
        assert info["duty"] == pytest.approx(levels[a])
        s = rk4_period(rig, s, acting)
        acting = levels[a]
        assert np.allclose(env.state, s, rtol=0, atol=1e-7), (k, env.state, s)
        assert reward == pytest.approx((1 + math.cos(s[2])) / 2, abs=1e-9)
        assert not truncated
        if terminated:
            break
    assert k > 50


def test_the_episode_ends_as_the_cart_enters_the_end_stop_margin():
    rig = tomllib.loads(DESK.read_text())
    reach = rig["track_half_length_m"] - rig["end_stop_margin_m"]
    env = cartpole_ddqn.SwingUpEnv(rig=str(DESK))
    env.reset(seed=1)
    for k in range(500):
        obs, _, terminated, truncated, _ = env.step(1)  # full push towards +x
        assert env.observation_space.contains(obs), obs
        x = env.state[0]
        assert terminated == (abs(x) > reach), (k, x)
        assert not truncated
        if terminated:
            break
    assert terminated and reach < x < rig["track_half_length_m"] + 1e-12
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)


def test_seeds_repeat_and_differ_and_the_horizon_truncates():
    env = cartpole_ddqn.SwingUpEnv(max_episode_steps=40)
    first, _ = env.reset(seed=11)
    again, _ = env.reset(seed=11)
    other, _ = env.reset(seed=12)
    assert np.array_equal(first, again) and not np.array_equal(first, other)
    for k in range(40):
        _, _, terminated, truncated, _ = env.step(k % 2)
        assert truncated == (k == 39) and not terminated


def test_registered_and_checked():
    env = gym.make(ID)
    assert env.spec.max_episode_steps == 1000
    assert env.action_space == gym.spaces.Discrete(2)
    assert env.observation_space.shape == (5,)
    check_env(cartpole_ddqn.SwingUpEnv(rig=str(DESK), levels=[-1, 0, 1]), skip_render_check=True)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"levels": [0.5, -0.5]}, "levels"),
        ({"levels": [-2, 1]}, "levels"),
        ({"max_episode_steps": 0}, "max_episode_steps"),
        ({"rig": str(REPO / "rigs" / "missing.toml")}, "missing.toml"),
    ],
)
def test_bad_arguments_are_refused_by_name(kwargs, match):
    with pytest.raises(ValueError, match=match):
        cartpole_ddqn.SwingUpEnv(**kwargs)


def test_an_action_outside_the_levels_is_refused():
    env = cartpole_ddqn.SwingUpEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="duty level"):
        env.step(2)
