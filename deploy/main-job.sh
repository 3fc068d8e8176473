#!/usr/bin/env bash
# The main job, run by `bash deploy/bootstrap.sh run` after the build: the paper's forward push
# (120 N for 0.1 s at the CoM, double support, Sec. 4.1) on the project's humanoid, with every
# component in its own process over loopback-only DDS, mixing the two vendors:
#   poise-sim, poise-estimator on Fast DDS; poise-contact, poise-controller on Cyclone DDS.
# The stack runs on the estimator's state (not ground truth), in lockstep. It prints progress, a
# one-line verdict, and writes results/forward_push_double_support.json. Every topic of the run is
# recorded to results/forward_push_double_support.mcap and drawn as the paper's Fig. 8/9 panels in
# results/plots/forward_push_double_support_balance.png (and .svg). Exit status 0 = survived.
set -euo pipefail
build=${1:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/build}
cd "$(dirname "$build")"
status=0
"$build/bin/poise" run forward_push_double_support \
  --dds-sim fastdds --dds-estimator fastdds --dds-contact cyclone --dds-controller cyclone \
  --record results/forward_push_double_support.mcap || status=$?
if [[ -f results/forward_push_double_support.mcap ]]; then
  "$build/bin/poise" plot results/forward_push_double_support.mcap -o results/plots || true
fi
exit "$status"
