#!/bin/sh
# A copy of the shipped humanoid with the joints its sideways single-support recovery saturates
# given wider ranges, and the single-support base scenario pointed at it: the experiment behind
# "What single support sideways runs out of" (README.md here). Not a robot to use: the ranges are
# made up to see whether the joint limits are what ends the recovery.
#
#   deploy/envelope/widen_joints.sh OUT_DIR
#   build/bin/poise envelope pushes --supports single --single OUT_DIR/lateral_push_single_support.yaml
#
# Widened: hip roll and hip yaw (both legs) to +-1.0 rad, the shoulder roll's inward limit to 1.0
# rad (from 0.2), torso yaw to +-1.5 rad (from 0.8). Everything else is the shipped robot.
set -eu
if [ $# -ne 1 ] || [ "$1" = "-h" ] || [ "$1" = "--help" ]; then
  sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'
  [ $# -eq 1 ] && exit 0 || exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
src="$here/../robots/poise_humanoid"
out=$1
mkdir -p "$out/robot"
cp "$src/robot.yaml" "$src/poise_humanoid.urdf" "$out/robot/"
urdf="$out/robot/poise_humanoid.urdf"
# limit JOINT LOWER UPPER: the <limit> of that joint's element (the first one after its name).
limit() {
  grep -q "<joint name=\"$1\"" "$urdf" || { echo "widen_joints.sh: no joint $1 in $urdf" >&2; exit 1; }
  sed -i "/<joint name=\"$1\"/,/<limit/ s/lower=\"[^\"]*\" upper=\"[^\"]*\"/lower=\"$2\" upper=\"$3\"/" "$urdf"
}
limit l_hip_roll -1.0 1.0
limit r_hip_roll -1.0 1.0
limit l_hip_yaw -1.0 1.0
limit r_hip_yaw -1.0 1.0
limit l_shoulder_roll -1.0 2.5
limit r_shoulder_roll -2.5 1.0
limit torso_yaw -1.5 1.5
robot=$(cd "$out/robot" && pwd)/robot.yaml
sed "s#config: ../robots/poise_humanoid/robot.yaml#config: $robot#" \
  "$here/../scenarios/lateral_push_single_support.yaml" > "$out/lateral_push_single_support.yaml"
grep -q "config: $robot" "$out/lateral_push_single_support.yaml" ||
  { echo "widen_joints.sh: the scenario's robot line was not found" >&2; exit 1; }
echo "widened robot: $robot"
echo "scenario:      $out/lateral_push_single_support.yaml"
