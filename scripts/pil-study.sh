#!/usr/bin/env bash
# The processor-in-the-loop study of docs/PIL.md: on each microcontroller target of the
# matrix, in QEMU, the board's controller driven by the twin's world over the link, nominal
# and two perturbed scenarios (encoders through the observer; noise, dead time and pushes),
# 500 periods an episode, each period compared with the same code run here, and the
# target's time per period. 1,000 episodes a row; the float policy on the cores without an
# FPU (soft float, some 700,000 instructions a period) gets 100.
# Writes docs/results/pil-TARGET-FORMAT.json and prints each run's wall time.
#   scripts/pil-study.sh [TARGET...]
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/targets.sh
targets=$(mcu_targets)
[ $# -gt 0 ] && targets="$*"
cargo build -q --release -p host-sim
for t in $targets; do
  cargo build -q --release -p selftest-app --bin pil --target "$t"
  for format in int8 f32; do
    controller=policy
    [ "$format" = int8 ] && controller=policy-int
    episodes=1000
    [ "$format" = f32 ] && [[ $t != *eabihf ]] && episodes=100
    echo "== $t $format: $episodes episodes a row"
    start=$SECONDS
    target/release/host-sim eval --pil "qemu:$t" --controller "$controller" \
      --scenario nominal,encoder,noise+delay+push --episodes "$episodes" --json \
      >"docs/results/pil-$t-$format.json"
    echo "$t $format: $((SECONDS - start)) s"
  done
done
