#!/usr/bin/env bash
# The processor-in-the-loop study of docs/PIL.md: on each microcontroller target of the
# matrix, in QEMU, the board's controller driven by the twin's world over the link, nominal
# and two perturbed scenarios (encoders through the observer; noise, dead time and pushes),
# 500 periods an episode, each period compared with the same code run here, and the
# target's time per period. 1,000 episodes a row; the float policy on the cores without an
# FPU (soft float, some 700,000 instructions a period) gets 100.
# And the C application (scripts/c-app.sh) on the Cortex-M4F, 200 episodes a row (100,000
# periods a format). Writes docs/results/pil-TARGET-FORMAT.json and pil-c-app-FORMAT.json,
# and, on the Cortex-M0, pil-thumbv6m-none-eabi-monitor.json (the integer pipeline with and
# without the runtime monitor, through faults), and prints each run's wall time.
#   scripts/pil-study.sh [TARGET... | c-app]
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/targets.sh
targets=$(mcu_targets)
targets="$targets c-app"
[ $# -gt 0 ] && targets="$*"
cargo build -q --release -p host-sim
run() { # NAME FORMAT EPISODES --pil... : one results file
  local name=$1 format=$2 episodes=$3 controller=policy start=$SECONDS
  shift 3
  [ "$format" = int8 ] && controller=policy-int
  echo "== $name $format: $episodes episodes a row"
  target/release/host-sim eval "$@" --controller "$controller" \
    --scenario nominal,encoder,noise+delay+push --episodes "$episodes" --json \
    >"docs/results/pil-$name-$format.json"
  echo "$name $format: $((SECONDS - start)) s"
}
monitor() { # the runtime monitor on the Cortex-M0's integer pipeline, through faults
  local start=$SECONDS
  echo "== thumbv6m-none-eabi: policy-int with and without the runtime monitor"
  target/release/host-sim eval --pil qemu:thumbv6m-none-eabi \
    --controller policy-int,monitored-int --horizon 1000 --episodes 200 --json \
    --scenario encoder,encoder+stuck=25/500,noise+delay+encoder+glitch+stuck+drop+late+weak=0.5+reset \
    >docs/results/pil-thumbv6m-none-eabi-monitor.json
  echo "monitor: $((SECONDS - start)) s"
}
for t in $targets; do
  if [ "$t" = c-app ]; then
    elf=$(scripts/c-app.sh | tail -1)
    for format in int8 f32; do
      run c-app "$format" 200 --pil qemu:thumbv7em-none-eabihf --pil-elf "$elf"
    done
    continue
  fi
  cargo build -q --release -p selftest-app --bin pil --target "$t"
  for format in int8 f32; do
    episodes=1000
    [ "$format" = f32 ] && [[ $t != *eabihf ]] && episodes=100
    run "$t" "$format" "$episodes" --pil "qemu:$t"
  done
  if [ "$t" = thumbv6m-none-eabi ]; then monitor; fi
done
