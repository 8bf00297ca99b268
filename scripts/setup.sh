#!/usr/bin/env bash
# Installs the toolchain parts rust-toolchain.toml names (rustup does not install them on
# demand on machines with RUSTUP_AUTO_INSTALL=0) and, on Debian/Ubuntu, qemu-system-arm and
# qemu-system-misc (RISC-V) for the firmware tests. Every entry point runs this first.
#   scripts/setup.sh              everything: the tests, CI, the microcontroller scripts
#   scripts/setup.sh --host       the toolchain alone in rustup's minimal profile (rustc,
#                                 cargo, the host's standard library): the main job, which
#                                 builds and runs the host tools and nothing else
#   scripts/setup.sh --toolchain  the toolchain with every part the tests use, no packages
#   scripts/setup.sh --system     the system's packages alone (CI installs them while it lints)
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/targets.sh
toolchain=1 parts=1 system=1
case ${1:-} in
  --host) parts=0 system=0 ;;
  --toolchain) system=0 ;;
  --system) toolchain=0 parts=0 ;;
  "") ;;
  *) echo "usage: scripts/setup.sh [--host | --toolchain | --system] (found: '$1')" >&2; exit 2 ;;
esac

# The addresses this machine's apt already fetches bookworm itself from, first choice first:
# deb822 `URIs:` of a stanza whose `Suites:` name `bookworm`, then one-line `deb` entries.
bookworm_uris() {
  local f
  for f in /etc/apt/sources.list.d/*.sources; do
    [ -r "$f" ] || continue
    awk 'BEGIN { RS = ""; FS = "\n" }
      {
        uris = ""; deb = 0; suite = 0; off = 0
        for (i = 1; i <= NF; i++) {
          if ($i ~ /^URIs:/) { uris = $i; sub(/^URIs:[ \t]*/, "", uris) }
          if ($i ~ /^Types:/ && ($i " ") ~ /[ \t]deb[ \t]/) deb = 1
          if ($i ~ /^Suites:/ && ($i " ") ~ /[ \t]bookworm[ \t]/) suite = 1
          if ($i ~ /^Enabled:[ \t]*no/) off = 1
        }
        if (uris != "" && deb && suite && !off) { split(uris, u, /[ \t]+/); print u[1] }
      }' "$f"
  done
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
    [ -r "$f" ] || continue
    # deb [OPTIONS] URI SUITE COMPONENT...
    awk '$1 == "deb" {
        i = 2
        if ($2 ~ /^\[/) { while (i < NF && $i !~ /\]$/) i++; i++ }
        if ($(i + 1) == "bookworm") print $i
      }' "$f"
  done
}

channel=$(rust_channel)
if [ "$toolchain" = 1 ]; then
  rustup toolchain install "$channel" --profile minimal >/dev/null
fi
if [ "$parts" = 1 ]; then
  rustup component add --toolchain "$channel" clippy rustfmt llvm-tools >/dev/null
  # shellcheck disable=SC2086 # one word per target
  rustup target add --toolchain "$channel" $(mcu_targets) >/dev/null
fi
[ "$system" = 1 ] || exit 0
missing=""
command -v qemu-system-arm >/dev/null || missing="$missing qemu-system-arm"
command -v qemu-system-riscv32 >/dev/null || missing="$missing qemu-system-misc"
# The C header test compiles the generated header as C and as C++.
command -v cc >/dev/null || missing="$missing gcc"
command -v c++ >/dev/null || missing="$missing g++"
# The C processor-in-the-loop application (scripts/c-app.sh) is built for the Cortex-M4F.
command -v arm-none-eabi-gcc >/dev/null || missing="$missing gcc-arm-none-eabi"
# The Python package's tests (scripts/python.sh) run in a virtual environment of their own.
python3 -c 'import ensurepip, venv' 2>/dev/null || missing="$missing python3-venv"
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
    # Backports from the mirror the machine already uses for bookworm.
    uri=$(bookworm_uris | sed -n 1p)
    if [ -z "$uri" ]; then
      echo "setup: no apt source for bookworm in /etc/apt/sources.list or" \
        "/etc/apt/sources.list.d/ to take the bookworm-backports address from;" \
        "add bookworm-backports to apt's sources and rerun" >&2
      exit 1
    fi
    echo "retrying from bookworm-backports at $uri"
    printf 'deb %s bookworm-backports main\n' "$uri" |
      $sudo_ tee /etc/apt/sources.list.d/bookworm-backports.list >/dev/null
    $sudo_ apt-get update -qq
    # shellcheck disable=SC2086 # one word per package
    DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq -t bookworm-backports $missing >/dev/null
  fi
fi
