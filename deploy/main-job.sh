#!/usr/bin/env bash
# The main job, run by `bash deploy/bootstrap.sh run` after the build.
#
# Interim main job (until the distributed controller lands): a cross-vendor exchange over the
# loopback-only DDS configuration, in separate processes, with the user-facing tools:
#   1. `poise topic echo` on Fast DDS waits for a joint command;
#   2. `poise topic pub` on Cyclone DDS publishes one at 100 Hz;
#   3. `poise topic hz` on Fast DDS measures the Cyclone publisher's rate;
#   4. `poise topic list` on Cyclone shows what is on the domain.
# Every process is bounded in time and killed by its pid on exit.
set -euo pipefail
build=${1:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/build}
poise="$build/bin/poise"
export POISE_DDS_DOMAIN=${POISE_DDS_DOMAIN:-42}

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT

sample='{"header":{"tick":1,"stamp_ns":1000000},"mode":"COMMAND_TORQUE","joint_count":3,"tau_ff":[1.5,-2.0,0.25],"kp":[100,100,50],"kd":[2,2,1]}'

echo "== poise topic echo (Fast DDS) <- poise topic pub (Cyclone DDS), domain $POISE_DDS_DOMAIN"
timeout 30 "$poise" topic --dds fastdds echo poise/joint_command --once --timeout 20 &
echo_pid=$!
pids+=("$echo_pid")
timeout 60 "$poise" topic --dds cyclone pub poise/joint_command "$sample" --rate 100 --count 0 \
  --wait-readers 0 >/dev/null &
pids+=("$!")
wait "$echo_pid"

echo
echo "== poise topic hz (Fast DDS) of the Cyclone publisher, 3 s"
timeout 20 "$poise" topic --dds fastdds hz poise/joint_command --duration 3.2

echo
echo "== poise topic list (Cyclone DDS)"
timeout 20 "$poise" topic --dds cyclone list --wait 2
echo
echo "main job: cross-vendor exchange OK"
