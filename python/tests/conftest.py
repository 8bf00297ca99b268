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
