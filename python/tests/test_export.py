"""Export: the files `policy-export export` writes, byte for byte, from a path and from
in-memory state dicts; nothing written on a refusal."""

import subprocess
import sys
import tracemalloc
import warnings

import numpy as np
import pytest

import cartpole_ddqn

from conftest import REPO, five_outputs, read_safetensors, run, write_safetensors

FIXTURES = REPO / "weights" / "tests" / "fixtures"
CASES = [
    ("rust", None, []),
    ("c", None, ["--format", "c"]),
    ("rust", "int8", ["--quant", "int8"]),
    ("c", "int8", ["--format", "c", "--quant", "int8"]),
]


def cli_export(tools, tmp_path, src, flags):
    out = tmp_path / "cli.out"
    run(tools["policy-export"], "export", src, "--out", out, *flags)
    return out.read_bytes()


@pytest.mark.parametrize("fmt, quant, flags", CASES)
def test_path_source_is_the_commands_output(tools, tmp_path, fmt, quant, flags):
    src = REPO / "shipped" / "policy.safetensors"
    out = tmp_path / "py.out"
    assert cartpole_ddqn.export(src, out=out, fmt=fmt, quant=quant) == out
    assert out.read_bytes() == cli_export(tools, tmp_path, src, flags)


@pytest.mark.parametrize("fmt, quant, flags", CASES)
@pytest.mark.parametrize("fixture", ["cleanrl.safetensors", "sequential.safetensors"])
def test_dict_source_is_the_commands_output_for_its_file(tools, tmp_path, fixture, fmt, quant, flags):
    src = FIXTURES / fixture
    tensors = read_safetensors(src)
    out = tmp_path / "py.out"
    cartpole_ddqn.export(tensors, out=out, fmt=fmt, quant=quant, label=fixture)
    assert out.read_bytes() == cli_export(tools, tmp_path, src, flags)


def test_torch_like_tensors_are_detached_and_copied_to_the_cpu(tmp_path):
    class Tensor:
        def __init__(self, a):
            self.a, self.dtype, self.shape = a, "torch.float32", a.shape

        def detach(self):
            return self

        def cpu(self):
            return self

        def numpy(self):
            return self.a

    tensors = read_safetensors(REPO / "shipped" / "policy.safetensors")
    a, b = tmp_path / "a.rs", tmp_path / "b.rs"
    cartpole_ddqn.export(tensors, out=a)
    cartpole_ddqn.export({k: Tensor(v) for k, v in tensors.items()}, out=b)
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize("order", [">f4", ">f8", ">f2"])
def test_big_endian_arrays_export_as_their_values_do(tmp_path, order):
    tensors = read_safetensors(REPO / "shipped" / "policy.safetensors")
    native = {k: v.astype(order.replace(">", "<")) for k, v in tensors.items()}
    swapped = {k: v.astype(order) for k, v in tensors.items()}
    assert all(v.dtype.byteorder == ">" for v in swapped.values())
    a, b = tmp_path / "a.rs", tmp_path / "b.rs"
    cartpole_ddqn.export(native, out=a)
    cartpole_ddqn.export(swapped, out=b)
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(fmt="go"), "fmt"),
        (dict(quant="int4"), "quant"),
        (dict(name="not an identifier"), "name"),
        (dict(granularity="per-row", quant="int8"), "granularity"),
        # Without quant it would be dropped; the command refuses --granularity without --quant.
        (dict(granularity="per-tensor"), 'granularity needs quant="int8"'),
    ],
)
def test_refusals_raise_value_error_and_write_nothing(tmp_path, kwargs, words):
    out = tmp_path / "never.rs"
    with pytest.raises(ValueError, match=words):
        cartpole_ddqn.export(REPO / "shipped" / "policy.safetensors", out=out, **kwargs)
    assert list(tmp_path.iterdir()) == []


# Writes under a file size limit of 1000 bytes (a module is some 20 KB), SIGXFSZ ignored so
# the write fails with EFBIG as on a full disk; set after the import, whose caches it spares.
FULL_DISK = """
import resource, signal, sys
import cartpole_ddqn
from conftest import read_safetensors
source = sys.argv[1] if sys.argv[3] == "path" else read_safetensors(sys.argv[1])
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (1000, 1000))
try:
    cartpole_ddqn.export(source, out=sys.argv[2])
except OSError as e:
    print(type(e).__name__, e)
"""


@pytest.mark.parametrize("source", ["path", "state dict"])
def test_a_write_that_fails_raises_os_error_not_value_error(tmp_path, source):
    """A full disk is the system's failure, not bad input: OSError, as the command exits 1
    there (2 for bad input); nothing is left behind."""
    out = tmp_path / "out" / "policy.rs"
    args = [sys.executable, "-c", FULL_DISK, REPO / "shipped" / "policy.safetensors", out, source]
    done = subprocess.run(args, cwd=REPO / "python" / "tests", capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"OSError writing {out}: File too large"), done.stdout
    assert list(out.parent.iterdir()) == []


def test_a_read_that_fails_raises_os_error_and_a_summary_refused_value_error(tmp_path):
    """A run's summary.json that opens as a regular file but fails to read (/proc/self/mem
    refuses a read at address 0 with an I/O error) is the system's failure, as the command
    exits 1 there; it raised ValueError. A summary that is no run's stays bad input."""
    src = tmp_path / "run"
    src.mkdir()
    (src / "policy.safetensors").write_bytes((REPO / "shipped" / "policy.safetensors").read_bytes())
    summary = src / "summary.json"
    summary.symlink_to("/proc/self/mem")
    out = tmp_path / "policy.rs"
    with pytest.raises(OSError, match=r"^reading .*summary\.json: Input/output error"):
        cartpole_ddqn.export(src, out=out)
    summary.unlink()
    summary.write_text("{}")
    with pytest.raises(ValueError, match="summary.json: not a run summary"):
        cartpole_ddqn.export(src, out=out)
    assert not out.exists()


def test_a_dict_without_the_network_is_refused(tmp_path):
    tensors = read_safetensors(REPO / "shipped" / "policy.safetensors")
    del tensors["fc2.weight"]
    with pytest.raises(ValueError):
        cartpole_ddqn.export(tensors, out=tmp_path / "x.rs")
    assert list(tmp_path.iterdir()) == []


def test_five_outputs_export_with_their_levels_as_the_command_does(tools, tmp_path):
    src = tmp_path / "five.safetensors"
    tensors = five_outputs()
    write_safetensors(src, tensors)
    levels = [-1, -0.2, 0, 0.2, 1]
    out = tmp_path / "py.out"
    cartpole_ddqn.export(tensors, out=out, label="five.safetensors", levels=levels)
    assert out.read_bytes() == cli_export(tools, tmp_path, src, ["--levels", "-1,-0.2,0,0.2,1"])
    out.unlink()
    with pytest.raises(ValueError, match="expected one level per output of the network, 5; found 3"):
        cartpole_ddqn.export(src, out=tmp_path / "never.rs", levels=[-1, 0, 1])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cli.out", "five.safetensors"]


class Unconvertible:
    """A tensor's shape and dtype whose values cannot be read: converting it fails the test."""

    def __init__(self, shape):
        self.shape, self.dtype = shape, np.dtype(np.float32)

    def __array__(self, *args, **kwargs):
        raise AssertionError("a tensor outside the network was converted")


def test_tensors_outside_the_network_are_never_converted(tmp_path):
    """A tensor beside the network is refused without a prefix and ignored with one, as in a
    file; either way it is read by its shape alone, never converted: an object that cannot
    be converted is not, and a broadcast view of 10^8 float64 stays a view."""
    tensors = read_safetensors(FIXTURES / "cleanrl.safetensors")
    small = tmp_path / "small.rs"
    cartpole_ddqn.export({**tensors, "junk": np.zeros(3, np.float32)}, out=small, prefix="network.")
    for junk in (Unconvertible((10000, 10000)), np.broadcast_to(np.zeros(1), (10000, 10000))):
        source = {**tensors, "junk": junk}
        with pytest.raises(ValueError, match='1 tensors are not part of the network under prefix "network."'):
            cartpole_ddqn.export(source, out=tmp_path / "never.rs")
        tracemalloc.start()
        try:
            out = cartpole_ddqn.export(source, out=tmp_path / "big.rs", prefix="network.")
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert peak < 1 << 20, peak
        assert out.read_bytes() == small.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.rs", "small.rs"]


def test_many_tensors_beside_the_network_are_ignored_by_shape(tmp_path):
    """The network is chosen by names and shapes: thirty thousand tensors of one shape, or
    ten thousand each of its own, are ignored under a chosen prefix, and never converted."""
    tensors = read_safetensors(FIXTURES / "cleanrl.safetensors")
    many = {**tensors, **{f"aux.{i}.weight": np.zeros(3, np.float32) for i in range(30_000)}}
    out = cartpole_ddqn.export(many, out=tmp_path / "many.rs", prefix="network.")
    assert "30000 other tensors ignored" in out.read_text()
    shapes = {**tensors, **{f"aux.{i}.weight": np.zeros(i, np.float32) for i in range(10_000)}}
    out = cartpole_ddqn.export(shapes, out=tmp_path / "shapes.rs", prefix="network.")
    assert "10000 other tensors ignored" in out.read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["many.rs", "shapes.rs"]


def test_entries_that_are_not_arrays_are_refused_unconverted(tmp_path):
    """A list sharing one inner list a thousand times would convert to a thousand copies."""
    tensors = read_safetensors(FIXTURES / "cleanrl.safetensors")
    inner = [0.0] * 1000
    with pytest.raises(ValueError, match="'junk': expected an array or a tensor .*; found list"):
        cartpole_ddqn.export({**tensors, "junk": [inner] * 1000}, out=tmp_path / "x.rs", prefix="network.")
    # A range of ten billion levels is read to one past the most there can be, not built.
    with pytest.raises(ValueError):
        cartpole_ddqn.export(tensors, out=tmp_path / "y.rs", prefix="network.", levels=range(10**10))
    assert list(tmp_path.iterdir()) == []


def test_a_runs_policy_without_board_figures_gives_the_commands_warning(tools, tmp_path):
    """The command warns that the run never tried the policy as an int8 board runs it;
    Python's export said nothing."""
    run_dir = tmp_path / "run"
    run(tools["policy-export"], "train", "--episodes", "2", "--max-steps", "5", "--out", run_dir)
    with pytest.warns(UserWarning, match=r"summary\.json has no board-level trial figures") as caught:
        cartpole_ddqn.export(run_dir, tmp_path / "p.rs")
    assert len(caught) == 1 and caught[0].filename == __file__
    assert (tmp_path / "p.rs").is_file()
    # Raised as an error, the warning stops the export before anything is written.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(UserWarning):
            cartpole_ddqn.export(run_dir, tmp_path / "q.rs")
    assert not (tmp_path / "q.rs").exists()


def test_export_writes_nothing_into_a_runs_directory(tools, tmp_path):
    """The run's marker proves its other files: overwritten by an export, any junk in its
    place read as no marker."""
    run_dir = tmp_path / "run"
    run(tools["policy-export"], "train", "--episodes", "2", "--max-steps", "5", "--out", run_dir)
    marker = (run_dir / ".cartpole-run").read_bytes()
    for name in (".cartpole-run", "metrics.csv", "notes.rs"):
        with pytest.raises(ValueError, match="expected a path outside the output directories"):
            cartpole_ddqn.export(run_dir, run_dir / name)
    assert (run_dir / ".cartpole-run").read_bytes() == marker
    assert not (run_dir / "notes.rs").exists()
