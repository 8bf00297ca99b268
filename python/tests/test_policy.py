"""Policies: the shipped policy's file against the policy compiled into the firmware, a
NumPy forward pass and the simulator's command line."""

import json
import re
import warnings

import numpy as np
import pytest

import cartpole_ddqn

from conftest import REPO, five_outputs, read_safetensors, run, write_safetensors

SHIPPED = REPO / "shipped" / "policy.safetensors"


def numpy_q(tensors, obs):
    """The 4-64-64-2 ReLU network in NumPy (float64): an independent reference."""
    h = np.asarray(obs, dtype=np.float64)
    for i in (1, 2, 3):
        w, b = (tensors[f"fc{i}.{k}"].astype(np.float64) for k in ("weight", "bias"))
        h = h @ w.T + b
        if i < 3:
            h = np.maximum(h, 0.0)
    return h


def states(n=2000, seed=0):
    scale = np.array([2.4, 2.0, 0.21, 3.0])
    return (np.random.default_rng(seed).uniform(-1, 1, size=(n, 4)) * scale).astype(np.float32)


def test_shipped_file_is_the_compiled_policy():
    obs = states()
    assert np.array_equal(cartpole_ddqn.load(SHIPPED).q_values(obs), cartpole_ddqn.shipped().q_values(obs))


def test_q_values_agree_with_numpy_and_act_takes_the_larger():
    policy, obs = cartpole_ddqn.load(SHIPPED), states()
    q = policy.q_values(obs)
    assert q.dtype == np.float32 and q.shape == (len(obs), 2)
    want = numpy_q(read_safetensors(SHIPPED), obs)
    assert np.max(np.abs(q - want)) <= 1e-5 * max(1.0, np.max(np.abs(want)))
    clear = np.abs(want[:, 1] - want[:, 0]) > 1e-3
    assert np.array_equal(policy.act(obs)[clear], np.argmax(want, axis=1)[clear])
    assert policy.q_values(obs.reshape(40, 50, 4)).shape == (40, 50, 2)
    assert policy.act(obs[0]) in (0, 1)


def with_value(value, at=(1, 2), dtype=np.float32):
    obs = states(3).astype(dtype)
    obs[at] = value
    return obs


@pytest.mark.parametrize(
    "obs, found",
    [
        (with_value(np.nan), "finite in float32; found nan at [1, 2]"),
        (with_value(-np.inf), "finite in float32; found -inf at [1, 2]"),
        (with_value(1e300, dtype=np.float64), "finite in float32; found 1e+300 at [1, 2]"),
        (with_value(1e39, at=(2, 0), dtype=np.float64), "finite in float32; found 1e+39 at [2, 0]"),
        (np.array([0.1, None, 0.0, 0.0]), "that are real numbers; found None at [1]"),
        ([[0, 0, 0, 0], [0, 0, 0, 2**128]], f"finite in float32; found {2**128} at [1, 3]"),
        ([0, 0, 10**400, 0], "finite in float32; found 1000000000000"),
        ([[0, 0, 0, 0], [0, 0, 0, "x"]], "that are real numbers; found <U21 readings, the first '0' at [0, 0]"),
        (np.array([1 + 2j, 0, 0, 0]), "that are real numbers; found complex128 readings, the first (1+2j) at [0]"),
        (np.array([True, False, False, True]), "that are real numbers; found bool readings, the first True at [0]"),
    ],
)
def test_readings_that_are_no_finite_real_numbers_are_refused_naming_obs(obs, found):
    """NaN turns every ReLU off, so the network answered a constant no state chose; None
    became NaN, 1e300 an infinity in float32, a complex number lost its imaginary part."""
    policy = cartpole_ddqn.shipped()
    for call in (policy.q_values, policy.act):
        with pytest.raises(ValueError, match="^" + re.escape(f"obs: expected readings {found}")):
            call(obs)
    # Valid readings beside them: float64, Python numbers, a strided view, a batch of batches.
    obs = states(6)
    assert np.array_equal(policy.q_values(obs.astype(np.float64)), policy.q_values(obs))
    assert np.array_equal(policy.q_values(np.array([*obs[0].tolist()[:3], 0], dtype=object)),
                          policy.q_values([*obs[0][:3], 0]))
    assert np.array_equal(policy.act(np.repeat(obs, 2, axis=1)[:, ::2]), policy.act(obs))
    assert policy.q_values(obs.reshape(2, 3, 4)).shape == (2, 3, 2)


def test_readings_whose_sums_leave_float32_are_refused_naming_obs():
    """Finite alone, 1e37 overflowed inside the network: the Q-values were -inf and NaN, or
    the last biases alone. The bound is the weights': past it some sum can overflow, at it
    none does (an independent float64 pass over the shipped weights agrees)."""
    policy = cartpole_ddqn.shipped()
    bound = policy.reading_bound
    assert 1e20 < bound < 1e37
    over = with_value(1e37, at=(2, 1), dtype=np.float64)
    for call in (policy.q_values, policy.act):
        with pytest.raises(ValueError, match=re.escape("found 1e+37 at [2, 1]")) as e:
            call(over)
        assert f"within +-{bound:.3e}" in str(e.value)
    at = np.full((1, 4), bound, dtype=np.float32) * np.array([1, -1, 1, -1], dtype=np.float32)
    q = policy.q_values(at)
    assert np.isfinite(q).all()
    want = numpy_q(read_safetensors(SHIPPED), at.astype(np.float64))
    assert np.allclose(q, want, rtol=1e-3)


def test_loaded_policy_evaluates_as_the_command_line_does(tools):
    args = ["--scenario", "noise+delay=2", "--controller", "policy", "--episodes", "40", "--horizon", "300"]
    want = json.loads(run(tools["host-sim"], "eval", "--policy", SHIPPED, "--json", *args))["rows"]
    got = cartpole_ddqn.evaluate(cartpole_ddqn.load(SHIPPED), "noise+delay=2", episodes=40, horizon=300)
    assert got == want


def test_the_repr_quotes_the_files_layer_names(tmp_path):
    """Tensor names are the file's: a layer named with a line break or an escape sequence
    is shown quoted and escaped, on one line."""
    path = tmp_path / "names.safetensors"
    layers = {"fc1": "q\nerror: fake fc1", "fc2": "\x1b[31mfc2", "fc3": "fc3"}
    write_safetensors(path, {layers[k[:3]] + k[3:]: v for k, v in read_safetensors(SHIPPED).items()})
    shown = repr(cartpole_ddqn.load(path))
    assert shown.startswith('Policy(layers "q\\nerror: fake fc1", "\\u{1b}[31mfc2", "fc3" under no prefix'), shown
    assert shown.isprintable(), shown


def test_refusals_raise_value_error():
    with pytest.raises(ValueError, match="nonexistent"):
        cartpole_ddqn.load(REPO / "nonexistent.safetensors")
    with pytest.raises(ValueError, match="found shape"):
        cartpole_ddqn.shipped().q_values(np.zeros((3, 5)))
    with pytest.raises(ValueError):
        cartpole_ddqn.load(REPO / "README.md")


FIXTURES = REPO / "weights" / "tests" / "fixtures"


@pytest.mark.parametrize(
    "name, prefix",
    [
        ("sequential64.pth", None),
        ("sequential64_protocol4.pth", None),
        ("cleanrl.cleanrl_model", None),
        ("fc_strided.pth", None),
        ("sb3_dqn.zip", "q_net.q_net."),
        ("sb3_dqn.zip", "q_net_target.q_net."),
        ("sequential64_gemm.onnx", None),
        ("sequential64_matmul.onnx", None),
    ],
)
def test_every_checkpoint_format_gives_pytorchs_q_values(name, prefix):
    expected = json.loads((FIXTURES / "expected.json").read_text())
    obs = np.array(expected["observations"], dtype=np.float32)
    want = np.array(expected["files"][name][prefix or next(iter(expected["files"][name]))])
    q = cartpole_ddqn.load(FIXTURES / name, prefix=prefix).q_values(obs)
    assert np.abs(q.astype(np.float64) - want).max() <= 1e-6


@pytest.mark.parametrize("name, says", [("evil.pth", "posix.system"), ("tanh.onnx", "Tanh")])
def test_a_hostile_or_foreign_checkpoint_is_refused_by_name(name, says):
    with pytest.raises(ValueError, match=says):
        cartpole_ddqn.load(FIXTURES / name)


FIVE = [-1.0, -0.2, 0.0, 0.2, 1.0]


def test_a_five_output_checkpoint_drives_the_levels_given(tmp_path):
    path = tmp_path / "five.safetensors"
    tensors = five_outputs()
    write_safetensors(path, tensors)
    policy = cartpole_ddqn.load(path, levels=FIVE)
    assert policy.levels == pytest.approx(FIVE, abs=1e-7)
    obs = states()
    q, want = policy.q_values(obs), numpy_q(tensors, obs)
    assert q.shape == (len(obs), 5)
    assert np.max(np.abs(q - want)) <= 1e-5 * max(1.0, np.max(np.abs(want)))
    top = np.sort(want, axis=1)
    clear = top[:, -1] - top[:, -2] > 1e-3
    assert np.array_equal(policy.act(obs)[clear], np.argmax(want, axis=1)[clear])
    assert policy.q_values(obs.reshape(40, 50, 4)).shape == (40, 50, 5)


@pytest.mark.parametrize(
    "levels, says",
    [
        (None, "5 outputs and its file records no duty levels"),
        ([-1, 1], r"levels \[-1, 1\]: expected one level per output of the network, 5; found 2"),
        ([1, 0, -1, 0.5, 0.2], "expected strictly increasing"),
    ],
)
def test_five_outputs_without_their_levels_are_refused(tmp_path, levels, says):
    path = tmp_path / "five.safetensors"
    write_safetensors(path, five_outputs())
    with pytest.raises(ValueError, match=says):
        cartpole_ddqn.load(path, levels=levels)


def test_a_policy_run_on_another_rig_gives_a_python_warning(tmp_path, capfd):
    """The command line's warning, which was printed raw and named `--rig`, as a `UserWarning`
    a caller can catch or filter; and none where no policy is read."""
    desk = REPO / "rigs" / "desk.toml"
    want = "trained for another rig than rig= gives"
    with pytest.warns(UserWarning, match=want) as caught:
        cartpole_ddqn.load(SHIPPED, rig=desk)
        cartpole_ddqn.shipped(rig=desk)
        cartpole_ddqn.evaluate(episodes=1, horizon=5, rig=desk)
        cartpole_ddqn.export(SHIPPED, tmp_path / "p.h", fmt="c", rig=desk)
    assert len(caught) == 4
    assert all(w.filename == __file__ for w in caught)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cartpole_ddqn.evaluate(episodes=1, horizon=5, rig=desk, controller="lqr")
        cartpole_ddqn.load(SHIPPED)
    # Judged against the rig it was trained for, not the one it was loaded for.
    with pytest.warns(UserWarning):
        on_desk = cartpole_ddqn.load(SHIPPED, rig=desk)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cartpole_ddqn.evaluate(on_desk, episodes=1, horizon=5, rig=REPO / "rigs" / "gymnasium.toml")
    assert "warning" not in capfd.readouterr().err
