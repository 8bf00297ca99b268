#!/usr/bin/env bash
# The test suite, from a fresh machine: set-up, then every crate's tests optimised (the
# end-to-end tests train a policy) but without link-time optimisation, which would be paid
# once per test binary (profile `quick`, Cargo.toml), then the Python package's tests in a
# fresh virtual environment (scripts/python.sh, built on the same artefacts, its
# dependencies downloaded while the workspace compiles).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
# The Python package's test dependencies download meanwhile.
deps=$(mktemp)
trap 'rm -f "$deps"' EXIT
scripts/python.sh --deps >"$deps" 2>&1 &
python_deps=$!
# The scripts' own Python modules (the instruction counter's Unicorn, Capstone and
# pyelftools) in an environment of their own, for tests/tests/scripts.rs, which fails
# without them.
venv=${CARGO_TARGET_DIR:-$PWD/target}/scripts-venv
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet -r scripts/requirements-dev.txt
export CARTPOLE_PYTHON="$venv/bin/python"
cargo test --workspace --profile quick --no-run
# The end-to-end crate's binaries run beside the other crates': most binaries hold a few
# long tests, which leave a core idle when the binaries run one after another. Its report
# follows the others'.
e2e_log=$(mktemp)
trap 'rm -f "$deps" "$e2e_log"' EXIT
cargo test -p e2e --profile quick >"$e2e_log" 2>&1 &
e2e=$!
status=0
cargo test --workspace --exclude e2e --profile quick || status=$?
e2e_status=0
wait "$e2e" || e2e_status=$?
cat "$e2e_log"
[ "$status" = 0 ] && [ "$e2e_status" = 0 ] || { echo "tests failed (workspace exit $status, e2e exit $e2e_status)"; exit 1; }
wait "$python_deps" || { cat "$deps"; exit 1; }
scripts/python.sh
