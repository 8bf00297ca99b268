#!/usr/bin/env bash
# Fuzzes with libFuzzer the host tools' parsers (the checkpoint importer, with its
# restricted pickle reader and its ONNX reader on their own, the TOML configuration, the
# trajectory parser, the scenario parser), the rendering of untrusted text into exported
# source (names, comments) and the link's frame reader (what a target reads from its serial
# port), SECONDS each (default 60), as many at once as the machine has cores, seeded with
# the repository's own valid inputs. Prints each target's executions and coverage, and for
# the checkpoint readers the largest peak memory an input cost them (they abort past 4
# bytes per input byte plus 8 MiB: fuzz/fuzz_targets/bound.rs); exits 1 on a crash (the
# input is kept in fuzz/artifacts/TARGET/).
#
# The targets (`fuzz/`, a workspace of its own) build with the pinned stable toolchain:
# libfuzzer-sys brings libFuzzer, and the flags below are the coverage instrumentation
# cargo-fuzz would pass (it is not needed, nor nightly Rust). No AddressSanitizer, which
# needs nightly: the parsers are safe Rust, so the fuzzer finds the same panics, with debug
# assertions and overflow checks on.
#   scripts/fuzz.sh [SECONDS] [TARGET...]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(weights_import torch_pickle onnx_model config_toml replay_parse scenario_parse source_comment link_frame)
host=$(rustc -vV | sed -n 's/^host: //p')
corpus=fuzz/corpus
mkdir -p "$corpus"/{weights_import,torch_pickle,onnx_model,config_toml,replay_parse,scenario_parse,source_comment,link_frame}
fixtures=weights/tests/fixtures
cp "$fixtures"/*.safetensors "$fixtures"/*.pth "$fixtures"/*.zip "$fixtures"/*.cleanrl_model \
  shipped/policy.safetensors "$corpus/weights_import/"
cp "$fixtures"/*.onnx "$corpus/onnx_model/"
# The pickles inside PyTorch's zips (stored uncompressed, so a zip reader is not needed).
python3 - "$corpus/torch_pickle" "$fixtures"/*.pth <<'PY'
import os, sys, zipfile
for path in sys.argv[2:]:
    with zipfile.ZipFile(path) as z:
        name = next(n for n in z.namelist() if n.endswith("data.pkl"))
        with open(os.path.join(sys.argv[1], os.path.basename(path) + ".pkl"), "wb") as f:
            f.write(z.read(name))
PY
# Built with the workspace selected, as the test suite builds it: after the suite, nothing
# to compile (tests/tests/features.rs).
cargo build -q --profile quick --workspace --bin policy-export
"${CARGO_TARGET_DIR:-target}/quick/policy-export" train --preset robust --print-config \
  >"$corpus/config_toml/robust.toml"
head -n 3 tests/data/gym_traj_public.jsonl >"$corpus/replay_parse/three.jsonl"
n=0
for spec in nominal noise=2+delay push=0.5/40 length=0.8+polemass=1.2 force=0.8+cartmass=1.2; do
  n=$((n + 1))
  printf '%s' "$spec" >"$corpus/scenario_parse/seed-$n"
done
printf 'cartpole_policy\nsource: a */ b /* c ??/ \\' >"$corpus/source_comment/seed-1"
printf 'POLICY' >"$corpus/source_comment/seed-2"
# An exchange's requests as frames (Hello, Start, readings), then a reply of nine scores
# (which a target reads, then refuses as a kind), written by zlib's CRC-32 and a COBS encoder
# of their own, so the reader's fuzzing starts past the frame check.
python3 - "$corpus/link_frame/exchange" <<'PY'
import struct, sys, zlib
def cobs(data):
    out, block = bytearray(), bytearray()
    for byte in data:
        if byte:
            block.append(byte)
        if not byte or len(block) == 254:
            out += bytes([len(block) + 1]) + block
            block = bytearray()
    return bytes(out + bytes([len(block) + 1]) + block)
def frame(payload):
    return cobs(payload + struct.pack("<I", zlib.crc32(payload))) + b"\0"
with open(sys.argv[1], "wb") as f:
    f.write(frame(bytes([3, 1, 0, 0, 1])) + frame(bytes([3, 2, 1, 0, 1, 1, 2]) + bytes(4))
            + frame(bytes([3, 4, 2, 0]) + struct.pack("<ii", -120, 2047))
            + frame(bytes([3, 5, 3, 0]))
            + frame(bytes([3, 0x83, 4, 0]) + struct.pack("<hHIBB9i", 500, 0, 7, 1, 9,
                                                         *range(-4, 5))))
PY
log=$(mktemp)
logs=$(mktemp -d)
trap 'rm -rf "$log" "$logs"' EXIT
# The target triple keeps the instrumentation off build scripts and procedural macros.
coverage="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Cdebug-assertions -Coverflow-checks"
target_dir=${CARGO_TARGET_DIR:-fuzz/target}
if ! RUSTFLAGS="$coverage" CARGO_TARGET_DIR="$target_dir" cargo build -q --release --locked \
    --manifest-path fuzz/Cargo.toml --bins --target "$host" >"$log" 2>&1; then
  tail -n 20 "$log"
  echo "fuzz: the targets do not compile against the project's code"
  exit 1
fi
# One target per core at a time (each run is single-threaded), reported in the list's order.
lanes=$(nproc)
fuzz() { # TARGET: runs it, its libFuzzer output in $logs/TARGET, its status in $logs/TARGET.rc
  local t=$1 status=0
  mkdir -p "fuzz/artifacts/$t"
  "$target_dir/$host/release/$t" "$corpus/$t" -artifact_prefix="fuzz/artifacts/$t/" \
    -max_total_time="$seconds" -max_len=65536 -rss_limit_mb=2048 \
    -print_final_stats=1 >"$logs/$t" 2>&1 || status=$?
  echo "$status" >"$logs/$t.rc"
}
report() { # TARGET: what its run found; fails if it crashed
  local t=$1
  echo "== fuzz $t for ${seconds} s"
  if [ "$(cat "$logs/$t.rc")" != 0 ]; then
    tail -n 40 "$logs/$t"
    echo "fuzz $t: failed (a crashing input is kept in fuzz/artifacts/$t/)"
    exit 1
  fi
  grep -E 'DONE|^stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb)' "$logs/$t"
  # The readers' targets print their largest peak of live bytes as it grows (bound.rs).
  grep '^bound:' "$logs/$t" | tail -n 1 || true
}
for ((i = 0; i < ${#targets[@]}; i += lanes)); do
  batch=("${targets[@]:i:lanes}")
  for t in "${batch[@]}"; do fuzz "$t" & done
  wait
  for t in "${batch[@]}"; do report "$t"; done
done
