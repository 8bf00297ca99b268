#!/usr/bin/env bash
# The main job, from a fresh machine: train the shipped policy's recipe, export it as Rust
# const arrays and a C header, compare with the policy compiled into firmware, and check the
# compiled policy in closed loop against the plant.
#   scripts/main-job.sh [RUN_DIR]      (default runs/shipped)
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
out=${1:-runs/shipped}
pe() { cargo run -q --release -p policy-export -- "$@"; }

echo "== train (deploy preset, seed 5, portable kernel; under 2 minutes) -> $out"
pe train --preset deploy --kernel portable --seed 5 --out "$out"
echo "== export"
pe export "$out" --format c --out "$out/cartpole_policy.h"
if cmp -s "$out/policy.rs" firmware/src/policy.rs &&
   cmp -s "$out/policy.safetensors" firmware/policy.safetensors; then
  echo "$out/policy.rs and policy.safetensors are byte-identical to the shipped ones"
else
  echo "$out/policy.rs differs from firmware/src/policy.rs; to ship it:"
  echo "  cp $out/policy.rs firmware/src/policy.rs && cp $out/policy.safetensors firmware/"
fi
echo "== closed loop: the trained policy through firmware::controller against the plant"
cargo run -q --release -p host-sim -- eval --policy "$out" --scenario nominal \
    --horizon 500,10000 --controller policy,lqr,random --min-success 1.0
echo "== end-to-end tests (the compiled firmware policy, train -> export -> load -> balance)"
cargo test -q --profile quick -p e2e
