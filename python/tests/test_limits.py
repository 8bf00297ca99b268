"""Long work bounded and interruptible: the limits the package shares with `host-sim eval`,
Ctrl-C in the middle of native work, MemoryError for results that cannot fit, and every
refusal a Python exception (never a Rust panic)."""

import os
import re
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import cartpole_ddqn
from cartpole_ddqn import _native

from conftest import REPO


def test_the_limits_are_the_command_lines(tools):
    """`host-sim eval` refuses one episode and one period more than the package allows, and
    so does the package."""
    for flag, limit in (("--episodes", cartpole_ddqn.MAX_EPISODES), ("--horizon", cartpole_ddqn.MAX_HORIZON)):
        done = subprocess.run(
            [str(tools["host-sim"]), "eval", flag, str(limit + 1)], cwd=REPO, capture_output=True, text=True
        )
        assert done.returncode == 2 and flag.strip("-") in done.stderr, done.stderr
    with pytest.raises(ValueError, match="episodes"):
        cartpole_ddqn.evaluate(episodes=cartpole_ddqn.MAX_EPISODES + 1)
    with pytest.raises(ValueError, match="horizon"):
        cartpole_ddqn.evaluate(episodes=1, horizon=cartpole_ddqn.MAX_HORIZON + 1)
    with pytest.raises(ValueError, match="max_episode_steps"):
        cartpole_ddqn.TwinEnv(max_episode_steps=cartpole_ddqn.MAX_HORIZON + 1)
    cartpole_ddqn.TwinEnv(max_episode_steps=cartpole_ddqn.MAX_HORIZON)


@pytest.mark.parametrize("n", [0, cartpole_ddqn.MAX_ENVS + 1, 10**7])
def test_too_many_environments_raise_value_error(n):
    with pytest.raises(ValueError, match="num_envs"):
        cartpole_ddqn.TwinVectorEnv(num_envs=n)


def test_the_native_vector_env_refuses_too_many_worlds_itself():
    with pytest.raises(ValueError, match="environments"):
        _native.VecTwin().reset([0] * (cartpole_ddqn.MAX_ENVS + 1))


class Interrupt:
    """SIGINT sent to this process from another thread after `delay` seconds, under
    Python's own handler (KeyboardInterrupt); `sent` is when (`time.monotonic`)."""

    def __init__(self, delay):
        self.timer = threading.Timer(delay, self._send)

    def _send(self):
        self.sent = time.monotonic()
        os.kill(os.getpid(), signal.SIGINT)

    def __enter__(self):
        self.handler = signal.signal(signal.SIGINT, signal.default_int_handler)
        self.timer.start()
        return self

    def __exit__(self, *exc):
        self.timer.cancel()
        self.timer.join()
        signal.signal(signal.SIGINT, self.handler)
        return False


def test_ctrl_c_stops_an_evaluation_that_could_never_finish():
    """Ten million episodes of 500 periods in every one of three scenarios: no machine
    ends it, so the interrupt arrives during the call, and it must end it."""
    with Interrupt(0.3), pytest.raises(KeyboardInterrupt):
        cartpole_ddqn.evaluate(
            scenario=["nominal", "noise", "push"], episodes=cartpole_ddqn.MAX_EPISODES, horizon=500
        )


def test_ctrl_c_stops_a_vector_env_and_a_reset_recovers_it():
    """Steps of the most worlds, for ever, until the interrupt; whether it lands within a
    native step (which leaves the worlds to be reset) or between two, it ends the loop, and
    a reset makes the environment step again."""
    venv = cartpole_ddqn.TwinVectorEnv(num_envs=cartpole_ddqn.MAX_ENVS, max_episode_steps=50)
    venv.reset(seed=0)
    actions = np.zeros(venv.num_envs, dtype=np.int64)
    with Interrupt(0.3), pytest.raises(KeyboardInterrupt):
        while True:
            venv.step(actions)
    try:
        venv.step(actions)
    except RuntimeError as e:
        assert "reset" in str(e)
    venv.reset(seed=1)
    assert venv.step(actions)[0].shape == (venv.num_envs, 4)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_ctrl_c_stops_q_values_and_act_on_a_huge_batch_within_a_second(dtype):
    """10^8 readings through a zero-stride view, many seconds of work: the interrupt is
    heard after the range of readings in progress, whether it lands as they are converted,
    checked or run, not after a pass over the whole batch (4 s of it at this size)."""
    huge = np.broadcast_to(np.zeros((1, 4), dtype=dtype), (10**8, 4))
    policy = cartpole_ddqn.shipped()
    for call in (policy.q_values, policy.act):
        with Interrupt(0.3) as interrupt, pytest.raises(KeyboardInterrupt):
            call(huge)
        late = time.monotonic() - interrupt.sent
        assert late < 1.0, f"{call.__name__}: KeyboardInterrupt {late:.2f} s after the signal"


def test_a_batch_that_cannot_fit_raises_memory_error():
    """A zero-stride view of 2^50 readings takes no memory; its Q-values would take
    2^53 bytes."""
    huge = np.broadcast_to(np.zeros((1, 4), dtype=np.float32), (2**50, 4))
    policy = cartpole_ddqn.shipped()
    with pytest.raises(MemoryError):
        policy._native.q_values(huge)
    with pytest.raises(MemoryError):
        policy._native.act(huge)
    with pytest.raises(MemoryError):
        policy.q_values(huge)


def envelope_file(tmp_path, bounds):
    path = tmp_path / "envelope.json"
    path.write_text('{"envelope": [%s]}' % ", ".join(bounds))
    return path


def test_every_refusal_is_a_python_exception_not_a_panic(tmp_path):
    """Hostile arguments at each entry point: each raises an ordinary exception (a Rust
    panic would surface as pyo3's PanicException, a BaseException that `Exception` does
    not catch)."""
    garbage = tmp_path / "garbage.safetensors"
    garbage.write_bytes(b"\xff" * 64)
    desk = REPO / "rigs" / "desk.toml"
    calls = [
        lambda: _native.Twin(levels=[]),
        lambda: _native.Twin(levels=[float("inf"), 1.0]),
        lambda: _native.Twin(max_episode_steps=-1),
        lambda: _native.Twin().step(0),
        lambda: _native.Twin().state,
        lambda: _native.VecTwin().step(np.zeros(1, dtype=np.int64)),
        lambda: _native.VecTwin().reset([]),
        lambda: _native.Twin(envelope=str(envelope_file(tmp_path, ["-1", "1", "1", "1"]))),
        lambda: _native.Twin(envelope=str(envelope_file(tmp_path, ["1e39", "1", "1", "1"]))),
        lambda: _native.Twin(envelope=str(envelope_file(tmp_path, ["1", "1", "1"]))),
        lambda: cartpole_ddqn.load(garbage),
        lambda: cartpole_ddqn.export(garbage, tmp_path / "out.rs"),
        lambda: cartpole_ddqn.shipped().q_values(np.zeros((2, 3))),
        lambda: _native.evaluate_json(None, ["nominal"], ["policy"], 1, [0], 0),
        lambda: _native.evaluate_json(None, ["nominal"], ["policy"], 0, [1], 0),
        lambda: cartpole_ddqn.evaluate(scenario="nominal+" * 200),
        lambda: cartpole_ddqn.TwinVectorEnv(2).step([0, 0]),
    ]
    for k, call in enumerate(calls):
        with pytest.raises((ValueError, RuntimeError, OverflowError)):
            call()
    # Accepted edge cases run without a panic: an envelope of zeros (the fallback decides
    # every period) on another rig, the largest level count a step can name.
    env = cartpole_ddqn.TwinEnv(rig=desk, envelope=envelope_file(tmp_path, ["0", "0", "0", "0"]), max_episode_steps=20)
    env.reset(seed=0)
    assert all(env.step(0)[4]["fallback"] for _ in range(3))
    many = cartpole_ddqn.TwinEnv(levels=np.linspace(-1, 1, 2001), max_episode_steps=5)
    many.reset(seed=0)
    assert many.step(2000)[4]["duty"] == 1.0


def test_provenance_reads_argv_no_further_than_a_command_line_holds():
    """A range of ten billion arguments was converted whole, to a MemoryError after 3.7 GB:
    past what Linux's execve takes (6 MiB, each argument's NUL and pointer counted) no
    process was given it, and it is refused after reading that much at most."""
    with pytest.raises(ValueError, match=r"^argv must fit a command line: at most 6291456 bytes"):
        cartpole_ddqn.provenance("x", range(10**10))
    with pytest.raises(ValueError, match=r"^argv must fit a command line: .*found more by argument 1$"):
        cartpole_ddqn.provenance("x", ["a" * 10**7])
    # The most there can be: one argument of 6 MiB less its NUL and pointer.
    most = 6 * 2**20 - 9
    assert cartpole_ddqn.provenance("x", ["a" * most])["argv"] == ["a" * most]
    with pytest.raises(ValueError, match="argv"):
        cartpole_ddqn.provenance("x", ["a" * (most + 1)])
    # A str is no list of arguments; bytes would be recorded as their repr.
    for argv, found in (("--steps 10", "found str"), (10, "found int"), ([b"--steps"], "found the item b'--steps'")):
        with pytest.raises(TypeError, match=r"^argv must be .*" + re.escape(found)):
            cartpole_ddqn.provenance("x", argv)
    # A byte sys.argv escapes (not UTF-8) is recorded as U+FFFD, as the tools record theirs.
    assert cartpole_ddqn.provenance("x", ["runs/\udcff", 10])["argv"] == ["runs/\ufffd", "10"]


@pytest.mark.parametrize(
    "make",
    [cartpole_ddqn.TwinEnv, cartpole_ddqn.SwingUpEnv, lambda **k: cartpole_ddqn.TwinVectorEnv(2, **k)],
)
def test_max_episode_steps_past_its_range_or_a_bool_names_the_argument(make):
    """2**64 raised the native conversion's OverflowError, naming nothing; True ran as 1."""
    top = cartpole_ddqn.MAX_HORIZON
    with pytest.raises(ValueError, match=rf"^max_episode_steps must be in \[1, {top}\]; found {2**64}$"):
        make(max_episode_steps=2**64)
    with pytest.raises(TypeError, match=r"^max_episode_steps must be an int \(a whole number of periods\); found True"):
        make(max_episode_steps=True)


def test_a_bool_is_no_count():
    """True is an int to Python, and each of these ran as 1."""
    with pytest.raises(TypeError, match=r"^episodes must be an int"):
        cartpole_ddqn.evaluate(controller="lqr", episodes=True, horizon=2)
    with pytest.raises(ValueError, match=r"^horizon must be a whole number of periods; found True"):
        cartpole_ddqn.evaluate(controller="lqr", episodes=1, horizon=True)
    with pytest.raises(ValueError, match=r"^num_envs must be a whole number"):
        cartpole_ddqn.TwinVectorEnv(num_envs=True)


def test_arguments_that_change_nothing_or_mismatch_their_machine_are_refused():
    """predict=False without dead time gave the same observations as predict=True; the
    shipped envelope, measured on Gymnasium's machine, bounded the desk's readings."""
    with pytest.raises(ValueError, match=r"^predict=False changes nothing where no world has dead time"):
        cartpole_ddqn.TwinEnv(predict=False)
    with pytest.raises(ValueError, match=r"^envelope=\"shipped\" was measured on Gymnasium's machine"):
        cartpole_ddqn.TwinEnv(envelope="shipped", rig=REPO / "rigs" / "desk.toml")
    # With dead time, the reading itself is another observation.
    cartpole_ddqn.TwinEnv(scenario="delay=2", predict=False)
    cartpole_ddqn.TwinVectorEnv(2, domain="delay=0..2", predict=False)
