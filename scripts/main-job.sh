#!/usr/bin/env bash
# The main job, from a fresh machine: train the shipped policy's recipe, export it as Rust
# const arrays and a C header, say whether the trained files equal the shipped ones, and
# check the trained policy in closed loop against the plant through the firmware's
# controller. The test suite is scripts/test.sh's job (it also checks, bit for bit, that the
# recipe regenerates the shipped policy).
#   scripts/main-job.sh [RUN_DIR]      (default runs/shipped)
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh --host
. scripts/targets.sh
# The toolchain by name: rustup then leaves rust-toolchain.toml's components and
# microcontroller targets alone, where it would otherwise fetch them on demand for a job
# that builds for the host only (docs/PERFORMANCE.md).
RUSTUP_TOOLCHAIN=$(rust_channel)
export RUSTUP_TOOLCHAIN
out=${1:-runs/shipped}
cargo build -q --release -p policy-export -p host-sim
pe() { target/release/policy-export "$@"; }

echo "== train (deploy preset, seed 5) -> $out"
pe train --preset deploy --seed 5 --out "$out"
echo "== export"
# Beside the run directory, not in it: a file added to it would make it no longer the
# tool's to replace on the next run.
pe export "$out" --format c --out "${out%/}-cartpole_policy.h"
if cmp -s "$out/policy.rs" shipped/src/policy.rs &&
   cmp -s "$out/policy.safetensors" shipped/policy.safetensors; then
  echo "$out/policy.rs and policy.safetensors are byte-identical to the shipped ones"
else
  echo "$out/policy.rs differs from shipped/src/policy.rs; to ship it:"
  echo "  cp $out/policy.rs shipped/src/policy.rs && cp $out/policy.safetensors shipped/"
fi
echo "== closed loop: the trained policy through firmware::controller against the plant"
target/release/host-sim eval --policy "$out" --scenario nominal \
    --horizon 500,10000 --controller policy,lqr --min-success 1.0
