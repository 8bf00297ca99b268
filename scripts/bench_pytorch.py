#!/usr/bin/env python3
"""Paper-preset training cost per environment step: `policy-export` against the PyTorch
reference (`scripts/pytorch_reference.py`), one thread each, measured in one run.

    cargo build --release -p policy-export
    .venv/bin/python scripts/bench_pytorch.py [--seeds 3] [--episodes K] [--kernel avx2]

Both sides get the same configuration (the one `train --preset paper --print-config`
prints), the same seeds and the same episode count, and each is timed over its training
loop alone (Rust: `wall_s` of the run's summary, which excludes the final evaluation;
PyTorch: the reference's `wall_s`). The sides alternate seed by seed, so a change in the
machine's load falls on both. Prints a Markdown table; exits 2 if the binary is missing.
"""

import argparse
import datetime
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BIN = ROOT / "target" / "release" / "policy-export"
REFERENCE = ROOT / "scripts" / "pytorch_reference.py"
# The Rust summary line: "seed   0: 300 episodes, final mean100 ..., 0.1 s, 11.8 us/step".
SUMMARY = re.compile(
    r"^seed\s+(\d+): (\d+) episodes, final mean100\s+([\d.]+).*, ([\d.]+) us/step$")


def fail(msg):
    print(f"error: {msg}", file=sys.stderr)
    sys.exit(2)


def run(cmd, env=None):
    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if p.returncode != 0:
        fail(f"{' '.join(map(str, cmd))} exited {p.returncode}:\n{p.stderr.strip()}")
    return p.stdout


def check_binary():
    if not BIN.is_file():
        fail(f"{BIN} not found; build it first: cargo build --release -p policy-export")
    if "--threads" not in run([BIN, "train", "--help"]):
        fail(f"{BIN} has no --threads (stale); rebuild: cargo build --release -p policy-export")


def rust(cfg, seed, extra, out):
    """One Rust run: its summary line, cross-checked against its summary.json."""
    stdout = run([BIN, "train", "--config", cfg, "--threads", "1", "--seed", str(seed),
                  "--out", out, *extra])
    lines = [m for m in map(SUMMARY.match, stdout.splitlines()) if m]
    if not lines:
        fail(f"no summary line in the Rust output:\n{stdout}")
    line = lines[-1]
    s = json.loads((Path(out) / "summary.json").read_text())
    # The line rounds to 0.1 us; the JSON has the same figure unrounded.
    if abs(s["us_per_env_step"] - float(line[4])) > 0.051 or int(line[2]) != s["episodes_run"]:
        fail(f"summary line and summary.json disagree: {line[0]!r}")
    return {"episodes": s["episodes_run"], "env_steps": s["env_steps"], "wall_s": s["wall_s"],
            "us": s["us_per_env_step"], "mean100": s["final_mean100"], "kernel": s["kernel"]}


def pytorch(cfg, seed, episodes):
    env = dict(os.environ, OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    out = run([sys.executable, REFERENCE, "--config", cfg, "--seed", str(seed),
               "--episodes", str(episodes)], env=env)
    r = json.loads(out.strip().splitlines()[-1])
    return {"episodes": r["episodes"], "env_steps": r["env_steps"], "wall_s": r["wall_s"],
            "us": r["us_per_env_step"], "mean100": r["final_mean100"], "torch": r["torch"]}


def machine():
    info = open("/proc/cpuinfo").read()
    model = re.search(r"^model name\s*:\s*(.*)$", info, re.M)
    flags = set((re.search(r"^flags\s*:\s*(.*)$", info, re.M) or ["", ""])[1].split())
    simd = ", ".join(f for f in ("avx512f", "avx2") if f in flags) or "neither avx512f nor avx2"
    nproc = subprocess.run(["nproc"], capture_output=True, text=True).stdout.strip()
    return model[1] if model else "unknown", simd, nproc


def load():
    return " ".join(open("/proc/loadavg").read().split()[:3])


def report(rows, meta):
    r_med = statistics.median(r["us"] for r, _ in rows)
    p_med = statistics.median(p["us"] for _, p in rows)
    out = [
        f"Paper preset, {meta['episodes']} episodes per seed, one thread each "
        f"({meta['date']}).",
        "",
        f"- CPU: {meta['cpu']} ({meta['simd']}); nproc {meta['nproc']}; "
        f"load average {meta['load0']} before, {meta['load1']} after",
        f"- Rust: policy-export at {meta['rev']}, kernel {rows[0][0]['kernel']}, --threads 1",
        f"- PyTorch: {rows[0][1]['torch']}, Python {sys.version.split()[0]}, "
        "torch.set_num_threads(1)",
        "",
        "| seed | Rust env steps | Rust us/step | Rust mean100 "
        "| PyTorch env steps | PyTorch us/step | PyTorch mean100 | PyTorch/Rust |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for seed, (r, p) in enumerate(rows):
        out.append(f"| {seed} | {r['env_steps']} | {r['us']:.2f} | {r['mean100']:.1f} "
                   f"| {p['env_steps']} | {p['us']:.1f} | {p['mean100']:.1f} "
                   f"| {p['us'] / r['us']:.0f}x |")
    out.append(f"| median | | {r_med:.2f} | | | {p_med:.1f} | | **{p_med / r_med:.0f}x** |")
    out += ["", f"Ratio of medians, PyTorch/Rust per env step: **{p_med / r_med:.1f}x**"]
    return "\n".join(out)


def git_rev():
    p = subprocess.run(["git", "-C", ROOT, "describe", "--always", "--dirty"],
                       capture_output=True, text=True)
    return p.stdout.strip() or "unknown"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=3, help="seeds 0..S (default 3)")
    ap.add_argument("--episodes", type=int, help="episodes per run, both sides "
                    "(default: the preset's)")
    ap.add_argument("--kernel", default="auto",
                    help="the Rust side's kernel (default auto: the CPU's widest)")
    args = ap.parse_args()
    if args.seeds < 1 or (args.episodes is not None and args.episodes < 1):
        fail("--seeds and --episodes must be at least 1")
    check_binary()
    cpu, simd, nproc = machine()
    meta = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "cpu": cpu, "simd": simd, "nproc": nproc, "rev": git_rev(), "load0": load()}
    with tempfile.TemporaryDirectory(prefix="bench-pytorch-") as tmp:
        cfg = os.path.join(tmp, "paper.toml")
        Path(cfg).write_text(run([BIN, "train", "--preset", "paper", "--print-config"]))
        episodes = args.episodes or int(re.search(r"^episodes = (\d+)$",
                                                  Path(cfg).read_text(), re.M)[1])
        extra = ["--episodes", str(episodes), "--kernel", args.kernel]
        rows = []
        for seed in range(args.seeds):
            r = rust(cfg, seed, extra, os.path.join(tmp, f"rust-{seed}"))
            p = pytorch(cfg, seed, episodes)
            if r["episodes"] != episodes or p["episodes"] != episodes:
                fail(f"seed {seed}: episode counts {r['episodes']}, {p['episodes']}; "
                     f"expected {episodes} each")
            print(f"seed {seed}: Rust {r['us']:.2f} us/step, PyTorch {p['us']:.1f} us/step",
                  file=sys.stderr)
            rows.append((r, p))
    meta.update(episodes=episodes, load1=load())
    print(report(rows, meta))


if __name__ == "__main__":
    main()
