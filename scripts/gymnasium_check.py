#!/usr/bin/env python3
"""Run a policy file in Gymnasium's own CartPole-v1, as a new user would: NumPy's float32
forward pass (its own summation order, not the firmware's), greedy actions, Gymnasium's
starts and physics. An independent check of what `host-sim eval --scenario nominal` says.

    python3 -m venv .venv && .venv/bin/pip install -r tests/data/requirements.txt
    .venv/bin/python scripts/gymnasium_check.py [--policy shipped/policy.safetensors] \
        [--episodes 1000] [--max-steps 500] [--seed 0]

Episode i starts from `env.reset(seed=SEED + i)`. Prints the failures as a count, the five
shortest episodes, and RMS theta and x. Exit status 2, with one line, on a bad policy file
or argument (scripts/safe_input.py): the policy a regular file of at most 64 MiB, episodes
and steps each at most 1,000,000 and together at most 100,000,000, the seed below 2^32.
"""

import json
import math
import struct
import sys

from safe_input import Refusal, bounded_int, parser, quote, read_capped, run

PROG = "gymnasium_check.py"
# The tools' own limits (docs/HOSTILE_INPUT.md): a policy file of at most 64 MiB whose
# header declares at most 1 MiB.
MAX_POLICY_BYTES = 64 << 20
MAX_HEADER_BYTES = 1 << 20
MAX_EPISODES = 1_000_000
MAX_STEPS = 1_000_000
# Episodes times steps: about an hour of Gymnasium at the limit.
MAX_TOTAL_STEPS = 100_000_000
WIDTHS = (16, 32, 64, 128, 256)
SHAPES = {
    "fc1.weight": (None, 4),
    "fc1.bias": (None,),
    "fc2.weight": (None, None),
    "fc2.bias": (None,),
    "fc3.weight": (2, None),
    "fc3.bias": (2,),
}


def tensor_spec(path, header, name, body_len):
    """The shape and byte range of tensor `name` in a parsed header, checked."""
    t = header.get(name)
    if not isinstance(t, dict):
        found = sorted(k for k in header if k != "__metadata__")[:10]
        raise Refusal(f"{path}: expected a tensor {name}, found tensors {quote(str(found))}")
    if t.get("dtype") != "F32":
        raise Refusal(f"{path}: expected {name} as F32, found {quote(str(t.get('dtype')))}")
    shape, offsets = t.get("shape"), t.get("data_offsets")
    ints = lambda v, n: isinstance(v, list) and len(v) == n and all(type(x) is int and x >= 0 for x in v)
    if not (ints(shape, len(SHAPES[name])) and ints(offsets, 2)):
        raise Refusal(f"{path}: expected {name} with a shape and data_offsets of whole numbers, "
                      f"found {quote(str(t))}")
    lo, hi = offsets
    if not lo <= hi <= body_len or hi - lo != 4 * math.prod(shape):
        raise Refusal(f"{path}: {name} has shape {shape} and offsets [{lo}, {hi}], which do not "
                      f"fit the file's {body_len} bytes of data")
    return tuple(shape), lo, hi


def load(path):
    """The six tensors of a 4-H-H-2 safetensors file named as `policy-export` writes them
    (fc1, fc2, fc3), as float32 arrays; every check before NumPy is imported."""
    data = read_capped(path, MAX_POLICY_BYTES)
    if len(data) < 8:
        raise Refusal(f"{path}: expected a safetensors file, found {len(data)} bytes")
    n = struct.unpack("<Q", data[:8])[0]
    if n > min(MAX_HEADER_BYTES, len(data) - 8):
        raise Refusal(f"{path}: expected a safetensors header of at most "
                      f"{min(MAX_HEADER_BYTES, len(data) - 8)} bytes, found a length of {n}")
    try:
        header = json.loads(data[8 : 8 + n])
    except (ValueError, UnicodeDecodeError, RecursionError):
        raise Refusal(f"{path}: expected a safetensors JSON header of {n} bytes, found none")
    if not isinstance(header, dict):
        raise Refusal(f"{path}: expected a JSON object as the header, found {type(header).__name__}")
    body = data[8 + n :]
    specs = {name: tensor_spec(path, header, name, len(body)) for name in SHAPES}
    h = specs["fc1.bias"][0][0]
    expect = {"fc1.weight": (h, 4), "fc1.bias": (h,), "fc2.weight": (h, h), "fc2.bias": (h,),
              "fc3.weight": (2, h), "fc3.bias": (2,)}
    if h not in WIDTHS:
        raise Refusal(f"{path}: expected a hidden width of {WIDTHS}, found {h}")
    for name, shape in expect.items():
        if specs[name][0] != shape:
            raise Refusal(f"{path}: expected {name} of shape {list(shape)} for width {h}, "
                          f"found {list(specs[name][0])}")
    import numpy as np

    tensors = {}
    for name, (shape, lo, hi) in specs.items():
        tensors[name] = np.frombuffer(body[lo:hi], dtype="<f4").reshape(shape)
        if not np.all(np.isfinite(tensors[name])):
            raise Refusal(f"{path}: expected finite values in {name}, found NaN or infinity")
    return tensors


def act(t, obs):
    import numpy as np

    x = np.asarray(obs, dtype=np.float32)
    h1 = np.maximum(t["fc1.weight"] @ x + t["fc1.bias"], np.float32(0))
    h2 = np.maximum(t["fc2.weight"] @ h1 + t["fc2.bias"], np.float32(0))
    q = t["fc3.weight"] @ h2 + t["fc3.bias"]
    # Ties go left, as np.argmax and the firmware both do.
    return int(np.argmax(q))


def main():
    p = parser(PROG, __doc__.split("\n\n")[0])
    p.add_argument("--policy", default="shipped/policy.safetensors")
    p.add_argument("--episodes", type=bounded_int(1, MAX_EPISODES), default=1000)
    p.add_argument("--max-steps", type=bounded_int(1, MAX_STEPS), default=500)
    p.add_argument("--seed", type=bounded_int(0, 2**32 - 1), default=0)
    a = p.parse_args()
    if a.episodes * a.max_steps > MAX_TOTAL_STEPS:
        raise Refusal(f"--episodes x --max-steps: expected at most {MAX_TOTAL_STEPS} steps, "
                      f"found {a.episodes * a.max_steps}")
    t = load(a.policy)
    import gymnasium as gym
    import numpy as np

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
    run(PROG, main)
