#!/usr/bin/env bash
# Installs the toolchain parts rust-toolchain.toml names (rustup does not install them on
# demand on machines with RUSTUP_AUTO_INSTALL=0) and, on Debian/Ubuntu, qemu-system-arm for
# the firmware tests. Every entry point runs this first.
set -euo pipefail
cd "$(dirname "$0")/.."
toolchain=$(sed -n 's/^channel *= *"\(.*\)"/\1/p' rust-toolchain.toml)
rustup toolchain install "$toolchain" --profile minimal >/dev/null
rustup component add --toolchain "$toolchain" clippy rustfmt llvm-tools >/dev/null
rustup target add --toolchain "$toolchain" thumbv7em-none-eabihf thumbv6m-none-eabi \
  thumbv8m.main-none-eabihf >/dev/null
if ! command -v qemu-system-arm >/dev/null && command -v apt-get >/dev/null; then
  sudo_=""
  [ "$(id -u)" -eq 0 ] || sudo_="sudo"
  echo "installing qemu-system-arm (apt-get)"
  $sudo_ apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq qemu-system-arm >/dev/null
fi
