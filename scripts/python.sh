#!/usr/bin/env bash
# The Python package (python/, docs/PYTHON.md): installed into a fresh virtual environment
# with the one documented command, then its tests (pytest) against Gymnasium and the
# command-line tools. It builds with the workspace's `quick` profile into the workspace's
# target directory (or CARGO_TARGET_DIR), so after scripts/test.sh it compiles only the
# bindings. VENV chooses where the environment goes (default: under the target directory).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
target=${CARGO_TARGET_DIR:-$PWD/target}
venv=${VENV:-$target/python-venv}
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
"$venv/bin/pip" install --quiet pytest gymnasium numpy
CARGO_TARGET_DIR="$target" "$venv/bin/pip" install --quiet --force-reinstall --no-deps ./python
"$venv/bin/python" -m pytest -q python/tests
