"""Actions are indices of duty levels, taken as Gymnasium's ``Discrete`` takes them: a Python
int (a bool too) or a NumPy integer, a 0-d integer array among them. Anything else, a float
above all, is refused with a ValueError, never truncated to a level it does not name."""

import re

import numpy as np
import pytest

import cartpole_ddqn

SINGLE = [cartpole_ddqn.TwinEnv, cartpole_ddqn.SwingUpEnv]
REFUSED = "an action must be the index of a duty level, 0 to 1; found "


def started(make):
    env = make()
    env.reset(seed=0)
    return env


@pytest.mark.parametrize("make", SINGLE)
@pytest.mark.parametrize(
    "action, found",
    [
        (1.7, "1.7"),
        (-0.5, "-0.5"),
        (0.99, "0.99"),
        (np.float64(1.0), "np.float64(1.0)"),
        (np.True_, "np.True_"),
        ("1", "'1'"),
        (np.array([1]), "array([1])"),
        (None, "None"),
        (2, "2"),
        (-1, "-1"),
        (2**70, str(2**70)),
    ],
)
def test_a_single_env_refuses_what_is_not_a_level_index(make, action, found):
    env = started(make)
    with pytest.raises(ValueError, match="^" + re.escape(REFUSED + found) + "$"):
        env.step(action)


@pytest.mark.parametrize("make", SINGLE)
@pytest.mark.parametrize("action", [True, np.int64(1), np.uint8(1), np.array(1)])
def test_a_single_env_takes_ints_and_numpy_integers_as_discrete_does(make, action):
    env, same = started(make), started(make)
    assert env.action_space.contains(action)
    assert np.array_equal(env.step(action)[0], same.step(1)[0])


@pytest.mark.parametrize(
    "actions, found",
    [
        (np.array([1.7, 0.2]), "float64 actions [1.7 0.2]"),
        (np.array([np.nan, 0]), "float64 actions [nan  0.]"),
        ([1.0, 0.0], "float64 actions [1. 0.]"),
        (np.array([True, False]), "bool actions [ True False]"),
        (np.array([0, 2**64 - 1], dtype=np.uint64), "18446744073709551615"),
        (np.array([0, 2]), "2"),
    ],
)
def test_the_vector_env_refuses_float_actions_and_indices_past_the_levels(actions, found):
    venv = cartpole_ddqn.TwinVectorEnv(2)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="^" + re.escape(REFUSED + found) + "$"):
        venv.step(actions)


def test_the_vector_env_takes_integer_arrays_of_any_width_and_lists_of_ints():
    venv, same = cartpole_ddqn.TwinVectorEnv(2), cartpole_ddqn.TwinVectorEnv(2)
    venv.reset(seed=0)
    same.reset(seed=0)
    for actions in (np.array([1, 0], dtype=np.uint8), [1, 0], np.array([1, 0], dtype=np.int32)):
        assert np.array_equal(venv.step(actions)[0], same.step(np.array([1, 0]))[0])
