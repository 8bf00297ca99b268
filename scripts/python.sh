#!/usr/bin/env bash
# The Python package (python/, docs/PYTHON.md): installed into a fresh virtual environment
# with the one documented command, then its tests (pytest) against Gymnasium and the
# command-line tools. It builds with the workspace's `quick` profile into the workspace's
# target directory (or CARGO_TARGET_DIR), so after scripts/test.sh it compiles only the
# bindings. VENV chooses where the environment goes (default: under the target directory).
# `--deps` makes the environment and installs the tests' dependencies alone, after the
# caller's set-up: scripts/test.sh downloads them while the workspace compiles.
#   scripts/python.sh [--deps]
set -euo pipefail
cd "$(dirname "$0")/.."
case ${1:-} in
  --deps | "") ;;
  *) echo "usage: scripts/python.sh [--deps] (found: '$1')" >&2; exit 2 ;;
esac
[ "${1:-}" = --deps ] || scripts/setup.sh
target=${CARGO_TARGET_DIR:-$PWD/target}
venv=${VENV:-$target/python-venv}
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
"$venv/bin/pip" install --quiet pytest gymnasium numpy
[ "${1:-}" != --deps ] || exit 0
CARGO_TARGET_DIR="$target" "$venv/bin/pip" install --quiet --force-reinstall --no-deps ./python
"$venv/bin/python" -m pytest -q python/tests
