"""Record Gymnasium CartPole-v1 reference trajectories for the cart-pole controller.

Writes gym_traj_public.jsonl (seeds 0..19, random actions) and gym_traj_public_long.jsonl
(seeds 100..109, a feedback rule with random flips) to OUT_DIR, by default this script's
directory. The plant's bit-exactness tests replay them, so the output must not drift:

    python3 -m venv venv && . venv/bin/activate
    pip install gymnasium==1.4.0 numpy==2.4.6   # or: pip install -r requirements.txt
    python3 record_gymnasium.py OUT_DIR

Pinned: gymnasium 1.4.0, numpy 2.4.6. Other versions may draw or step differently, so the
script refuses to run with them.
"""

import json
import os
import sys
import tempfile

import gymnasium as gym
import numpy as np

GYMNASIUM_VERSION = "1.4.0"
NUMPY_VERSION = "2.4.6"

MAX_STEPS = 500  # CartPole-v1's time limit, applied here since the env is unwrapped
FEEDBACK_GAIN = 0.5  # push towards theta + 0.5 * theta_dot: keeps the pole up for long
FLIP_PROBABILITY = 0.05  # enough flips to leave the rule's limit cycle, rarely enough to stay up
FLIP_SEED_OFFSET = 7  # not this case's own stream; 7 is what the recorded files used


def check_versions():
    found = {"gymnasium": gym.__version__, "numpy": np.__version__}
    expected = {"gymnasium": GYMNASIUM_VERSION, "numpy": NUMPY_VERSION}
    if found != expected:
        print(f"record_gymnasium.py: expected {expected}, found {found}", file=sys.stderr)
        sys.exit(2)


def rollout(env, seed, kind, initial_state, choose):
    """Steps the unwrapped env from initial_state; choose(step, state) gives each action."""
    env.reset(seed=seed)
    # The reference states are the env's own float64 state, not the float32 observation.
    env.state = np.array(initial_state, dtype=np.float64)
    states = [[float(v) for v in env.state]]
    actions, rewards, terminated = [], [], []
    for step in range(MAX_STEPS):
        action = choose(step, env.state)
        _, reward, done, _, _ = env.step(action)
        actions.append(action)
        states.append([float(v) for v in env.state])
        rewards.append(float(reward))
        terminated.append(bool(done))
        if done:
            break
    return {
        "seed": seed,
        "kind": kind,
        "gymnasium_version": gym.__version__,
        "numpy_version": np.__version__,
        "initial_state": states[0],
        "actions": actions,
        "states": states,
        "states_hex": [[v.hex() for v in s] for s in states],
        "rewards": rewards,
        "terminated": terminated,
        "terminated_at": len(actions) if terminated[-1] else None,
    }


def public_case(env, seed):
    rng = np.random.default_rng(seed)
    initial_state = rng.uniform(-0.05, 0.05, size=4)
    # Drawn up front, so a case's actions do not depend on when it terminates.
    planned = [int(a) for a in rng.integers(0, 2, size=MAX_STEPS)]
    case = rollout(env, seed, "public", initial_state, lambda step, _: planned[step])
    case["planned_actions"] = planned
    return case


def long_case(env, seed):
    initial_state = np.random.default_rng(seed).uniform(-0.05, 0.05, size=4)
    flips = np.random.default_rng(seed + FLIP_SEED_OFFSET)

    def choose(_, state):
        action = int(state[2] + FEEDBACK_GAIN * state[3] > 0)
        # One draw every step, so the flips do not depend on the actions taken.
        return 1 - action if flips.random() < FLIP_PROBABILITY else action

    case = rollout(env, seed, "public_long", initial_state, choose)
    # Closed loop: what was planned is what was applied, and it replays open-loop.
    case["planned_actions"] = list(case["actions"])
    return case


def write_atomically(path, cases):
    # A reader (or an interrupted run) never sees a half-written file.
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), prefix=".tmp-", suffix=".jsonl")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            for case in cases:
                f.write(json.dumps(case) + "\n")
        os.chmod(tmp, 0o644)  # mkstemp's 0600 would hide the file from other users
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def main():
    if len(sys.argv) > 2:
        print(f"usage: {sys.argv[0]} [OUT_DIR]", file=sys.stderr)
        sys.exit(2)
    check_versions()
    out_dir = sys.argv[1] if len(sys.argv) == 2 else os.path.dirname(os.path.abspath(__file__))
    os.makedirs(out_dir, exist_ok=True)
    env = gym.make("CartPole-v1").unwrapped  # no TimeLimit or checker wrappers
    write_atomically(
        os.path.join(out_dir, "gym_traj_public.jsonl"),
        [public_case(env, seed) for seed in range(0, 20)],
    )
    write_atomically(
        os.path.join(out_dir, "gym_traj_public_long.jsonl"),
        [long_case(env, seed) for seed in range(100, 110)],
    )


if __name__ == "__main__":
    main()
