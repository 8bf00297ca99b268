# shellcheck shell=bash
# Sourced by the scripts that need the microcontroller targets. The list is
# rust-toolchain.toml's `targets = [...]`, which rustup reads anyway, so it is written down
# once; the first entry is the default target, the one the root memory.x maps.
#   . scripts/targets.sh; targets=$(mcu_targets); for t in $targets; do ...; done
# (Assigned first: under `set -e` a failing $(...) in a `for` list would go unnoticed.)

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
