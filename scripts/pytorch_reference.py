#!/usr/bin/env python3
"""The `paper` preset of `policy-export train`, written as a PyTorch user would write it.

It is the baseline `scripts/bench_pytorch.py` times the Rust trainer against, so it follows
the trainer where cost or behaviour depends on it (policy-export/src/train, src/nn): Double
DQN on a 4-H-H-2 ReLU MLP, Xavier-normal weights and 0.01 biases, MSE TD loss, Adam,
global grad-norm clipping, a FIFO replay buffer sampled uniformly without replacement, one
gradient step per environment step once the buffer holds `max(learning_starts,
batch_size)` transitions, a hard target copy every `target_period` episodes, and
`eps = end + (start - end) * exp(-t / decay)` over environment steps. Episodes run on
Gymnasium's CartPole-v1 cut at `max_steps`; only termination zeroes the bootstrap.

Every hyperparameter comes from the TOML the Rust CLI prints, so none is written twice:

    target/release/policy-export train --preset paper --print-config > cfg.toml
    .venv/bin/python scripts/pytorch_reference.py --config cfg.toml --seed 0 [--episodes K]

It prints one JSON line: env_steps, wall_s (the training loop only), us_per_env_step and
the mean return of the last 100 episodes. One thread, float32, CPU.

Setup: CPU is all it needs, but the torch 2.15.0 wheel links the CUDA libraries, so it
cannot import without them. scripts/requirements-torch.txt pins the smallest set that imports
(torch's own dependency list adds triton, cuda-bindings, cusolver and nvtx, never loaded
here); --no-deps takes exactly that set:

    python3 -m venv .venv
    .venv/bin/pip install --no-deps -r scripts/requirements-torch.txt
"""

import argparse
import json
import math
import os
import stat
import sys
import time
import tomllib

import gymnasium as gym
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

# The Rust CLI caps its config reads too; a printed config is about 1 KB.
MAX_CONFIG_BYTES = 64 * 1024

# What this reference implements; any other value would silently change the algorithm.
REQUIRED = {
    "algo": "ddqn", "loss": "mse", "init": "xavier", "train_unit": "steps",
    "updates_per_train": 1, "target_update": "hard", "target_period_unit": "episodes",
    "eps_unit": "steps", "max_env_steps": 0, "domain": "", "reward": "",
    "compensate": False,
}
USED = [
    "width", "lr", "adam_beta1", "adam_beta2", "adam_eps", "gamma", "buffer_size",
    "batch_size", "learning_starts", "train_every", "target_period", "eps_start",
    "eps_end", "eps_decay", "episodes", "max_steps", "grad_clip",
]


def fail(msg):
    print(f"error: {msg}", file=sys.stderr)
    sys.exit(2)


def load_config(path):
    """The TOML at `path`, checked to be the preset this file implements."""
    try:
        # Non-blocking, so that opening a FIFO by mistake fails below instead of hanging.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as e:
        fail(f"--config {path}: {e.strerror}")
    with os.fdopen(fd, "rb") as f:
        # Checked on the open file, so a FIFO or device is never read from.
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            fail(f"--config {path}: not a regular file")
        data = f.read(MAX_CONFIG_BYTES + 1)
    if len(data) > MAX_CONFIG_BYTES:
        fail(f"--config {path}: larger than {MAX_CONFIG_BYTES} bytes")
    try:
        cfg = tomllib.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        fail(f"--config {path}: {e}")
    missing = [k for k in USED + list(REQUIRED) if k not in cfg]
    if missing:
        fail(f"--config {path}: missing keys {', '.join(missing)}")
    for key in USED:
        if isinstance(cfg[key], bool) or not isinstance(cfg[key], (int, float)):
            fail(f"--config {path}: {key} = {cfg[key]!r}; expected a number")
    for key, want in REQUIRED.items():
        if cfg[key] != want:
            fail(f"--config {path}: {key} = {cfg[key]!r}; this reference implements {want!r}")
    return cfg


def make_net(width):
    """4-H-H-2 ReLU MLP, initialised as the trainer's `init_weights` does."""
    net = nn.Sequential(
        nn.Linear(4, width), nn.ReLU(),
        nn.Linear(width, width), nn.ReLU(),
        nn.Linear(width, 2),
    )
    for m in net:
        if isinstance(m, nn.Linear):
            nn.init.xavier_normal_(m.weight)
            nn.init.constant_(m.bias, 0.01)
    return net


class Replay:
    """FIFO ring of preallocated arrays: a push is five row writes, a sample five gathers."""

    def __init__(self, capacity, rng):
        self.s = np.zeros((capacity, 4), np.float32)
        self.a = np.zeros(capacity, np.int64)
        self.r = np.zeros(capacity, np.float32)
        self.s2 = np.zeros((capacity, 4), np.float32)
        self.done = np.zeros(capacity, np.float32)
        self.capacity, self.pos, self.len, self.rng = capacity, 0, 0, rng

    def push(self, s, a, r, s2, terminated):
        i = self.pos
        self.s[i], self.a[i], self.r[i], self.s2[i], self.done[i] = s, a, r, s2, terminated
        self.pos = (i + 1) % self.capacity
        self.len = min(self.len + 1, self.capacity)

    def sample(self, n):
        idx = self.rng.choice(self.len, n, replace=False)
        return tuple(torch.from_numpy(x[idx]) for x in (self.s, self.a, self.r, self.s2, self.done))


def update(online, target, opt, batch, cfg):
    """One Double DQN step: the online net picks a', the target net scores it."""
    s, a, r, s2, done = batch
    q = online(s).gather(1, a.unsqueeze(1)).squeeze(1)
    with torch.no_grad():
        a2 = online(s2).argmax(1, keepdim=True)
        y = r + cfg["gamma"] * (1.0 - done) * target(s2).gather(1, a2).squeeze(1)
    loss = F.mse_loss(q, y)
    opt.zero_grad(set_to_none=True)
    loss.backward()
    nn.utils.clip_grad_norm_(online.parameters(), cfg["grad_clip"])
    opt.step()


def act(online, obs, eps, rng):
    if rng.random() < eps:
        return int(rng.integers(2))
    with torch.no_grad():
        return int(online(torch.from_numpy(obs)).argmax())


def train(cfg, seed, episodes):
    """Returns (env steps, training-loop seconds, per-episode returns)."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    online = make_net(cfg["width"])
    target = make_net(cfg["width"])
    target.load_state_dict(online.state_dict())
    # fused: PyTorch's fastest Adam on CPU (one kernel for all six tensors), same update.
    opt = torch.optim.Adam(online.parameters(), lr=cfg["lr"], eps=cfg["adam_eps"],
                           betas=(cfg["adam_beta1"], cfg["adam_beta2"]), fused=True)
    buf = Replay(cfg["buffer_size"], rng)
    env = gym.make("CartPole-v1", max_episode_steps=cfg["max_steps"])
    starts = max(cfg["learning_starts"], cfg["batch_size"])
    steps, returns = 0, []
    t0 = time.perf_counter()
    for ep in range(episodes):
        obs, _ = env.reset(seed=seed if ep == 0 else None)
        ret, over = 0, False
        while not over:
            eps = cfg["eps_end"] + (cfg["eps_start"] - cfg["eps_end"]) * math.exp(
                -steps / cfg["eps_decay"])
            a = act(online, obs, eps, rng)
            obs2, r, terminated, truncated, _ = env.step(a)
            steps += 1
            ret += r
            buf.push(obs, a, r, obs2, terminated)
            if buf.len >= starts and steps % cfg["train_every"] == 0:
                update(online, target, opt, buf.sample(cfg["batch_size"]), cfg)
            obs, over = obs2, terminated or truncated
        returns.append(ret)
        if (ep + 1) % cfg["target_period"] == 0:
            target.load_state_dict(online.state_dict())
    return steps, time.perf_counter() - t0, returns


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--config", required=True, help="TOML from `train --print-config`")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--episodes", type=int, help="override the config's episode count")
    args = p.parse_args()
    cfg = load_config(args.config)
    episodes = cfg["episodes"] if args.episodes is None else args.episodes
    if episodes < 1:
        fail("--episodes must be at least 1")
    # One thread each side: the comparison is per core, not per machine.
    torch.set_num_threads(1)
    torch.set_num_interop_threads(1)
    steps, wall, returns = train(cfg, args.seed, episodes)
    tail = returns[-100:]
    print(json.dumps({
        "seed": args.seed, "episodes": episodes, "env_steps": steps,
        "wall_s": round(wall, 4), "us_per_env_step": round(wall * 1e6 / steps, 2),
        "final_mean100": round(sum(tail) / len(tail), 2), "torch": torch.__version__,
    }))


if __name__ == "__main__":
    main()
