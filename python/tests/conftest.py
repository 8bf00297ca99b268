"""What the tests share: the repository, and the command-line tools the package is checked
against, built by cargo (a no-op when the test suite built them already)."""

import json
import pathlib
import struct
import subprocess

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def tools():
    """Paths of the `host-sim` and `policy-export` binaries of the `quick` profile."""
    subprocess.run(
        ["cargo", "build", "--quiet", "--profile", "quick", "--bin", "host-sim", "--bin", "policy-export"],
        cwd=REPO,
        check=True,
    )
    meta = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps"],
        cwd=REPO,
        check=True,
        capture_output=True,
        text=True,
    )
    target = pathlib.Path(json.loads(meta.stdout)["target_directory"]) / "quick"
    return {"host-sim": target / "host-sim", "policy-export": target / "policy-export"}


def run(tool, *args):
    """A tool's standard output; its failure fails the test."""
    done = subprocess.run([str(tool), *map(str, args)], cwd=REPO, check=True, capture_output=True, text=True)
    return done.stdout


def read_safetensors(path):
    """A safetensors file's tensors as NumPy arrays, read by the format's definition (a
    little-endian u64 header length, a JSON header, the raw data): a reference independent
    of the project's reader."""
    data = pathlib.Path(path).read_bytes()
    (n,) = struct.unpack("<Q", data[:8])
    header = json.loads(data[8 : 8 + n])
    body = data[8 + n :]
    dtypes = {"F32": "<f4", "F64": "<f8", "F16": "<f2"}
    out = {}
    for name, t in header.items():
        if name == "__metadata__":
            continue
        lo, hi = t["data_offsets"]
        out[name] = np.frombuffer(body[lo:hi], dtype=dtypes[t["dtype"]]).reshape(t["shape"])
    return out


def write_safetensors(path, tensors):
    """Writes float32 `tensors` as a safetensors file, by the format's definition, with no
    metadata: a checkpoint as `safetensors.torch.save_file` writes one, recording no levels."""
    header, body = {}, b""
    for name, a in tensors.items():
        data = np.ascontiguousarray(a, dtype="<f4").tobytes()
        header[name] = {"dtype": "F32", "shape": list(a.shape), "data_offsets": [len(body), len(body) + len(data)]}
        body += data
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 8)
    pathlib.Path(path).write_bytes(struct.pack("<Q", len(text)) + text + body)


def five_outputs(seed=0):
    """A width-64 network of five outputs with random weights, as a state dict."""
    rng = np.random.default_rng(seed)
    shapes = {"fc1": (64, 4), "fc2": (64, 64), "fc3": (5, 64)}
    out = {}
    for layer, shape in shapes.items():
        out[f"{layer}.weight"] = (rng.standard_normal(shape) * 0.3).astype(np.float32)
        out[f"{layer}.bias"] = (rng.standard_normal(shape[0]) * 0.1).astype(np.float32)
    return out
