#!/usr/bin/env bash
# Builds the self-test application for one microcontroller target and runs it in QEMU; the
# exit status is the self-test's verdict (0 PASS, 1 FAIL, 2 an unknown target).
#
#   scripts/mcu.sh thumbv6m-none-eabi          # Cortex-M0, micro:bit
#   scripts/mcu.sh thumbv7em-none-eabihf       # Cortex-M4F, mps2-an386
#   scripts/mcu.sh thumbv8m.main-none-eabihf   # Cortex-M33, mps2-an505
#   scripts/mcu.sh riscv32imac-unknown-none-elf  # RISC-V RV32IMAC, QEMU virt
#
# The runners (.cargo/config.toml) use `-icount shift=6`: a 15.625 MHz core at one
# instruction per cycle, so the paced lines' overruns follow the code's instruction count.
set -euo pipefail
cd "$(dirname "$0")/.."
targets="thumbv6m-none-eabi thumbv7em-none-eabihf thumbv8m.main-none-eabihf riscv32imac-unknown-none-elf"
target=${1:-}
if [ -z "$target" ] || ! grep -qw -- "$target" <<<"$targets"; then
  echo "usage: scripts/mcu.sh TARGET, TARGET one of: $targets (found: '${target}')" >&2
  exit 2
fi
scripts/setup.sh
exec timeout 600 cargo run -q --release -p selftest-app --target "$target"
