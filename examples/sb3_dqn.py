"""Stable-Baselines3's DQN trained on the twin, deployed the project's way.

Trains SB3's DQN (a 4-64-64-2 Q-network, the controller's shape) on the twin's randomised
worlds, the domain the shipped policy was trained on (`policy-export train --preset deploy`),
or on one scenario (`--world nominal`: Gymnasium's CartPole-v1), saves SB3's own model.zip, exports it as the firmware's Rust module and the C header, and
evaluates it with `host-sim eval` beside the shipped policy. DQN's greedy policy comes and
goes as it trains, so, as SB3's own examples do, it is evaluated twenty times on 20
episodes of the training worlds and the best of those is the one deployed (its evaluation
steps are not counted as training). Writes into --out: model.zip (the last), best_model.zip
(the deployed), policy.rs, policy.h, eval-sb3.json, eval-shipped.json and report.md.

Needs the package and Stable-Baselines3 (with PyTorch) in one environment:

    pip install ./python stable-baselines3
    python examples/sb3_dqn.py --steps 100000

Run from the repository; the command-line tools are built with cargo if needed.
"""

import argparse
import json
import os
import platform
import subprocess
import sys
import time
import tomllib

import gymnasium as gym
import torch
from stable_baselines3 import DQN
from stable_baselines3.common.callbacks import BaseCallback, EvalCallback
from stable_baselines3.common.monitor import Monitor

import cartpole_ddqn  # noqa: F401  (registers cartpole_ddqn/Twin-v0)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# SB3 names its online network's layers q_net.q_net.{0,2,4} in policy.pth.
PREFIX = "q_net.q_net."


def tool(name, *args, capture=True):
    """Runs a project tool (built in release by cargo on first use)."""
    cmd = ["cargo", "run", "--release", "-q", "-p", name, "--", *args]
    done = subprocess.run(cmd, cwd=ROOT, check=True, text=True,
                          stdout=subprocess.PIPE if capture else None)
    return done.stdout


def deploy_domain():
    """The randomised worlds the shipped policy trained on, from the preset itself."""
    cfg = tomllib.loads(tool("policy-export", "train", "--preset", "deploy", "--print-config"))
    return cfg["domain"]


class Progress(BaseCallback):
    """One line per tenth of the budget: steps, episodes' mean length, rate, ETA."""

    def __init__(self, total):
        super().__init__()
        self.total, self.start, self.next = total, time.monotonic(), total // 10

    def _on_step(self):
        if self.num_timesteps >= self.next:
            self.next += self.total // 10
            spent = time.monotonic() - self.start
            rate = self.num_timesteps / spent
            lengths = [e["l"] for e in self.model.ep_info_buffer]
            mean = sum(lengths) / len(lengths) if lengths else 0.0
            print(f"  {self.num_timesteps:>8} env steps, mean episode {mean:6.1f}, "
                  f"{rate:6.0f} steps/s, ETA {(self.total - self.num_timesteps) / rate:5.0f} s",
                  flush=True)
        return True


def train(args, world):
    env = gym.make("cartpole_ddqn/Twin-v0", **world, max_episode_steps=500)
    # RL Baselines3 Zoo's tuned DQN for CartPole-v1, with the controller's 64-64 layers.
    model = DQN("MlpPolicy", env, learning_rate=2.3e-3, batch_size=64, buffer_size=100_000,
                learning_starts=1000, gamma=0.99, target_update_interval=10,
                train_freq=256, gradient_steps=128, exploration_fraction=0.16,
                exploration_final_eps=0.04, policy_kwargs=dict(net_arch=[64, 64]),
                seed=args.seed, device="cpu", verbose=0)
    judge_env = Monitor(gym.make("cartpole_ddqn/Twin-v0", **world, max_episode_steps=500))
    judge = EvalCallback(judge_env,
                         n_eval_episodes=20, eval_freq=max(args.steps // 20, 1),
                         best_model_save_path=args.out, deterministic=True, verbose=0)
    start = time.monotonic()
    model.learn(total_timesteps=args.steps, callback=[Progress(args.steps), judge])
    seconds = time.monotonic() - start
    model.save(os.path.join(args.out, "model.zip"))
    env.close()
    return seconds, judge.best_mean_reward


def evaluate(args, policy):
    """`host-sim eval`'s rows for the default and hard sets, as JSON."""
    out = os.path.join(args.out, f"eval-{'sb3' if policy else 'shipped'}.json")
    extra = ["--policy", policy, "--prefix", PREFIX] if policy else []
    text = tool("host-sim", "eval", "--scenario", "all,hard", "--controller", "policy",
                "--episodes", str(args.episodes), "--horizon", str(args.horizon),
                "--json", *extra)
    with open(out, "w") as f:
        f.write(text)
    return json.loads(text)


def label_of(provenance):
    """The --label of the run a provenance records."""
    argv = provenance["argv"]
    return argv[argv.index("--label") + 1] if "--label" in argv[:-1] else "sb3-dqn"


def merge(args, sb3, shipped):
    """Both evaluations into --results, `host-sim eval --json`'s format: the SB3 rows under
    the controller name --label, replacing that label's and the shipped policy's rows, so
    that runs of several trainings share one file (`host-sim tables` renders it). Its
    `provenance` lists the run behind each label, this one last."""
    doc = {"rows": [], "seed": shipped["seed"]}
    if os.path.exists(args.results):
        with open(args.results) as f:
            doc = json.load(f)
    rows = [r for r in doc["rows"] if r["controller"] not in ("policy", args.label)]
    rows += shipped["rows"] + [dict(r, controller=args.label) for r in sb3["rows"]]
    order = {r["scenario"]: i for i, r in enumerate(shipped["rows"])}
    doc["rows"] = sorted(rows, key=lambda r: order.get(r["scenario"], len(order)))
    runs = doc.get("provenance", [])
    runs = [runs] if isinstance(runs, dict) else runs
    ours = cartpole_ddqn.provenance("examples/sb3_dqn.py", sys.argv[1:])
    doc["provenance"] = [p for p in runs if label_of(p) != args.label] + [ours]
    tmp = args.results + ".tmp"
    with open(tmp, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    os.replace(tmp, args.results)


def cell(row):
    lo, hi = row["success_ci95"]
    return f"{100 * row['success_rate']:.1f}% [{100 * lo:.1f}, {100 * hi:.1f}]"


def report(args, world, trained, sb3, shipped):
    (kind, spec), = world.items()
    seconds, best = trained
    lines = [
        f"SB3 DQN trained on the {kind} `{spec}`: "
        f"{args.steps} env steps in {seconds:.0f} s, best evaluation {best:.1f} of 500 "
        f"(seed {args.seed}, one thread; "
        f"{platform.processor() or platform.machine()}, torch {torch.__version__}); "
        f"{args.episodes} episodes of {args.horizon} periods a row (`host-sim eval`).",
        "",
        "| scenario | shipped policy | SB3 DQN on the twin |",
        "| --- | ---: | ---: |",
    ]
    sb3 = {r["scenario"]: r for r in sb3["rows"]}
    for row in shipped["rows"]:
        lines.append(f"| `{row['scenario']}` | {cell(row)} | {cell(sb3[row['scenario']])} |")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(args.out, "report.md"), "w") as f:
        f.write(text)
    print(text)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--steps", type=int, default=100_000, help="SB3 training budget")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--episodes", type=int, default=1000, help="evaluation episodes a row")
    p.add_argument("--horizon", type=int, default=500, help="periods an evaluation episode")
    p.add_argument("--world", default="deploy",
                   help="`deploy` (the shipped policy's training domain) or a scenario")
    p.add_argument("--out", default=os.path.join(ROOT, "runs", "sb3-dqn"))
    p.add_argument("--results", help="a results file to merge both evaluations into")
    p.add_argument("--label", default="sb3-dqn", help="the SB3 rows' controller name there")
    args = p.parse_args()
    if args.steps < 10 or args.episodes < 1 or args.horizon < 1:
        sys.exit("sb3_dqn: --steps must be at least 10, --episodes and --horizon at least 1")
    torch.set_num_threads(1)
    os.makedirs(args.out, exist_ok=True)
    world = {"domain": deploy_domain()} if args.world == "deploy" else {"scenario": args.world}
    print(f"training SB3 DQN for {args.steps} env steps on {world}", flush=True)
    trained = train(args, world)
    model = os.path.join(args.out, "best_model.zip")
    for fmt, name in (("rust", "policy.rs"), ("c", "policy.h")):
        cartpole_ddqn.export(model, out=os.path.join(args.out, name), fmt=fmt, prefix=PREFIX)
    print(f"exported {model} as policy.rs and policy.h; evaluating", flush=True)
    sb3, shipped = evaluate(args, model), evaluate(args, None)
    report(args, world, trained, sb3, shipped)
    if args.results:
        merge(args, sb3, shipped)


if __name__ == "__main__":
    main()
