#!/usr/bin/env bash
# Builds the ackermann_msgs interfaces (ros/ackermann_msgs) with the ROS 2 generators from PyPI and
# installs them into a virtual environment's prefix, where the ros-* wheels put theirs: the Python
# package in site-packages, the libraries in VENV/lib (which the wheels' start-up hook puts on the
# library path), the definitions and the type hashes in VENV/share/ackermann_msgs.
# Needs cmake and a C/C++ compiler. Usage: ros/build_msgs.sh VENV
set -euo pipefail
venv=$(cd "${1:?usage: $0 VENV}" && pwd)
here=$(cd "$(dirname "$0")" && pwd)
build="$venv/build/ackermann_msgs"
# A fresh build every time (about 30 s): a build folder configured from another checkout of the
# sources (a second clone or worktree sharing the venv) would be refused by cmake.
rm -rf "$build"
mkdir -p "$build"
# The generators find the type supports through the ament index of the prefix.
export AMENT_PREFIX_PATH="$venv"
export PATH="$venv/bin:$PATH"
cmake -S "$here/ackermann_msgs" -B "$build" -Wno-dev \
    -DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
    -DCMAKE_PREFIX_PATH="$venv" -DCMAKE_INSTALL_PREFIX="$venv" \
    -DPython3_EXECUTABLE="$venv/bin/python" >"$build.log" 2>&1 || { cat "$build.log"; exit 1; }
cmake --build "$build" -j 2 >>"$build.log" 2>&1 || { tail -50 "$build.log"; exit 1; }
cmake --install "$build" >>"$build.log" 2>&1 || { tail -50 "$build.log"; exit 1; }
