#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine (run as root, or with sudo available):
#   bash deploy/bootstrap.sh run    install packages, build the tools and nodes, run the main job
#   bash deploy/bootstrap.sh test   install packages, build, run the whole test suite (ctest)
#   bash deploy/bootstrap.sh build  install packages and build only
# Environment: POISE_BUILD_DIR (default: build), POISE_JOBS (default: nproc),
#              POISE_SKIP_APT=1 to skip the package step on a machine that has them.
set -euo pipefail

mode=${1:-run}
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${POISE_BUILD_DIR:-$here/build}
jobs=${POISE_JOBS:-$(nproc)}

# Every Debian package the project needs: build tools, the five named dependencies and the
# well-kept libraries it uses (JSON, YAML, CLI parsing, tests, benchmarks, network namespaces,
# MCAP chunk compression, plots, GNU parallel for sharded studies) and Node.js, which runs the independent MCAP reader of the tests.
packages=(
  build-essential cmake pkg-config git python3 iproute2 procps
  libeigen3-dev liburdfdom-dev
  libfastrtps-dev libfastcdr-dev fastddsgen default-jre-headless
  cyclonedds-dev cyclonedds-tools iceoryx
  libbullet-dev libbullet-extras-dev
  nlohmann-json3-dev libyaml-cpp-dev libcli11-dev libyaml-dev libexpat1-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libzstd-dev liblz4-dev zlib1g-dev gnuplot-nox nodejs parallel
)

step() { printf '\n== %s\n' "$*"; }

if [[ "${POISE_SKIP_APT:-0}" != 1 ]]; then
  sudo=""
  [[ $(id -u) -eq 0 ]] || sudo=sudo
  step "Installing Debian packages (${#packages[@]})"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -q
  $sudo apt-get install -y -q --no-install-recommends "${packages[@]}"
  # Debian's nodejs comes without npm (package npm); other Node.js builds bundle it.
  command -v npm >/dev/null || $sudo apt-get install -y -q --no-install-recommends npm
fi

# `run` builds what it runs: the tools and nodes, not the test suites and benchmarks (half the
# build); `test` and `build` build everything. The choice is written into the build's cache each
# time, so one build directory serves both.
all=ON
[[ "$mode" == run ]] && all=OFF
# The test suite includes the in-process loop and the file loaders built a second time under
# AddressSanitizer + UndefinedBehaviorSanitizer (tests/sanitized/README.md), in their own
# directory; the main build runs those suites as its own tests.
sanitized=""
[[ "$mode" == test ]] && sanitized=${POISE_SANITIZED_BUILD_DIR:-$build-sanitized}
step "Configuring ($build, Release; tests and benchmarks: $all)"
cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=Release \
  -DPOISE_BUILD_TESTS="$all" -DPOISE_BUILD_BENCHMARKS="$all" \
  -DPOISE_SANITIZED_BUILD_DIR="$sanitized"
step "Building with $jobs jobs"
cmake --build "$build" -j "$jobs"
if [[ -n "$sanitized" ]]; then
  step "Building the sanitized suites ($sanitized: ASan + UBSan, -O1)"
  cmake -S "$here" -B "$sanitized" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE=-O1 \
    -DCMAKE_C_FLAGS_RELEASE=-O1 -DPOISE_SANITIZE=ON -DPOISE_BUILD_TESTS=ON \
    -DPOISE_BUILD_BENCHMARKS=OFF
  cmake --build "$sanitized" -j "$jobs" \
    --target poise_sanitized_loop_test poise_model_mutated_files_test
fi

case "$mode" in
  build) ;;
  test)
    step "Running the test suite"
    cd "$build"
    ctest --output-on-failure --timeout 600 -j "$jobs"
    ;;
  run)
    step "Running the main job"
    exec "$here/deploy/main-job.sh" "$build"
    ;;
  *)
    echo "usage: $0 run|test|build" >&2
    exit 2
    ;;
esac
