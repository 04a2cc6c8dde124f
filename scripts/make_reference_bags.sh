#!/usr/bin/env bash
# Makes the reference recordings kept in git (bags/README.md says how each was made):
#   bags/reference_default/  2 s of simulated time, every simulator topic (recorder + simulator)
#   bags/reference_camera/   3 s of simulated time at real_time_factor 0.5, every simulator topic
#                            plus the camera node's 60 fps images (texture off: ~8 KB per zstd
#                            compressed 1280x720 frame instead of ~520 KB with the textured wall)
# Existing reference bags are kept: delete one to make it again.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
source "$ROOT/scripts/bootstrap.sh"
cd "$ROOT"
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$((RANDOM % 100 + 1))}" ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_LOCALHOST_ONLY
SIM_TOPICS='[/clock,/saw/pose,/saw/twist,/saw/contacts,/saw/contact_wrench,/saw/joint_states]'
CAMERA_TOPICS="[${SIM_TOPICS:1:-1},/saw/camera/image_raw,/saw/camera/camera_info]"
LOGS="${LOGS:-$(mktemp -d)}"
PIDS=()
trap 'for p in "${PIDS[@]}"; do kill -INT "$p" 2>/dev/null || true; done' EXIT

wait_log() {  # wait_log <file> <text> <pid>: until the log says it (or the process died)
  until grep -q -- "$2" "$1"; do
    kill -0 "$3" 2>/dev/null || { cat "$1" >&2; return 1; }; sleep 0.1; done
}

cpu_ticks() { awk '{print $14 + $15}' "/proc/$1/stat" 2>/dev/null || echo gone; }

wait_idle() {  # wait_idle <pid>: until the process used no CPU for 0.5 s (its backlog is done)
  local before after
  before="$(cpu_ticks "$1")"
  while sleep 0.5; do
    after="$(cpu_ticks "$1")"
    [ "$after" = "$before" ] && return 0
    before="$after"
  done
}

# record <name> <topics> <camera: 0|1> [simulator params...]: record while the simulator runs
# (and, with camera 1, the camera node renders it), then finish the bag.
record() {
  local name="$1" topics="$2" camera="$3"; shift 3
  if [ -e "bags/$name" ]; then echo "bags/$name exists: kept" >&2; return 0; fi
  local cam=""
  if [ "$camera" = 1 ]; then
    # Texture off keeps the frames small in zstd; everything else is the camera's default.
    python -m saw_ros.ros.nodes.camera --ros-args -p texture:=false >"$LOGS/camera.log" 2>&1 &
    cam=$!; PIDS+=("$cam")
    wait_log "$LOGS/camera.log" 'camera 1280x720' "$cam"
  fi
  python -m saw_ros.ros.nodes.recorder --ros-args -p output:="bags/$name" -p "topics:=$topics" \
    >"$LOGS/rec_$name.log" 2>&1 &
  local rec=$!; PIDS+=("$rec")
  wait_log "$LOGS/rec_$name.log" 'recording to' "$rec"
  if [ -n "$cam" ]; then  # the camera's topics are subscribed before the first image exists
    wait_log "$LOGS/rec_$name.log" 'recording /saw/camera/image_raw' "$rec"
    wait_log "$LOGS/rec_$name.log" 'recording /saw/camera/camera_info' "$rec"
  fi
  # wait_for_subscribers 1: every simulator topic has the recorder before the first step.
  python -m saw_ros.ros.nodes.simulator --ros-args -p wait_for_subscribers:=1 "$@" \
    >"$LOGS/simulator_$name.log" 2>&1
  if [ -n "$cam" ]; then  # the last frames are rendered once the inputs reach their time
    wait_idle "$cam"
    kill -INT "$cam"; wait "$cam" || true
  fi
  kill -INT $rec; wait $rec || true
  tail -1 "$LOGS/rec_$name.log" >&2
  saw-ros bag info "bags/$name"
  check_order "bags/$name/${name}_0.mcap"
}

check_order() {  # check_order <file.mcap>: messages in log_time order, chunks apart in time
  python - "$1" <<'PY'
import sys
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
with open(sys.argv[1], 'rb') as f:
    times = [r.log_time for r in StreamReader(f, validate_crcs=True).records
             if isinstance(r, Message)]
    f.seek(0)
    chunks = sorted(make_reader(f).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
back = sum(b < a for a, b in zip(times, times[1:]))
overlaps = sum(b.message_start_time <= a.message_end_time for a, b in zip(chunks, chunks[1:]))
print(f'{sys.argv[1]}: {len(times)} messages, {back} steps back in log_time; '
      f'{len(chunks)} chunks, {overlaps} overlapping the next', file=sys.stderr)
sys.exit(1 if back or overlaps else 0)
PY
}

record reference_default "$SIM_TOPICS" 0 -p duration:=2.0
record reference_camera "$CAMERA_TOPICS" 1 -p duration:=3.0 -p real_time_factor:=0.5
