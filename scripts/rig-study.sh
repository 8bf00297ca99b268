#!/usr/bin/env bash
# The rig study of docs/RIGS.md, end to end, for the desk rig at 50 Hz and at 100 Hz: the
# board's identification experiments run on the true rig (simulated: rigs/desk*.toml is the
# truth), the rig identified from those logs and the builder's measured rig file
# (rigs/desk*-measured.toml) into rigs/desk*-identified.toml, the deploy recipe trained for
# the identified rig, and the table: the shipped policy, the policy trained for the rig and
# bang-bang LQR designed on the true rig, 1,000 episodes of 10,000 periods each in the true
# rig's continuous world, the state read exactly and through the encoders.
# Writes runs/rig-study/ (logs, policies) and docs/results/rig-*.json.
#   scripts/rig-study.sh
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build -q --release -p policy-export -p host-sim
P=target/release/policy-export
S=target/release/host-sim
out=runs/rig-study
mkdir -p "$out"
eval_json() { "$S" eval --horizon 10000 --episodes 1000 --json "$@"; }
for rig in desk desk-100hz; do
  echo "== $rig: the experiments' logs, the identification"
  "$S" simulate-logs --world "rigs/$rig.toml" --rig "rigs/$rig-measured.toml" --out "$out/$rig.log"
  "$S" identify "$out/$rig.log" --rig "rigs/$rig-measured.toml" --out "rigs/$rig-identified.toml"
  echo "== $rig: the deploy recipe for the identified rig"
  rm -rf "$out/$rig-policy"
  "$P" train --preset deploy --rig "rigs/$rig-identified.toml" --seed 5 --out "$out/$rig-policy"
  echo "== $rig: the table, in the true rig's world"
  # The shipped policy's board models Gymnasium's machine at the rig's rate.
  board=rigs/gymnasium.toml
  [ "$rig" = desk-100hz ] && board=rigs/gymnasium-100hz.toml
  eval_json --rig "$board" --world "rigs/$rig.toml" --scenario delay=0,nominal,encoder \
    --controller policy >"docs/results/rig-$rig-shipped.json"
  eval_json --policy "$out/$rig-policy" --world "rigs/$rig.toml" --scenario nominal,encoder \
    --controller policy >"docs/results/rig-$rig-trained.json"
  eval_json --rig "rigs/$rig.toml" --scenario nominal,encoder \
    --controller lqr,lqr-predict >"docs/results/rig-$rig-lqr.json"
done
