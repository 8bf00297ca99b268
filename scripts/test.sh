#!/usr/bin/env bash
# The test suite, from a fresh machine: set-up, then every crate's tests optimised (the
# end-to-end tests train a policy) but without link-time optimisation, which would be paid
# once per test binary (profile `quick`, Cargo.toml), then the Python package's tests in a
# fresh virtual environment (scripts/python.sh, built on the same artefacts).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cargo test --workspace --profile quick
scripts/python.sh
