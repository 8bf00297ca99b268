#!/usr/bin/env bash
# Regenerates what the code makes, in the order it depends on itself: the shipped policy
# (trained), its Rust, int8 and C exports, the runtime monitor's envelope, every results file
# of docs/results/ and docs/reproduction/, and the documents' tables, figures and results
# pages; then prints what changed (`git diff --stat`, and per results file the rows whose
# figures moved beyond their 95% intervals). The steps and their commands are
# docs/results/manifest.toml's, the one place they are written; this script only runs them.
#
#   scripts/regenerate.sh [--list] [--only GLOB]... [--from STEP] [--skip GLOB]...
#                         [--profile PROFILE] [--built]
#
#   --list         print the steps that would run (name, estimated CPU minutes, tools,
#                  command) and run nothing
#   --only GLOB    only the steps whose name matches (a shell glob; repeatable), e.g.
#                  --only eval-int, --only 'rig-*'
#   --from STEP    start at STEP, skipping the steps before it
#   --skip GLOB    leave out the matching steps (repeatable), e.g. --skip 'pil-*' where
#                  QEMU is missing, --skip 'sb3-*' without Stable-Baselines3; each skipped
#                  step is named in the plan
#   --profile P    build the tools with cargo profile P (default release; `quick` builds
#                  faster and computes the same bits)
#   --built        the tools of that profile are built already (a test run built them
#                  with the workspace's features): read the manifest with them without
#                  building first (a step that changes what they compile still rebuilds)
#
# A step that needs a tool beyond cargo (QEMU, arm-none-eabi-gcc, a Python with
# stable_baselines3 and cartpole_ddqn as $PYTHON, default python3) is refused before any
# work if the tool is missing, naming the --skip that leaves it out. Each step's output is
# complete or untouched: a printed output goes to a temporary file renamed into place, and
# the tools write their own files atomically. Progress lines give each step's time.
set -euo pipefail
cd "$(dirname "$0")/.."

die() { echo "regenerate: $*" >&2; exit 2; }
only=() skip=() from="" list=0 built=0 profile=release
while [ $# -gt 0 ]; do
  case $1 in
    --list) list=1; shift ;;
    --built) built=1; shift ;;
    --only|--skip|--from|--profile)
      [ $# -ge 2 ] && [ -n "$2" ] || die "$1 expects a value"
      case $1 in
        --only) only+=("$2") ;;
        --skip) skip+=("$2") ;;
        --from) from=$2 ;;
        --profile) profile=$2 ;;
      esac
      shift 2 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) die "unknown argument '${1:0:100}' (see --help)" ;;
  esac
done
[[ $profile =~ ^[a-z][a-z0-9_-]*$ ]] || die "--profile expects a cargo profile's name"

target_dir=${CARGO_TARGET_DIR:-$PWD/target}
PYTHON=${PYTHON:-python3}
# The commands' words for the tools: functions, so the manifest names no path.
host-sim() { "$target_dir/$profile/host-sim" "$@"; }
policy-export() { "$target_dir/$profile/policy-export" "$@"; }
python() { "$PYTHON" "$@"; }
build() { cargo build -q --profile "$profile" -p policy-export -p host-sim; }

clock() { printf '%dm%02ds' $(($1 / 60)) $(($1 % 60)); }
matches() { # NAME GLOB...: whether NAME matches one of the globs
  local name=$1 g
  shift
  for g in "$@"; do
    # shellcheck disable=SC2053 # the glob is meant to match as a pattern
    [[ $name == $g ]] && return 0
  done
  return 1
}
has() { # TOOL: whether a step's tool is here
  case $1 in
    qemu) command -v qemu-system-arm >/dev/null && command -v qemu-system-riscv32 >/dev/null ;;
    arm-gcc) command -v arm-none-eabi-gcc >/dev/null ;;
    sb3) "$PYTHON" -c 'import cartpole_ddqn, stable_baselines3' >/dev/null 2>&1 ;;
    *) return 1 ;;
  esac
}

# --list builds the tools only if they are not there (it needs host-sim to read the manifest).
if [ $built = 1 ]; then
  for tool in host-sim policy-export; do
    [ -x "$target_dir/$profile/$tool" ] || die "--built: expected $target_dir/$profile/$tool, found none"
  done
elif [ $list = 0 ] || [ ! -x "$target_dir/$profile/host-sim" ]; then
  echo "== build ($profile)"
  build
fi
steps=$(host-sim results steps)

# The plan: every step, selected or left out and why.
names=() plan=() reasons=()
started=0
[ -z "$from" ] && started=1
while IFS=$'\t' read -r name cost needs rebuild printed output prepare run about; do
  names+=("$name")
  [ "$name" = "$from" ] && started=1
  reason=""
  if [ $started = 0 ]; then reason="before --from $from"
  elif [ ${#only[@]} -gt 0 ] && ! matches "$name" "${only[@]}"; then reason="not --only"
  elif [ ${#skip[@]} -gt 0 ] && matches "$name" "${skip[@]}"; then reason="--skip"
  fi
  if [ -z "$reason" ]; then
    plan+=("$name"$'\t'"$cost"$'\t'"$needs"$'\t'"$rebuild"$'\t'"$printed"$'\t'"$output"$'\t'"$prepare"$'\t'"$run")
  else
    reasons+=("$name ($reason)")
  fi
done <<<"$steps"
if [ -n "$from" ] && [ $started = 0 ]; then die "--from: no step named '${from:0:100}'"; fi
for g in ${only[@]+"${only[@]}"} ${skip[@]+"${skip[@]}"}; do
  found=0
  for n in "${names[@]}"; do matches "$n" "$g" && found=1; done
  [ $found = 1 ] || die "no step matches '${g:0:100}' (--list shows them)"
done
[ ${#plan[@]} -gt 0 ] || die "no step is left to run"

total=0 missing=()
for p in "${plan[@]}"; do
  IFS=$'\t' read -r name cost needs _ <<<"$p"
  total=$(awk -v a="$total" -v b="$cost" 'BEGIN { print a + b }')
  [ "$needs" = - ] && continue
  for tool in ${needs//,/ }; do
    has "$tool" || missing+=("$name needs $tool")
  done
done

printf '%-40s %8s  %-12s %s\n' step "CPU min" needs command
for p in "${plan[@]}"; do
  IFS=$'\t' read -r name cost needs _ _ _ _ run <<<"$p"
  printf '%-40s %8s  %-12s %s\n' "$name" "$cost" "$needs" "$run"
done
unselected=0
for r in ${reasons[@]+"${reasons[@]}"}; do
  case $r in *"(--skip)") echo "left out: $r" ;; *) unselected=$((unselected + 1)) ;; esac
done
[ $unselected = 0 ] || echo "left out: $unselected steps not selected (--only, --from)"
echo "${#plan[@]} steps, about $total CPU minutes (docs/results/manifest.toml: costs)"
for m in ${missing[@]+"${missing[@]}"}; do echo "missing: $m"; done
[ $list = 1 ] && exit 0
if [ ${#missing[@]} -gt 0 ]; then
  die "install what is missing, or leave those steps out with --skip (e.g. --skip 'pil-*', --skip 'sb3-*')"
fi

# A step runs in the background, waited for, so that an interrupt stops it (its command's
# process, and that process's children) and removes its unfinished output.
part="" running=""
stop() {
  if [ -n "$running" ]; then
    pkill -TERM -P "$running" 2>/dev/null || true
    kill -TERM "$running" 2>/dev/null || true
  fi
  [ -z "$part" ] || rm -f "$part"
  echo "regenerate: interrupted; the step's output is left as it was" >&2
  exit 130
}
trap stop INT TERM
trap '[ -z "$part" ] || rm -f "$part"' EXIT
begin=$SECONDS i=0 written=() tables_ran=0
for p in "${plan[@]}"; do
  IFS=$'\t' read -r name cost needs rebuild printed output prepare run <<<"$p"
  i=$((i + 1)) t=$SECONDS
  echo "== [$i/${#plan[@]}] $name: $run"
  # A step's preparation prints to standard error: a printed output holds the command's alone.
  [ "$prepare" = - ] || eval "$prepare" >&2
  if [ "$printed" != - ]; then
    part="$(dirname "$printed")/.$(basename "$printed").part"
    eval "$run" >"$part" &
  else
    eval "$run" &
  fi
  running=$!
  wait "$running"
  running=""
  if [ -n "$part" ]; then
    mv -f "$part" "$printed"
    part=""
  fi
  [ "$rebuild" = 1 ] && build
  [ "$output" = - ] || written+=("$output")
  [ "$name" = tables ] && tables_ran=1
  echo "== [$i/${#plan[@]}] $name: $(clock $((SECONDS - t))) (all: $(clock $((SECONDS - begin))))"
done

echo "== what changed"
git diff --stat
for out in ${written[@]+"${written[@]}"}; do
  [ "$out" = docs/reproduction ] && out=docs/reproduction/results.json
  case $out in docs/results/*.json|docs/reproduction/results.json) ;; *) continue ;; esac
  if git cat-file -e "HEAD:$out" 2>/dev/null; then
    was=$(mktemp)
    git show "HEAD:$out" >"$was"
    host-sim results moved "$was" "$out" --name "$out"
    rm -f "$was"
  else
    echo "$out: new (no committed version)"
  fi
done | awk '!seen[$0]++'
if [ $tables_ran = 0 ] && [ ${#written[@]} -gt 0 ]; then
  echo "the documents were not rendered from these results: scripts/regenerate.sh --only tables"
fi
