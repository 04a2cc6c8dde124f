#!/usr/bin/env bash
# Makes the reference recordings kept in git (bags/README.md says how each was made):
#   bags/reference_default/  2 s of simulated time, every simulator topic (recorder + simulator)
#   bags/reference_camera/   the same with the camera node's images (skipped until it exists)
# Existing reference bags are kept: delete one to make it again.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/bootstrap.sh"
cd "$ROOT"
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$((RANDOM % 100 + 1))}" ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_LOCALHOST_ONLY
SIM_TOPICS='[/clock,/saw/pose,/saw/twist,/saw/contacts,/saw/contact_wrench,/saw/joint_states]'
LOGS="$(mktemp -d)"

record() {  # record <name> <topics> <node> [node params...]: record while the node runs
  local name="$1" topics="$2" node="$3"; shift 3
  if [ -e "bags/$name" ]; then echo "bags/$name exists: kept" >&2; return 0; fi
  python -m saw_ros.nodes.recorder --ros-args -p output:="bags/$name" -p "topics:=$topics" \
    >"$LOGS/rec_$name.log" 2>&1 &
  local rec=$!
  until grep -q 'recording to' "$LOGS/rec_$name.log"; do
    kill -0 $rec 2>/dev/null || { cat "$LOGS/rec_$name.log" >&2; return 1; }; sleep 0.1; done
  python -m saw_ros.nodes."$node" --ros-args "$@" >"$LOGS/$node.log" 2>&1
  kill -INT $rec; wait $rec || true
  tail -1 "$LOGS/rec_$name.log" >&2
  saw-ros bag info "bags/$name"
}

record reference_default "$SIM_TOPICS" simulator -p duration:=2.0 -p wait_for_subscribers:=1
if [ -f saw_ros/nodes/camera.py ]; then
  record reference_camera "[${SIM_TOPICS:1:-1},/saw/camera/image_raw,/saw/camera/camera_info]" \
    camera -p duration:=1.0 -p wait_for_subscribers:=1
else
  echo "saw_ros/nodes/camera.py does not exist yet: bags/reference_camera not made" >&2
fi
