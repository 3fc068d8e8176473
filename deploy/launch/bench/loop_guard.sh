#!/bin/bash
# loop_guard.sh: has a change slowed the loop? Times poise-bench-loop of this build and of a
# reference build beside it, alternating, and fails when either loop (in process, distributed) is
# 15 % or more slower than the reference's. Only ratios measured in one sitting are compared: this
# machine's absolute speed varies from day to day.
set -euo pipefail

usage() {
  cat <<'USAGE'
usage: loop_guard.sh (--ref COMMIT | --ref-build DIR) [--build DIR] [--rounds N]
                     [--threshold PCT] [--duration S] [--scenario FILE] [-- BENCH-ARGS...]

  --ref COMMIT      build COMMIT's benchmark (git worktree under $TMPDIR, build kept for reuse)
  --ref-build DIR   a reference build directory that has bin/poise-bench-loop
  --build DIR       the build under test (default: build/ of this checkout)
  --rounds N        alternating rounds, the median of each build is compared (default 5)
  --threshold PCT   a slowdown of PCT % or more fails (default 15)
  --duration S      simulated seconds per run (default 5)
  --scenario FILE   scenario of both builds' runs (default: the benchmark's own)
  -- BENCH-ARGS     extra arguments for this build's runs only (e.g. --add-work-us 100 to see
                    the guard fail)
Exit: 0 no loop slowed, 1 a loop slowed by the threshold or more, 2 usage or a failed run.
USAGE
}

here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../../.." && pwd)
ref="" ref_build="" build="$root/build" rounds=5 threshold=15 duration=5 scenario=""
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --ref) ref="$2"; shift 2 ;;
    --ref-build) ref_build="$2"; shift 2 ;;
    --build) build="$2"; shift 2 ;;
    --rounds) rounds="$2"; shift 2 ;;
    --threshold) threshold="$2"; shift 2 ;;
    --duration) duration="$2"; shift 2 ;;
    --scenario) scenario="$2"; shift 2 ;;
    --) shift; extra=("$@"); break ;;
    -h|--help) usage; exit 0 ;;
    *) echo "loop_guard.sh: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
if [ -z "$ref" ] && [ -z "$ref_build" ]; then
  echo "loop_guard.sh: give --ref COMMIT or --ref-build DIR" >&2; exit 2
fi
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "loop_guard.sh: --rounds must be a positive integer" >&2; exit 2; }
[[ "$threshold" =~ ^[0-9]+([.][0-9]+)?$ ]] || { echo "loop_guard.sh: --threshold must be a number" >&2; exit 2; }

if [ -n "$ref" ]; then
  sha=$(git -C "$root" rev-parse --verify "$ref^{commit}") ||
    { echo "loop_guard.sh: no commit '$ref'" >&2; exit 2; }
  tree="${TMPDIR:-/tmp}/poise-loop-guard-${sha:0:12}"
  if [ ! -d "$tree" ]; then
    echo "loop_guard.sh: reference ${sha:0:12}: worktree $tree"
    git -C "$root" worktree add --detach "$tree" "$sha" >/dev/null
  fi
  ref_build="$tree/build"
  echo "loop_guard.sh: building the reference's benchmark and nodes in $ref_build (once)"
  cmake -S "$tree" -B "$ref_build" -DCMAKE_BUILD_TYPE=Release >"$tree/configure.log" 2>&1 ||
    { echo "loop_guard.sh: configuring the reference failed: $tree/configure.log" >&2; exit 2; }
  cmake --build "$ref_build" -j"$(nproc)" --target poise-bench-loop >"$tree/build.log" 2>&1 ||
    { echo "loop_guard.sh: building the reference failed: $tree/build.log" >&2; exit 2; }
fi
for b in "$ref_build" "$build"; do
  [ -x "$b/bin/poise-bench-loop" ] ||
    { echo "loop_guard.sh: $b/bin/poise-bench-loop not found (build the target poise-bench-loop)" >&2; exit 2; }
done

out=$(mktemp -d "${TMPDIR:-/tmp}/poise-loop-guard.XXXXXX")
trap 'rm -rf "$out"' EXIT
# One run: "in-process-us distributed-us" on stdout.
run() {  # run NAME BUILD [EXTRA...]
  local name=$1 b=$2; shift 2
  local log="$out/$name.log"
  if ! timeout 600 "$b/bin/poise-bench-loop" ${scenario:+"$scenario"} --duration "$duration" "$@" >"$log" 2>&1; then
    echo "loop_guard.sh: $b/bin/poise-bench-loop failed:" >&2; tail -5 "$log" >&2; exit 2
  fi
  local inp dist
  inp=$(sed -n 's/^in-process loop *: .*(\([0-9.]*\) us per tick).*/\1/p' "$log")
  dist=$(sed -n 's/^distributed loop: .*(\([0-9.]*\) us per tick).*/\1/p' "$log")
  if [ -z "$inp" ] || [ -z "$dist" ]; then
    echo "loop_guard.sh: no loop figures in the output of $b/bin/poise-bench-loop:" >&2
    tail -5 "$log" >&2; exit 2
  fi
  echo "$inp $dist"
}

for ((i = 1; i <= rounds; i++)); do
  # Alternate which build goes first, so that a drift in the machine's speed hits both.
  if ((i % 2)); then
    r=$(run "ref$i" "$ref_build"); n=$(run "new$i" "$build" "${extra[@]}")
  else
    n=$(run "new$i" "$build" "${extra[@]}"); r=$(run "ref$i" "$ref_build")
  fi
  echo "$r" >>"$out/ref"; echo "$n" >>"$out/new"
  printf 'round %d/%d: us per tick, reference in-process %s distributed %s | this build %s %s\n' \
    "$i" "$rounds" $r $n
done

median() { sort -g | awk '{a[NR]=$1} END {if (NR % 2) print a[(NR+1)/2]; else print (a[NR/2]+a[NR/2+1])/2}'; }
status=0
printf '\n%-12s %14s %14s %8s  %s\n' loop "reference us" "this build us" ratio verdict
for col in 1 2; do
  name=$([ $col = 1 ] && echo in-process || echo distributed)
  mr=$(cut -d' ' -f$col "$out/ref" | median)
  mn=$(cut -d' ' -f$col "$out/new" | median)
  verdict=$(awk -v r="$mr" -v n="$mn" -v t="$threshold" \
    'BEGIN {q = n / r; printf "%.3f ", q; if (q >= 1 + t / 100) print "SLOWER by " int((q - 1) * 100 + 0.5) " % (limit " t " %)"; else print "ok"}')
  printf '%-12s %14.1f %14.1f %s\n' "$name" "$mr" "$mn" "$verdict"
  case "$verdict" in *SLOWER*) status=1 ;; esac
done
exit $status
