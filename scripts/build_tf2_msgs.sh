#!/usr/bin/env bash
# Usage: scripts/build_tf2_msgs.sh VENV
# tf2_msgs (for /tf, /tf_static) is not among the ROS 2 wheels: build its one message, TFMessage,
# from third_party/tf2_msgs with the rosidl generators of requirements.txt (ament_cmake,
# rosidl_default_generators) into the venv, which is laid out like a ROS install prefix. About
# 15 s, once; again only when third_party/tf2_msgs changes. Run by scripts/bootstrap.sh. A ROS
# install has the real package and never builds this one (third_party/COLCON_IGNORE).
# Fails with one line on stderr saying what is missing or what went wrong.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${1:?usage: scripts/build_tf2_msgs.sh VENV}"
SRC="$ROOT/third_party/tf2_msgs"
stamp() { cat "$SRC/CMakeLists.txt" "$SRC/package.xml" "$SRC"/msg/*.msg | sha256sum | cut -c1-16; }
if [ "$(cat "$VENV/.tf2_msgs_stamp" 2>/dev/null)" = "$(stamp)" ]; then
  exit 0
fi
for tool in cmake cc c++; do
  if ! command -v "$tool" >/dev/null; then
    echo "[bootstrap] error: building tf2_msgs (the /tf message type) needs cmake and a C/C++ compiler: '$tool' not found (Debian: apt-get install cmake g++)" >&2
    exit 1
  fi
done
echo "[bootstrap] building tf2_msgs/TFMessage into $VENV (third_party/tf2_msgs)" >&2
BUILD="$VENV/build/tf2_msgs"
rm -rf "$BUILD" && mkdir -p "$BUILD"
if ! { PATH="$VENV/bin:$PATH" AMENT_PREFIX_PATH="$VENV" cmake -S "$SRC" -B "$BUILD" \
         -DCMAKE_INSTALL_PREFIX="$VENV" -DCMAKE_PREFIX_PATH="$VENV" \
         -DPython3_EXECUTABLE="$VENV/bin/python" -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release \
       && PATH="$VENV/bin:$PATH" cmake --build "$BUILD" -j 2 \
       && cmake --install "$BUILD"; } > "$BUILD.log" 2>&1; then
  # CMake wraps its messages over lines: look in the log as one line for the missing package,
  # else quote the first error (a compiler's, cmake's).
  why="$(tr -s '\n ' '  ' < "$BUILD.log" | grep -m1 -oE 'provided by "[^"]+"' | head -n1 \
         | sed 's/provided by /package not found: /' || true)"
  [ -n "$why" ] || why="$(grep -m1 -E ' error: ' "$BUILD.log" || true)"
  # CMake's own message is on the lines after its 'CMake Error at <file>:<line>' header.
  [ -n "$why" ] || why="$(awk '/CMake Error/ {e = 1; next} e && NF {sub(/^ +/, ""); print; exit}' \
                            "$BUILD.log")"
  [ -n "$why" ] || why="$(tail -n1 "$BUILD.log")"
  echo "[bootstrap] error: building tf2_msgs failed: ${why:0:200} (whole log: $BUILD.log)" >&2
  exit 1
fi
stamp > "$VENV/.tf2_msgs_stamp"
