#!/usr/bin/env bash
# Builds the self-test application for one microcontroller target and runs it in QEMU; the
# exit status is the self-test's verdict (0 PASS, 1 FAIL, 2 an unknown target).
#
#   scripts/mcu.sh thumbv7em-none-eabihf
#
# TARGET is one of rust-toolchain.toml's `targets` (scripts/targets.sh prints them); the
# machine each runs on is its runner in .cargo/config.toml. The runners use `-icount
# shift=6,sleep=off`: a 15.625 MHz core at one instruction per cycle whose sleeps end at the
# next timer in virtual time, so the paced lines' overruns follow the code's instruction count
# and nothing else: not the host's speed, not its load.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/targets.sh
targets=$(mcu_targets)
target=${1:-}
if [ -z "$target" ] || ! grep -qxF -- "$target" <<<"$targets"; then
  echo "usage: scripts/mcu.sh TARGET, TARGET one of: ${targets//$'\n'/ } (found: '${target}')" >&2
  exit 2
fi
scripts/setup.sh
exec timeout 600 cargo run -q --release -p selftest-app --target "$target"
