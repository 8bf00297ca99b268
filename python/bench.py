"""Steps per second of the twin's environments against Gymnasium's CartPole-v1, side by side
in one run: the vector environment against `SyncVectorEnv` with as many CartPoles, and one
environment against one (both through `gymnasium.make`'s wrappers). Prints a Markdown table
with the machine and the date.

    python python/bench.py [--seconds S]
"""

import argparse
import datetime
import os
import platform
import subprocess
import time

import gymnasium as gym
import numpy as np

import cartpole_ddqn  # noqa: F401  (registers the environment)

ID = "cartpole_ddqn/Twin-v0"


def cpu_model():
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        for line in out.splitlines():
            if line.startswith("Model name:"):
                return line.split(":", 1)[1].strip()
    except (OSError, subprocess.CalledProcessError):
        pass
    return platform.processor() or "unknown"


def rate(step, steps_per_call, seconds):
    """Environment steps per second of `step`, called for about `seconds` after a warm-up."""
    for _ in range(50):
        step()
    calls, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        for _ in range(20):
            step()
        calls += 20
    return calls * steps_per_call / elapsed


def vector_rate(env, n, seconds):
    env.reset(seed=0)
    actions = np.random.default_rng(0).integers(0, 2, size=(64, n))
    k = iter(range(1 << 62))
    return rate(lambda: env.step(actions[next(k) % 64]), n, seconds)


def single_rate(env, seconds):
    env.reset(seed=0)
    actions = np.random.default_rng(0).integers(0, 2, size=4096).tolist()
    k = iter(range(1 << 62))

    def step():
        _, _, term, trunc, _ = env.step(actions[next(k) % 4096])
        if term or trunc:
            env.reset()

    return rate(step, 1, seconds)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="time per measurement")
    a = parser.parse_args()
    print(f"date: {datetime.date.today()}, nproc: {os.cpu_count()}, CPU: {cpu_model()}")
    print(f"gymnasium {gym.__version__}, numpy {np.__version__}, Python {platform.python_version()}")
    print()
    print("| environments | scenario | twin steps/s | CartPole-v1 steps/s | Gymnasium vectorised by | ratio |")
    print("|---:|---|---:|---:|---|---:|")
    for n in (16, 256):
        gym_vec = gym.make_vec("CartPole-v1", num_envs=n, vectorization_mode="sync")
        theirs = vector_rate(gym_vec, n, a.seconds)
        for scenario in ("nominal", "noise+delay=2+push"):
            twin = gym.make_vec(ID, num_envs=n, vectorization_mode="vector_entry_point", scenario=scenario)
            ours = vector_rate(twin, n, a.seconds)
            print(f"| {n} | {scenario} | {ours:,.0f} | {theirs:,.0f} | SyncVectorEnv | {ours / theirs:.1f}x |")
    theirs = single_rate(gym.make("CartPole-v1"), a.seconds)
    for scenario in ("nominal", "noise+delay=2+push"):
        ours = single_rate(gym.make(ID, scenario=scenario), a.seconds)
        print(f"| 1 | {scenario} | {ours:,.0f} | {theirs:,.0f} | (one env, `gymnasium.make`) | {ours / theirs:.2f}x |")


if __name__ == "__main__":
    main()
