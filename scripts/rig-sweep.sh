#!/usr/bin/env bash
# Draws rigs at random within the range of the repository's rig files and runs, for each,
# the whole chain a builder runs (docs/RIGS.md): the board's identification experiments
# simulated on the true rig, `host-sim identify` from the builder's measured file, the
# deploy recipe trained for the identified rig, and the trained policy judged in the true
# rig's world through its encoders at 10,000 periods, as float and as int8. Prints one row
# per rig and seed: the share of episodes each board held.
#
#   scripts/rig-sweep.sh [--rigs N] [--seeds S] [--episodes E] [--draw SEED]
#                        [--profile PROFILE] [--out DIR]
#
#   --rigs N       rigs drawn (default 3)
#   --seeds S      training seeds per rig, 0..S (default 2)
#   --episodes E   evaluation episodes per board (default 200)
#   --draw SEED    the seed of the rigs' draw (default 1): the same seed draws the same rigs
#   --profile P    cargo profile the tools are built with (default release; `quick`
#                  computes the same bits)
#   --out DIR      where the rigs, logs, runs and evaluations go (default runs/rig-sweep)
#
# Each rig is drawn uniformly between the desk rig's and the lab rig's values (rigs/desk.toml,
# rigs/lab.toml): masses, the pole's centre of mass, the track, the motor's stall force and
# damping, the friction, the encoders; its dead time 0 or 1 period at 50 Hz. Its builder's
# file is the truth with the motor a datasheet's guess (the stall force 20% high, the
# damping a third low), the pole's centre of mass 1 cm short and the dead time unknown (0),
# as rigs/desk-measured.toml is the desk rig's.
set -euo pipefail
cd "$(dirname "$0")/.."

die() { echo "rig-sweep: $*" >&2; exit 2; }
rigs=3 seeds=2 episodes=200 draw=1 profile=release out=runs/rig-sweep
while [ $# -gt 0 ]; do
  [ $# -ge 2 ] && [ -n "$2" ] || die "$1 expects a value"
  case $1 in
    --rigs) rigs=$2 ;;
    --seeds) seeds=$2 ;;
    --episodes) episodes=$2 ;;
    --draw) draw=$2 ;;
    --profile) profile=$2 ;;
    --out) out=$2 ;;
    *) die "unknown option '${1:0:40}': expected --rigs, --seeds, --episodes, --draw, --profile or --out" ;;
  esac
  shift 2
done
for v in rigs seeds episodes draw; do
  [[ ${!v} =~ ^[0-9]+$ ]] || die "--$v expects a whole number, found '${!v:0:40}'"
done
[ "$rigs" -ge 1 ] && [ "$seeds" -ge 1 ] && [ "$episodes" -ge 1 ] ||
  die "--rigs, --seeds and --episodes expect at least 1"

cargo build -q --profile "$profile" -p host-sim -p policy-export
bin=${CARGO_TARGET_DIR:-target}/$([ "$profile" = dev ] && echo debug || echo "$profile")
mkdir -p "$out"

# rig-N.toml (the truth) and rig-N-measured.toml (the builder's), from one seeded draw.
python3 - "$out" "$rigs" "$draw" <<'EOF'
import random, sys
out, n, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
rng = random.Random(seed)
def between(desk, lab):
    return rng.uniform(min(desk, lab), max(desk, lab))
def rig(r, stall, damping, com, dead):
    return f"""# Drawn by scripts/rig-sweep.sh --draw {seed}.
cart_mass_kg = {r['cart']:.4f}
pole_mass_kg = {r['pole']:.4f}
pole_com_m = {com:.4f}
track_half_length_m = {r['track']:.3f}
end_stop_margin_m = {r['margin']:.3f}
period_s = 0.02
dead_time_periods = {dead}

[encoders]
cart_counts_per_m = {r['cart_counts']}
pole_counts_per_rev = {r['pole_counts']}

[actuator]
stall_force_n = {stall:.3f}
damping_n_s_per_m = {damping:.3f}

[friction]
cart_coulomb = {r['coulomb']:.4f}
pivot_viscous_n_m_s = {r['viscous']:.5f}
"""
for i in range(1, n + 1):
    track = between(0.4, 0.8)
    r = dict(
        cart=between(0.6, 2.0), pole=between(0.08, 0.25), com=between(0.22, 0.4),
        track=track, margin=track / 8, stall=between(5.0, 20.0), damping=between(3.0, 8.0),
        coulomb=between(0.0, 0.01), viscous=between(0.0, 0.002),
        cart_counts=round(between(15000, 20000)), pole_counts=round(between(2400, 4096)),
        dead=rng.randint(0, 1),
    )
    with open(f"{out}/rig-{i}.toml", "w") as f:
        f.write(rig(r, r['stall'], r['damping'], r['com'], r['dead']))
    with open(f"{out}/rig-{i}-measured.toml", "w") as f:
        f.write(rig(r, r['stall'] * 1.2, r['damping'] * 2 / 3, r['com'] - 0.01, 0))
EOF

# The share of episodes a board held, from `host-sim eval --json` on standard input.
held() {
  python3 -c '
import json, sys
rows = {r["controller"]: r for r in json.load(sys.stdin)["rows"]}
print(" ".join("%.1f" % (100 * (1 - rows[c]["failures"] / rows[c]["episodes"])) for c in ("policy", "policy-int")))'
}

printf '| rig | stall N, damping N s/m, pole kg at m, cart kg, dead time | seed | f32 %% | int8 %% |\n'
printf '| --- | --- | ---: | ---: | ---: |\n'
for i in $(seq 1 "$rigs"); do
  true_rig=$out/rig-$i.toml
  "$bin/host-sim" simulate-logs --world "$true_rig" --rig "$out/rig-$i-measured.toml" \
    --out "$out/rig-$i.log" >/dev/null 2>&1
  "$bin/host-sim" identify "$out/rig-$i.log" --rig "$out/rig-$i-measured.toml" \
    --out "$out/rig-$i-identified.toml" >"$out/rig-$i-identify.txt" 2>&1
  what=$(python3 -c '
import sys, tomllib
r = tomllib.load(open(sys.argv[1], "rb"))
a = r["actuator"]
print("%.1f, %.1f, %.3f at %.3f, %.2f, %d" % (a["stall_force_n"], a["damping_n_s_per_m"],
      r["pole_mass_kg"], r["pole_com_m"], r["cart_mass_kg"], r["dead_time_periods"]))' "$true_rig")
  for s in $(seq 0 $((seeds - 1))); do
    run=$out/rig-$i-seed-$s
    "$bin/policy-export" train --preset deploy --rig "$out/rig-$i-identified.toml" --seed "$s" \
      --out "$run" >"$run.train.txt" 2>&1
    "$bin/host-sim" eval --policy "$run" --world "$true_rig" --scenario encoder \
      --controller policy,policy-int --horizon 10000 --episodes "$episodes" --json \
      >"$run.eval.json" 2>/dev/null
    read -r f32 int8 < <(held <"$run.eval.json")
    printf '| %s | %s | %s | %s | %s |\n' "$i" "$what" "$s" "$f32" "$int8"
  done
done
