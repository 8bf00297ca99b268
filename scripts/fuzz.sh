#!/usr/bin/env bash
# Fuzzes the host tools' four parsers with libFuzzer (cargo-fuzz, nightly Rust): the
# checkpoint importer, the TOML configuration, the trajectory parser and the scenario
# parser, SECONDS each (default 60), seeded with the repository's own valid inputs. Prints
# each target's executions and coverage; exits 1 on a crash (the input is kept in
# fuzz/artifacts/). Installs the nightly toolchain and cargo-fuzz if they are missing.
# FUZZ_SANITIZER=none builds without AddressSanitizer (much faster to build; the parsers are
# safe Rust, so it finds the same panics), as CI does.
#   scripts/fuzz.sh [SECONDS] [TARGET...]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(weights_import config_toml replay_parse scenario_parse)
rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null || cargo +nightly install cargo-fuzz --locked
corpus=fuzz/corpus
mkdir -p "$corpus"/{weights_import,config_toml,replay_parse,scenario_parse}
cp weights/tests/fixtures/*.safetensors firmware/policy.safetensors "$corpus/weights_import/"
cargo run -q --profile quick -p policy-export -- train --preset robust --print-config \
  >"$corpus/config_toml/robust.toml"
head -n 3 tests/data/gym_traj_public.jsonl >"$corpus/replay_parse/three.jsonl"
n=0
for spec in nominal noise=2+delay push=0.5/40 length=0.8+polemass=1.2 force=0.8+cartmass=1.2; do
  n=$((n + 1))
  printf '%s' "$spec" >"$corpus/scenario_parse/seed-$n"
done
log=$(mktemp)
trap 'rm -f "$log"' EXIT
# The harness must compile with the project's own toolchain: if it does not, our code broke it
# (a renamed module, say), which is a failure, not a nightly's quirk.
if ! cargo check -q --locked --manifest-path fuzz/Cargo.toml --bins >"$log" 2>&1; then
  tail -n 20 "$log"
  echo "fuzz: the targets do not compile against the project's code"
  exit 1
fi
if ! cargo +nightly fuzz build -s "${FUZZ_SANITIZER:-address}" >"$log" 2>&1; then
  tail -n 20 "$log"
  echo "fuzz: the targets do not build with this nightly toolchain ($(rustc +nightly --version))"
  exit 3
fi
for t in "${targets[@]}"; do
  echo "== fuzz $t for ${seconds} s"
  if ! cargo +nightly fuzz run -s "${FUZZ_SANITIZER:-address}" "$t" "$corpus/$t" -- \
      -max_total_time="$seconds" \
      -max_len=65536 -rss_limit_mb=2048 -print_final_stats=1 >"$log" 2>&1; then
    tail -n 40 "$log"
    echo "fuzz $t: failed (a crashing input is kept in fuzz/artifacts/$t/)"
    exit 1
  fi
  grep -E 'DONE|^stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb)' "$log"
done
