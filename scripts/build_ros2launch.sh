#!/usr/bin/env bash
# Usage: scripts/build_ros2launch.sh SOURCES [VENV]
# `ros2 launch` in the pip set-up: ros2cli, launch, launch_ros and ros2launch are not published as
# wheels, so this installs them into VENV (default .venv) from their sources in SOURCES, one
# checkout of each repository's jazzy branch:
#   SOURCES/launch             github.com/ros2/launch              (launch, launch_xml, launch_yaml)
#   SOURCES/launch_ros         github.com/ros2/launch_ros          (launch_ros, ros2launch)
#   SOURCES/ros2cli            github.com/ros2/ros2cli             (ros2cli, ros2pkg)
#   SOURCES/rosidl_runtime_py  github.com/ros2/rosidl_runtime_py
# e.g.  for r in launch launch_ros ros2cli rosidl_runtime_py; do
#         git clone -b jazzy https://github.com/ros2/$r SOURCES/$r; done
# and builds composition_interfaces (launch_ros imports it; not among the wheels) from
# third_party/composition_interfaces as scripts/build_tf2_msgs.sh builds tf2_msgs (cmake, g++).
# The Python libraries they need and the wheels lack are pinned below. About a minute, once.
# Fails with one line on stderr saying what is missing or what went wrong.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
SOURCES="${1:?usage: scripts/build_ros2launch.sh SOURCES [VENV]}"
VENV="${2:-$ROOT/.venv}"
# What ros2cli, launch and launch_ros import that the ROS wheels do not bring (their package.xml
# exec_depends), and wheel (the sources build through setup.py bdist_wheel), at the versions
# this script was checked with.
PYTHON_DEPENDENCIES=(osrf-pycommon==2.0.2 argcomplete==3.7.2 psutil==7.2.2 wheel==0.45.1)
PACKAGES=(rosidl_runtime_py launch/launch launch/launch_xml launch/launch_yaml ros2cli/ros2cli
          ros2cli/ros2pkg launch_ros/launch_ros launch_ros/ros2launch)
fail() { echo "[ros2launch] error: $*" >&2; exit 1; }
[ -x "$VENV/bin/python" ] || fail "no Python venv at $VENV (run scripts/bootstrap.sh first)"
for package in "${PACKAGES[@]}"; do
  [ -f "$SOURCES/$package/setup.py" ] \
    || fail "$SOURCES/$package/setup.py not found: SOURCES must hold the jazzy checkouts of launch, launch_ros, ros2cli and rosidl_runtime_py (see this script's header)"
done
for tool in cmake cc c++; do
  command -v "$tool" >/dev/null \
    || fail "building composition_interfaces needs cmake and a C/C++ compiler: '$tool' not found (Debian: apt-get install cmake g++)"
done
LOG="$VENV/build/ros2launch.log"
mkdir -p "$VENV/build"
: > "$LOG"
echo "[ros2launch] building composition_interfaces into $VENV (third_party/composition_interfaces)" >&2
BUILD="$VENV/build/composition_interfaces"
rm -rf "$BUILD" && mkdir -p "$BUILD"
if ! { PATH="$VENV/bin:$PATH" AMENT_PREFIX_PATH="$VENV" cmake -S "$ROOT/third_party/composition_interfaces" \
         -B "$BUILD" -DCMAKE_INSTALL_PREFIX="$VENV" -DCMAKE_PREFIX_PATH="$VENV" \
         -DPython3_EXECUTABLE="$VENV/bin/python" -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release \
       && PATH="$VENV/bin:$PATH" cmake --build "$BUILD" -j 2 \
       && cmake --install "$BUILD"; } >> "$LOG" 2>&1; then
  fail "building composition_interfaces failed: $(grep -m1 -E ' error: |CMake Error' "$LOG" | cut -c1-200) (whole log: $LOG)"
fi
echo "[ros2launch] installing ${PACKAGES[*]} from $SOURCES into $VENV" >&2
if ! "$VENV/bin/python" -m pip install --no-input "${PYTHON_DEPENDENCIES[@]}" >> "$LOG" 2>&1; then
  fail "pip could not install ${PYTHON_DEPENDENCIES[*]}: $(tail -n1 "$LOG" | cut -c1-200) (whole log: $LOG)"
fi
# --no-deps: their setup.py files name ROS packages (rclpy, ament_index_python) that the wheels
# provide under other distribution names. The venv is a ROS install prefix, so each package's
# data_files (ament index marker, share/<pkg>/package.xml) land where ros2cli looks for them.
for package in "${PACKAGES[@]}"; do
  if ! "$VENV/bin/python" -m pip install --no-input --no-deps --no-build-isolation \
         "$SOURCES/$package" >> "$LOG" 2>&1; then
    fail "pip could not install $SOURCES/$package: $(tail -n1 "$LOG" | cut -c1-200) (whole log: $LOG)"
  fi
done
if ! out="$(PATH="$VENV/bin:$PATH" AMENT_PREFIX_PATH="$VENV" "$VENV/bin/ros2" launch --help 2>&1)"; then
  fail "ros2 launch does not start after the install: $(echo "$out" | tail -n1 | cut -c1-200)"
fi
echo "[ros2launch] ros2 launch installed: $VENV/bin/ros2" >&2
