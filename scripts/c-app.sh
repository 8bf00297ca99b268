#!/usr/bin/env bash
# Builds the C processor-in-the-loop application (capi/c-app): libcartpole_policy.a for the
# Cortex-M4F, the shipped policy exported as C headers (f32 and int8, with its rig), and the
# application compiled and linked with Debian's arm-none-eabi-gcc (apt-get install
# gcc-arm-none-eabi) for QEMU's mps2-an386. Prints the ELF's path.
#   scripts/c-app.sh [OUT_DIR]      (default: target/c-app)
# PROFILE=quick builds the Rust parts with the test suite's profile instead of release.
# Then: cargo run --release -p host-sim -- eval --pil qemu:thumbv7em-none-eabihf \
#         --pil-elf target/c-app/c-pil.elf
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/c-app}
command -v arm-none-eabi-gcc >/dev/null || {
  echo "c-app: arm-none-eabi-gcc not found (apt-get install gcc-arm-none-eabi)" >&2
  exit 2
}
target=thumbv7em-none-eabihf
target_dir=${CARGO_TARGET_DIR:-target}
profile=${PROFILE:-release}
mkdir -p "$out"
cargo build -q --profile "$profile" -p capi --target "$target"
cargo build -q --profile "$profile" -p policy-export
export_c() {
  "$target_dir/$profile/policy-export" export shipped/policy.safetensors --format c "$@" \
    2>"$out/export.log" || { cat "$out/export.log" >&2; exit 1; }
}
export_c --name shipped --out "$out/shipped.h"
export_c --quant int8 --name shipped_int --out "$out/shipped_int.h"
arm-none-eabi-gcc -std=c99 -Wall -Wextra -Werror -pedantic -O2 -ffreestanding -nostdlib \
  -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16 \
  -Icapi/include -I"$out" -Tcapi/c-app/link.ld -Wl,--gc-sections,-z,noexecstack \
  capi/c-app/startup.c capi/c-app/pil.c "$target_dir/$target/$profile/libcartpole_policy.a" -lgcc \
  -o "$out/c-pil.elf"
echo "$out/c-pil.elf"
