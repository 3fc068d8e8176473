#!/bin/bash
# Before/after timing of the sequential method in one process: the contact library of git revision
# REV (default 7cca123, before the normal-equation stages and the shared NNLS/BVLS code) and that
# of the working tree, compiled side by side (namespaces renamed) and timed interleaved, problem by
# problem, on the double-support problems of the benchmark corpus.
#   compare_revisions.sh [REV] [RECORDED_CORPUS] [PASSES]
# RECORDED_CORPUS: a poise-contact-record file (converted for old readers). Set DENSE=1 to time the
# working tree with its dense stages (SequentialOptimizer::set_use_normal_equations(false)).
# Compiles with at most 2 jobs; needs g++, Eigen, git.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(git -C "$here" rev-parse --show-toplevel)
rev=${1:-7cca123}
recorded=${2:-}
passes=${3:-2}
work=$(mktemp -d /tmp/poise-contact-compare.XXXXXX)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/old" "$work/A" "$work/B"
git -C "$repo" archive "$rev" controller/contact | tar -x -C "$work/old"
if [ -n "$recorded" ]; then  # old readers know kinds 0-3 and no comment lines
  { echo "# poise contact corpus v1"; grep -v '^#' "$recorded" | sed -E 's/^4 /0 /; s/^5 /1 /'; } \
    > "$work/recorded.txt"
  recorded="$work/recorded.txt"
fi
build_side() {  # TAG SOURCE_DIR EXTRA_FLAGS
  local tag=$1 src=$2 extra=$3
  local f files=()
  for f in "$src"/bench/contact_corpus.cpp "$src"/src/{nnls,bvls,contact_problem}.cpp \
           "$src"/src/{sequential_optimizer,least_squares_workspace}.cpp "$here/runner.cpp"; do
    if [ -f "$f" ]; then files+=("$f"); fi
  done
  printf '%s\n' "${files[@]}" |
    xargs -P2 -I{} sh -c "g++ -O3 -DNDEBUG -std=c++20 -Dpoise=poise_$tag -DTAG=$tag $extra \
      -I$src/bench -I$src/include -isystem /usr/include/eigen3 -c {} -o $work/$tag/\$(basename {} .cpp).o"
}
build_side A "$work/old/controller/contact" ""
build_side B "$repo/controller/contact" "-DPOISE_COMPARE_DENSE_SWITCH"
g++ -O2 -std=c++20 "$here/driver.cpp" "$work"/A/*.o "$work"/B/*.o -o "$work/compare"
echo "old = $rev, new = working tree; load average: $(cut -d' ' -f1-3 /proc/loadavg)"
"$work/compare" "$recorded" "$passes" "${DENSE:-0}"
