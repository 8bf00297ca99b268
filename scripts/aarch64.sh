#!/usr/bin/env bash
# The host crates on 64-bit Arm Linux (Apple Silicon under Linux, Graviton), from an x86-64
# machine: cross-builds the plant, network, quantiser, importer, trainer and determinism
# tests for aarch64-unknown-linux-gnu and runs them under qemu-aarch64 (user-mode
# emulation). The trainer's tests check fingerprints recorded on x86-64 (a small run, and
# the shipped deploy recipe cut short), so a platform that computes other bits, here NEON's
# fused multiply-adds, fails them. `--full` also retrains the shipped policy and requires it
# bit for bit (hours under emulation: docs/TRAINING.md). Installs what it needs on
# Debian/Ubuntu: the Rust target, gcc-aarch64-linux-gnu (the linker), the aarch64 C library
# and qemu-user.
# `--packages` installs those system packages and nothing else (CI, while other steps run).
#   scripts/aarch64.sh [--full | --packages]
set -euo pipefail
cd "$(dirname "$0")/.."
case ${1:-} in
  --full | --packages | "") ;;
  *) echo "usage: scripts/aarch64.sh [--full | --packages] (found: '$1')" >&2; exit 2 ;;
esac
if [ "${1:-}" != --packages ]; then
  toolchain=$(sed -n 's/^channel *= *"\(.*\)"/\1/p' rust-toolchain.toml)
  rustup target add --toolchain "$toolchain" aarch64-unknown-linux-gnu >/dev/null
fi
if ! command -v qemu-aarch64 >/dev/null || ! command -v aarch64-linux-gnu-gcc >/dev/null; then
  sudo_=""
  [ "$(id -u)" -eq 0 ] || sudo_="sudo"
  echo "installing gcc-aarch64-linux-gnu, libc6-dev-arm64-cross, qemu-user (apt-get)"
  $sudo_ apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq \
    gcc-aarch64-linux-gnu libc6-dev-arm64-cross qemu-user >/dev/null
fi
[ "${1:-}" != --packages ] || exit 0
export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
runner=(qemu-aarch64 -L /usr/aarch64-linux-gnu)
# What is checked here is the platform's arithmetic, which a few cases of each property
# exercise; the search's breadth is x86-64's.
export PROPTEST_CASES=32
# In-process tests only: a test that starts one of the tools would exec an aarch64 binary
# outside the emulator. Of weights' own test files, the one whose networks compute: the
# rest read and write files byte by byte, which no platform changes. One cargo invocation
# builds them all: a package selection decides its dependencies' features, so building the
# trainer apart would build serde, image and plotters a second time.
selection=(-p firmware -p weights -p host-common -p policy-export --lib --test faults
  --test pytorch_fixtures)
cargo_test() { cargo test -q --profile quick --target aarch64-unknown-linux-gnu "$@"; }
command -v python3 >/dev/null ||
  { echo "aarch64: python3 not found (it lists the test binaries)" >&2; exit 1; }
# Compiler messages go to the terminal; the artefacts' JSON, to the listing.
built=$(cargo_test "${selection[@]}" --no-run --message-format=json-render-diagnostics | python3 -c '
import json, os, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m["profile"]["test"]:
        print(os.path.dirname(m["manifest_path"]), m["target"]["name"], m["executable"], sep="\t")
' | sort)
[ -n "$built" ] || { echo "aarch64: cargo listed no test binaries" >&2; exit 1; }
# Each test binary from its package's directory, as cargo runs it. Of the trainer's own tests,
# the bits recorded on x86-64, of a small run and of the shipped recipe cut short. Every
# transition it learns from is the plant's, so they hold the plant's bits too (the recorded
# Gymnasium trajectories are replayed on x86-64 only: the simulator's dependencies would
# double this step's cold build).
while IFS=$'\t' read -r dir name exe; do
  filter=()
  [ "$name" = policy_export ] && filter=(recorded_bits)
  # The exhaustive sweep of glitch sizes and positions (half a minute under emulation)
  # measures bounds of the observer's f32 arithmetic, which has no fused steps and so
  # gives the same results on every platform; the sampled glitches run here.
  [ "$name" = faults ] && filter=(--skip the_recovery_bounds_are_the_worst_glitches_measured)
  echo "$name (${exe##*/})"
  (cd "$dir" && "${runner[@]}" "$exe" -q "${filter[@]}" </dev/null)
done <<<"$built"
if [ "${1:-}" = "--full" ]; then
  CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="${runner[*]}" cargo_test -p e2e --test shipped_policy
fi
