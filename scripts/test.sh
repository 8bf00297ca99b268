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
e2e_log=$(mktemp)
jobs_running=()
# A script's background jobs ignore Ctrl-C: they are stopped here, with their children (the
# test binaries cargo runs), however the script ends.
cleanup() {
  for pid in "${jobs_running[@]}"; do
    pkill -TERM -P "$pid" 2>/dev/null || true
    kill "$pid" 2>/dev/null || true
  done
  rm -f "$deps" "$e2e_log"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
scripts/python.sh --deps >"$deps" 2>&1 &
python_deps=$!
jobs_running+=("$python_deps")
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
# follows the others'. Selected alone, it resolves its dependencies' features as the
# workspace does (tests/tests/features.rs), so it builds nothing the suite did not.
cargo test -p e2e --profile quick >"$e2e_log" 2>&1 &
e2e=$!
jobs_running+=("$e2e")
status=0
cargo test --workspace --exclude e2e --profile quick || status=$?
e2e_status=0
wait "$e2e" || e2e_status=$?
cat "$e2e_log"
if [ "$status" != 0 ] || [ "$e2e_status" != 0 ]; then
  echo "tests failed (the workspace's exit $status, the end-to-end crate's $e2e_status)" >&2
  exit 1
fi
status=0
wait "$python_deps" || status=$?
jobs_running=()
[ "$status" = 0 ] || { cat "$deps"; exit 1; }
scripts/python.sh
