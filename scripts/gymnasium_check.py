#!/usr/bin/env python3
"""Run a policy file in Gymnasium's own CartPole-v1, as a new user would: NumPy's float32
forward pass (its own summation order, not the firmware's), greedy actions, Gymnasium's
starts and physics. An independent check of what `host-sim eval --scenario nominal` says.

    python3 -m venv .venv && .venv/bin/pip install -r tests/data/requirements.txt
    .venv/bin/python scripts/gymnasium_check.py [--policy firmware/policy.safetensors] \
        [--episodes 1000] [--max-steps 500] [--seed 0]

Episode i starts from `env.reset(seed=SEED + i)`. Prints the failures as a count, the five
shortest episodes, and RMS theta and x. Exit status 2 on a bad policy file or argument.
"""

import argparse
import json
import struct
import sys

import gymnasium as gym
import numpy as np

SHAPES = {
    "fc1.weight": (None, 4),
    "fc1.bias": (None,),
    "fc2.weight": (None, None),
    "fc2.bias": (None,),
    "fc3.weight": (2, None),
    "fc3.bias": (2,),
}


def fail(msg):
    print(f"gymnasium_check.py: {msg}", file=sys.stderr)
    sys.exit(2)


def load(path):
    """The six tensors of a 4-H-H-2 safetensors file named as `policy-export` writes them
    (fc1, fc2, fc3), as float32 arrays."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        fail(f"cannot read the policy file {path}: {e.strerror}")
    if len(data) < 8:
        fail(f"{path}: expected a safetensors file, found {len(data)} bytes")
    n = struct.unpack("<Q", data[:8])[0]
    if n > len(data) - 8:
        fail(f"{path}: expected a safetensors file, found a header length of {n} in {len(data)} bytes")
    try:
        header = json.loads(data[8 : 8 + n])
    except (ValueError, UnicodeDecodeError):
        fail(f"{path}: expected a safetensors JSON header of {n} bytes, found none")
    body = data[8 + n :]
    tensors = {}
    for name, want in SHAPES.items():
        t = header.get(name)
        if not isinstance(t, dict):
            fail(f"{path}: expected a tensor {name}, found tensors {sorted(k for k in header if k != '__metadata__')}")
        if t.get("dtype") != "F32":
            fail(f"{path}: expected {name} as F32, found {t.get('dtype')}")
        shape = tuple(t.get("shape", ()))
        lo, hi = t.get("data_offsets", (0, -1))
        if len(shape) != len(want) or not 0 <= lo <= hi <= len(body) or hi - lo != 4 * int(np.prod(shape)):
            fail(f"{path}: {name} has shape {list(shape)} and offsets [{lo}, {hi}], which do not fit the file")
        tensors[name] = np.frombuffer(body[lo:hi], dtype="<f4").reshape(shape)
    h = tensors["fc1.bias"].shape[0]
    expect = {"fc1.weight": (h, 4), "fc2.weight": (h, h), "fc2.bias": (h,), "fc3.weight": (2, h), "fc3.bias": (2,)}
    for name, shape in expect.items():
        if tensors[name].shape != shape:
            fail(f"{path}: expected {name} of shape {list(shape)} for width {h}, found {list(tensors[name].shape)}")
    return tensors


def act(t, obs):
    x = np.asarray(obs, dtype=np.float32)
    h1 = np.maximum(t["fc1.weight"] @ x + t["fc1.bias"], np.float32(0))
    h2 = np.maximum(t["fc2.weight"] @ h1 + t["fc2.bias"], np.float32(0))
    q = t["fc3.weight"] @ h2 + t["fc3.bias"]
    # Ties go left, as np.argmax and the firmware both do.
    return int(np.argmax(q))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--policy", default="firmware/policy.safetensors")
    p.add_argument("--episodes", type=int, default=1000)
    p.add_argument("--max-steps", type=int, default=500)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    if a.episodes < 1:
        fail(f"--episodes: expected at least 1, found {a.episodes}")
    if a.max_steps < 1:
        fail(f"--max-steps: expected at least 1, found {a.max_steps}")
    if a.seed < 0:
        fail(f"--seed: expected a non-negative integer, found {a.seed}")
    t = load(a.policy)

    env = gym.make("CartPole-v1", max_episode_steps=a.max_steps)
    lengths, starts = [], []
    sq_theta = sq_x = 0.0
    steps = 0
    for i in range(a.episodes):
        obs, _ = env.reset(seed=a.seed + i)
        starts.append(obs.copy())
        n = 0
        while True:
            obs, _, terminated, truncated, _ = env.step(act(t, obs))
            n += 1
            sq_x += float(obs[0]) ** 2
            sq_theta += float(obs[2]) ** 2
            if terminated or truncated:
                break
        steps += n
        lengths.append(n)
        if (i + 1) % max(1, a.episodes // 10) == 0:
            print(f"  {i + 1} of {a.episodes} episodes", file=sys.stderr)
    failed = sum(n < a.max_steps for n in lengths)
    print(
        f"Gymnasium {gym.__version__} CartPole-v1, {a.policy}, {a.episodes} episodes of at most "
        f"{a.max_steps} steps from seeds {a.seed} to {a.seed + a.episodes - 1}:"
    )
    print(f"  {failed} of {a.episodes} failed")
    print(f"  RMS theta {np.degrees(np.sqrt(sq_theta / steps)):.3f} deg, RMS x {np.sqrt(sq_x / steps):.3f} m")
    print("  shortest:")
    for i in sorted(range(a.episodes), key=lambda i: lengths[i])[:5]:
        s = ", ".join(f"{v:.4f}" for v in starts[i])
        print(f"    seed {a.seed + i}: {lengths[i]} steps from [{s}]")


if __name__ == "__main__":
    main()
