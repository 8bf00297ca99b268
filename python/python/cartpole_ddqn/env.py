"""Gymnasium environments over the twin's worlds: one, and many stepped in one native call;
and the swing-up task over a rig's full circle (``SwingUpEnv``, described in its class).

For ``TwinEnv`` and ``TwinVectorEnv``, the observation is what the board's controller decides
on in the scenario (the exact state rounded to float32 on Gymnasium's machine; with noise,
encoders or dead time, the reading its sensor gives and its predictor advances), the reward
1.0 per period, and an episode terminates where the true plant leaves the track or the angle
limit. Action ``i`` drives the ``i``-th duty level (``levels=``, fractions of the full push; the paper's two, full push left
and right, by default) through the period.

``info["duty"]`` is the duty the period drove; at an episode's end ``info`` also has its
motor figures, by the names ``host-sim eval --json`` gives their means over episodes:
``reversals_per_s``, ``mean_abs_duty``, ``duty_tv_per_s`` and ``heat``.
"""

import itertools
import operator
import os

import numpy as np
import gymnasium
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import _native
from .api import _SEEDS, _items, _levels, _seed, _short, _steps

# The most worlds a vector environment holds.
MAX_ENVS = _native.MAX_ENVS

# Gymnasium's CartPole bounds: twice the termination limits for the positions, the largest
# float32 for the velocities.
_HIGH_FACTOR = 2.0


def _observation_space(x_threshold, theta_threshold):
    big = np.finfo(np.float32).max
    high = np.array(
        [x_threshold * _HIGH_FACTOR, big, theta_threshold * _HIGH_FACTOR, big],
        dtype=np.float32,
    )
    return spaces.Box(-high, high, dtype=np.float32)


def _seed_from(rng):
    """A 64-bit seed drawn from Gymnasium's generator, for an unseeded reset."""
    return int(rng.integers(0, 2**63))


def _no_options(options):
    """Refuses reset options: Gymnasium's CartPole takes a start range there (``low``,
    ``high``), but the twin draws its starts from the seed's own streams, so options would
    be ignored without a word. None or an empty dict (Gymnasium's checker passes one) ask
    for nothing."""
    if not (options is None or (isinstance(options, dict) and not options)):
        raise ValueError(
            "options: expected None or {} (the twin draws its starts from the seed), found "
            f"{type(options).__name__} {_short(options)}"
        )


def _envelope(envelope):
    """The envelope argument as the native module takes it: None, or a path (``"shipped"``
    naming the shipped policy's)."""
    if envelope is None or isinstance(envelope, (str, os.PathLike)):
        return envelope
    raise ValueError(
        f'envelope must be None, "shipped" or the path of a `host-sim envelope --json` file; '
        f"found {envelope!r}"
    )


def _refused_action(n, found):
    return ValueError(f"an action must be the index of a duty level, 0 to {n - 1}; found {found:.200}")


def _action(action, n):
    """An action as Gymnasium's ``Discrete(n)`` takes one: a Python int (a bool among them)
    or a NumPy integer, a 0-d integer array too (what ``operator.index`` takes). A float is
    refused: truncated, 1.7 would drive level 1 and -0.5 level 0."""
    try:
        index = operator.index(action)
    except TypeError:
        raise _refused_action(n, repr(action)) from None
    # Checked here as well as natively: an int past 64 bits would reach the native step as
    # an OverflowError.
    if not 0 <= index < n:
        raise _refused_action(n, str(index))
    return index


def _actions(actions, n):
    """One action per world as ``int64``, from an integer array (or a list of ints): float
    actions are refused, not truncated (NaN would become the most negative int64)."""
    a = np.asarray(actions)
    if not np.issubdtype(a.dtype, np.integer):
        raise _refused_action(n, f"{a.dtype} actions {np.array2string(a.reshape(-1), threshold=8)}")
    # Checked before the cast: an unsigned index past int64's range would wrap.
    outside = a[(a < 0) | (a >= n)]
    if outside.size:
        raise _refused_action(n, str(outside[0]))
    return np.ascontiguousarray(a, dtype=np.int64).reshape(-1)


class TwinEnv(gymnasium.Env):
    """One world of a scenario (``scenario="noise+delay=2+push"``) or of a domain
    (``domain="length=0.5..1.6"``), on Gymnasium's machine or a rig file's (``rig=``).

    ``levels=[-1, -0.2, 0, 0.2, 1]`` gives the duty levels the actions drive (checked as the
    tools' ``--levels``): the action space is ``Discrete(len(levels))``.

    With ``envelope=`` (``"shipped"``, or the file ``host-sim envelope --json`` wrote) the
    board's runtime monitor runs: outside the envelope, or on faulty readings, its LQR
    fallback decides instead of the agent, and ``info["fallback"]`` says so."""

    metadata = {"render_modes": []}

    def __init__(self, scenario=None, domain=None, rig=None, max_episode_steps=None, predict=True,
                 envelope=None, levels=None):
        self._twin = _native.Twin(scenario, domain, rig, _steps(max_episode_steps), predict,
                                  _envelope(envelope), _levels(levels))
        self._monitored = envelope is not None
        self._twin.reset(0)
        name, self.tau, x_limit, theta_limit = self._twin.world
        # The world is read from an episode that is no caller's: stepping it would step from
        # its start, where Gymnasium's CartPole asks for reset() first.
        self._twin.close()
        self.observation_space = _observation_space(x_limit, theta_limit)
        self.action_space = spaces.Discrete(len(self._twin.levels))
        self._seeded = False

    def reset(self, *, seed=None, options=None):
        _no_options(options)
        seed = None if seed is None else _seed(seed)
        super().reset(seed=seed)
        if seed is None and not self._seeded:
            seed = _seed_from(self.np_random)
        self._seeded = True
        obs = self._twin.reset(seed)
        return obs, {}

    def step(self, action):
        obs, terminated, truncated, duty = self._twin.step(_action(action, self.action_space.n))
        info = {"duty": duty}
        if self._monitored:
            info["fallback"] = self._twin.fallback
        if terminated or truncated:
            info.update(self._twin.motor())
        return obs, 1.0, terminated, truncated, info

    def close(self):
        """Ends the episode: step() then needs a reset() first."""
        self._twin.close()
        super().close()

    @property
    def levels(self):
        """The duty level each action drives, a fraction of the full push."""
        return self._twin.levels

    @property
    def motor(self):
        """The motor figures of the episode so far, as ``info`` gives them at its end: for
        an episode Gymnasium's ``TimeLimit`` wrapper truncated, which the environment does
        not see (``gymnasium.make`` adds one)."""
        return dict(self._twin.motor())

    @property
    def state(self):
        """The plant's true state ``[x, x_dot, theta, theta_dot]`` (float64)."""
        return np.array(self._twin.state)

    @property
    def rejected(self):
        """Whether the controller rejects this period's reading: the cart coasts."""
        return self._twin.rejected


class TwinVectorEnv(VectorEnv):
    """``num_envs`` worlds stepped together in native code, with Gymnasium's next-step
    autoreset: the step after an episode ends returns the next episode's first reading,
    reward 0, neither terminated nor truncated, and ignores that world's action. ``levels=``
    as for ``TwinEnv``. ``info["duty"]`` is each world's duty in the period; where a world's
    episode ended, ``info`` has its motor figures (masked by ``info["_reversals_per_s"]``
    and the like, Gymnasium's way). With ``envelope=``, as for ``TwinEnv``,
    ``info["fallback"]`` says per world whether the monitor's fallback decided.

    At most ``MAX_ENVS`` worlds. A step interrupted by Ctrl-C (``KeyboardInterrupt``) leaves
    some worlds stepped and others not: ``reset()`` before stepping again."""

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs=1, scenario=None, domain=None, rig=None, max_episode_steps=None, predict=True,
                 envelope=None, levels=None):
        # True is an int to Python: it ran as one world.
        bad_type = not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, (bool, np.bool_))
        if bad_type or not 1 <= num_envs <= MAX_ENVS:
            raise ValueError(f"num_envs must be a whole number in [1, {MAX_ENVS}]; found {num_envs!r}")
        self.num_envs = int(num_envs)
        self._twin = _native.VecTwin(scenario, domain, rig, _steps(max_episode_steps), predict,
                                     _envelope(envelope), _levels(levels))
        self._monitored = envelope is not None
        probe = _native.Twin(scenario, domain, rig, None, predict, None, _levels(levels))
        probe.reset(0)
        _, _, x_limit, theta_limit = probe.world
        self.levels = probe.levels
        self.single_observation_space = _observation_space(x_limit, theta_limit)
        self.single_action_space = spaces.Discrete(len(self.levels))
        # The mask of a figure every world has, shared by every step's info: read-only.
        self._every = np.ones(self.num_envs, dtype=bool)
        self._every.flags.writeable = False
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._seeded = False

    def reset(self, *, seed=None, options=None):
        """World ``i`` starts episode 0 of ``seed + i``. ``seed`` is None (drawn from the
        environment's generator), an int as Gymnasium takes one (or a NumPy integer), or a
        list of ``num_envs`` of them, one per world, None among them drawing that world's
        as Gymnasium's ``SyncVectorEnv`` does. Every seed is below 2**64."""
        _no_options(options)
        n = self.num_envs
        if isinstance(seed, (int, np.integer)):
            seed = _seed(seed, _SEEDS - n, name="seed (world i takes seed + i)")
            super().reset(seed=seed)
            return self._twin.reset([seed + i for i in range(n)]), {}
        # Gymnasium's own seeding takes one seed; a list seeds the worlds alone.
        super().reset(seed=None)
        if seed is None:
            base = _seed_from(self.np_random)
            return self._twin.reset([base + i for i in range(n)]), {}
        items = _items(seed, "seed", f"None, an int or a list of {n} ints, one per world")
        # Read to one past the worlds at most: a range of ten billion builds no list.
        given = list(itertools.islice(items, n + 1))
        if len(given) != n:
            raise ValueError(f"seed: expected {n} seeds, one per world; found {len(given)}")
        seeds = [
            _seed_from(self.np_random) if s is None else _seed(s, name=f"seed[{i}]") for i, s in enumerate(given)
        ]
        return self._twin.reset(seeds), {}

    def step(self, actions):
        obs, reward, terminated, truncated, duty = self._twin.step(_actions(actions, self.single_action_space.n))
        info = {"duty": duty, "_duty": self._every}
        if self._monitored:
            info.update(fallback=self._twin.fallbacks(), _fallback=self._every)
        ended = terminated | truncated
        if ended.any():
            for name, values in self._twin.motor():
                info[name], info["_" + name] = values, ended
        return obs, reward, terminated, truncated, info

    def close_extras(self, **kwargs):
        """Ends every world's episode: step() then needs a reset() first."""
        self._twin.close()

    @property
    def states(self):
        """The plants' true states ``[num_envs, 4]`` (float64)."""
        return self._twin.states()


class SwingUpEnv(gymnasium.Env):
    """The swing-up task on Gymnasium's machine or a rig file's (``rig=``): the machine's true
    world over the full circle (its physics, the dead time between a command and the motor,
    the track's end stops), the world ``host-sim startup`` runs its board in. Each episode
    starts with the pole hanging nearly at rest and the cart near the centre.

    The observation is ``[x, x_dot, cos(theta), sin(theta), theta_dot]`` (float32), the
    angle counted from upright; the reward is the pole's height as a share,
    ``(1 + cos(theta)) / 2`` (1 upright, 0 hanging). An episode terminates when the cart
    ends a period inside the rig's end-stop margin (or against an end stop), and is
    truncated at ``max_episode_steps``. ``levels=`` as for ``TwinEnv``; ``info["duty"]`` is
    the duty the period sent."""

    metadata = {"render_modes": []}

    def __init__(self, rig=None, max_episode_steps=None, levels=None):
        self._world = _native.SwingUp(rig, _steps(max_episode_steps), _levels(levels))
        self.tau, _, end = self._world.world
        big = np.finfo(np.float32).max
        # The episode ends past the margin, but the end stops hold the cart.
        high = np.array([end, big, 1.0, 1.0, big], dtype=np.float32)
        self.observation_space = spaces.Box(-high, high, dtype=np.float32)
        self.action_space = spaces.Discrete(len(self._world.levels))

    def reset(self, *, seed=None, options=None):
        _no_options(options)
        seed = None if seed is None else _seed(seed)
        super().reset(seed=seed)
        if seed is None:
            seed = _seed_from(self.np_random)
        return self._world.reset(seed), {}

    def step(self, action):
        obs, reward, terminated, truncated, duty = self._world.step(_action(action, self.action_space.n))
        return obs, reward, terminated, truncated, {"duty": duty}

    def close(self):
        """Ends the episode: step() then needs a reset() first."""
        self._world.close()
        super().close()

    @property
    def levels(self):
        """The duty level each action drives, a fraction of the full push."""
        return self._world.levels

    @property
    def state(self):
        """The plant's true state ``[x, x_dot, theta, theta_dot]`` (float64), the angle
        counted over whole turns."""
        return np.array(self._world.state)
