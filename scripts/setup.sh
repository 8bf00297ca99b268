#!/usr/bin/env bash
# Installs the toolchain parts rust-toolchain.toml names (rustup does not install them on
# demand on machines with RUSTUP_AUTO_INSTALL=0) and, on Debian/Ubuntu, qemu-system-arm and
# qemu-system-misc (RISC-V) for the firmware tests. Every entry point runs this first.
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/targets.sh
toolchain=$(sed -n 's/^channel *= *"\(.*\)"/\1/p' rust-toolchain.toml)
targets=$(mcu_targets)
rustup toolchain install "$toolchain" --profile minimal >/dev/null
rustup component add --toolchain "$toolchain" clippy rustfmt llvm-tools >/dev/null
# shellcheck disable=SC2086 # one word per target
rustup target add --toolchain "$toolchain" $targets >/dev/null
missing=""
command -v qemu-system-arm >/dev/null || missing="$missing qemu-system-arm"
command -v qemu-system-riscv32 >/dev/null || missing="$missing qemu-system-misc"
if [ -n "$missing" ] && command -v apt-get >/dev/null; then
  sudo_=""
  [ "$(id -u)" -eq 0 ] || sudo_="sudo"
  echo "installing$missing (apt-get)"
  $sudo_ apt-get update -qq
  # shellcheck disable=SC2086 # one word per package
  if ! DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq $missing >/dev/null; then
    # A bookworm machine whose qemu-utils came from backports refuses bookworm's older
    # qemu-system packages (qemu-utils breaks qemu-system-common < 8): take backports' too.
    . /etc/os-release
    [ "${VERSION_CODENAME:-}" = bookworm ] || exit 1
    echo "retrying from bookworm-backports"
    echo "deb http://deb.debian.org/debian bookworm-backports main" |
      $sudo_ tee /etc/apt/sources.list.d/bookworm-backports.list >/dev/null
    $sudo_ apt-get update -qq
    # shellcheck disable=SC2086 # one word per package
    DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq -t bookworm-backports $missing >/dev/null
  fi
fi
