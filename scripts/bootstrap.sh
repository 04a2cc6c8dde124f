#!/usr/bin/env bash
# Creates (once) the virtual environment with the pinned ROS 2 Jazzy wheels and the package, laid
# out so that `ros2 run saw_ros <exe>` would find the executables; sourced, it then exports the
# environment. Sourced by scripts/main.sh and scripts/test.sh; safe to run again (it skips what
# is done).
#
# Sourced, it changes nothing in the caller's shell but PATH, AMENT_PREFIX_PATH and
# PYTHONUNBUFFERED: the work runs in a child bash with set -euo pipefail, which sourced would
# stay set in an interactive shell (the next failing command would close the terminal), and
# no variable or function of ours is left behind.
if [ "${BASH_SOURCE[0]}" != "$0" ]; then
  _saw_ros_bootstrap() {
    local venv
    venv="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/.venv" || return 1
    "${BASH:-bash}" "${BASH_SOURCE[0]}" || return 1
    export PATH="$venv/bin:$PATH"
    export AMENT_PREFIX_PATH="$venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
    export PYTHONUNBUFFERED=1
  }
  if _saw_ros_bootstrap; then
    unset -f _saw_ros_bootstrap
    return 0
  fi
  unset -f _saw_ros_bootstrap
  return 1
fi
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
PY="${PYTHON:-$(command -v python3.11 || command -v python3)}"

stamp_of() { cat "$ROOT/requirements.txt" "$ROOT/setup.py" "$ROOT/setup.cfg" | sha256sum | cut -c1-16; }
if [ ! -x "$VENV/bin/python" ]; then
  echo "[bootstrap] creating $VENV with $("$PY" --version)" >&2
  "$PY" -m venv "$VENV"
fi
if [ "$(cat "$VENV/.saw_ros_stamp" 2>/dev/null)" != "$(stamp_of)" ]; then
  echo "[bootstrap] installing pinned wheels (requirements.txt) and saw_ros" >&2
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check -r "$ROOT/requirements.txt"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check --no-deps -e "$ROOT"
  # pip ignores setup.cfg's script_dir: put the executables where `ros2 run` looks,
  # <prefix>/lib/saw_ros/<exe> (the venv is laid out like a ROS install prefix).
  mkdir -p "$VENV/lib/saw_ros" "$VENV/share/ament_index/resource_index/packages" "$VENV/share/saw_ros"
  for exe in simulator camera vision comparison recorder player video_source speed_controller \
      foxglove_bridge; do
    ln -sf "../../bin/$exe" "$VENV/lib/saw_ros/$exe"
  done
  # Editable installs skip data_files: the ament index marker and package.xml, by hand.
  cp "$ROOT/resource/saw_ros" "$VENV/share/ament_index/resource_index/packages/saw_ros"
  ln -sf "$ROOT/package.xml" "$VENV/share/saw_ros/package.xml"    # a link: never stale
  ln -sfn "$ROOT/msg_config" "$VENV/share/saw_ros/msg_config"
  # ...and setup.py's other data_files, the same layout as a colcon install.
  ln -sfn "$ROOT/urdf" "$VENV/share/saw_ros/urdf"
  mkdir -p "$VENV/share/saw_ros/viewers"
  ln -sf "$ROOT/docs/saw_ros.rviz" "$ROOT/docs/foxglove_layout.json" "$VENV/share/saw_ros/viewers/"
  stamp_of > "$VENV/.saw_ros_stamp"
fi

# The launch files as a folder of links, not a link to the folder: ros2launch looks for
# saw.launch.py by walking share/saw_ros, which does not enter links to folders ("file
# 'saw.launch.py' was not found in the share directory"). Outside the stamp's block: venvs made
# before this have the folder link.
[ ! -L "$VENV/share/saw_ros/launch" ] || rm "$VENV/share/saw_ros/launch"
mkdir -p "$VENV/share/saw_ros/launch"
ln -sf "$ROOT"/launch/*.launch.py "$VENV/share/saw_ros/launch/"

# tf2_msgs (for /tf, /tf_static) is not among the ROS wheels: built into the venv, once.
"$ROOT/scripts/build_tf2_msgs.sh" "$VENV"

# The physics core's kernels compiled into their disk cache once per version of them (the
# folder saw_ros/core/jit.py names after a digest of the kernel modules: the same modules as
# jit.kernel_sources picks, or the marker is never found and every run loads them again), so
# that the first simulate or simulator node loads them instead of compiling (docs/core.md).
KERNELS="$(for f in $(grep -lF -e 'numba.njit' -e '@compiled' "$ROOT"/saw_ros/core/*.py \
    | LC_ALL=C sort); do
  printf '%s' "$(basename "$f")"; cat "$f"; done | sha256sum | cut -c1-16)"
WARM="$ROOT/saw_ros/core/__pycache__/numba/kernels-$KERNELS/.warm"
if [ -z "${NUMBA_CACHE_DIR:-}" ] && [ ! -e "$WARM" ]; then
  echo "[bootstrap] compiling the physics core's kernels (once per change of them, ~1 min)" >&2
  "$VENV/bin/python" -c 'from saw_ros.core.dynamics import warm_up; warm_up()' \
    && { [ ! -d "$(dirname "$WARM")" ] || touch "$WARM"; }
fi
