#!/usr/bin/env bash
# The main job, run by `bash deploy/bootstrap.sh run` after the build.
# Today: the cross-vendor round trip of every topic type, in two separate processes (one on
# Cyclone DDS, one on Fast DDS), over the loopback-only configuration. It grows into the paper's
# push-recovery scenario as the controller lands.
set -euo pipefail
build=${1:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/build}
exec "$build/bin/poise" demo interop
