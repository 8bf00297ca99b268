# shellcheck shell=bash
# Sourced by the scripts that need the microcontroller targets or the toolchain's name. Both
# are rust-toolchain.toml's (`targets = [...]`, `channel`), which rustup reads anyway, so
# each is written down once; the first target is the default one, the one the root memory.x
# maps.
#   . scripts/targets.sh; targets=$(mcu_targets); for t in $targets; do ...; done
# (Assigned first: under `set -e` a failing $(...) in a `for` list would go unnoticed.)

# The toolchain's channel (the pinned release); fails if the file names none.
rust_channel() {
  local toolchain channel
  toolchain="$(dirname "${BASH_SOURCE[0]}")/../rust-toolchain.toml"
  channel=$(sed -n 's/^channel *= *"\(.*\)"/\1/p' "$toolchain")
  if [ -z "$channel" ]; then
    echo "no channel = \"...\" in $toolchain" >&2
    return 1
  fi
  printf '%s\n' "$channel"
}

# The targets, one a line, in the file's order; fails if the list is missing or empty.
mcu_targets() {
  local toolchain list
  toolchain="$(dirname "${BASH_SOURCE[0]}")/../rust-toolchain.toml"
  # An empty list is reported below, not by grep's status (which `set -e` would act on).
  list=$(sed -n '/^targets *= *\[/,/\]/p' "$toolchain" | grep -o '"[^"]*"' | tr -d '"') || true
  if [ -z "$list" ]; then
    echo "no targets = [...] list in $toolchain" >&2
    return 1
  fi
  printf '%s\n' "$list"
}
