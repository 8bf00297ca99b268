#!/usr/bin/env bash
# The test suite, from a fresh machine: set-up, then every crate's tests in release mode
# (the end-to-end tests train a policy; release keeps them to seconds).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
cargo test --workspace --release
