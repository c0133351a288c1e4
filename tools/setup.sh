#!/usr/bin/env bash
# One-command set-up for ros_hrc on Debian 12 (run as root, or with sudo available):
#   1. Debian's ROS 1 Noetic packages (apt),
#   2. a virtual environment .venv made from /usr/bin/python3 with --system-site-packages,
#      holding the pinned PyPI packages of requirements.txt (Ray among them, for --cluster),
#   3. a catkin workspace .ws/ around the repository (.ws/src/ros_hrc holds a link to each
#      top-level entry of the repository), built with catkin_make and the environment's python.
# Idempotent: each step leaves a stamp holding what it was made from, and is skipped while
# that input is unchanged, so a second run does no network work and finishes in seconds.
set -euo pipefail

repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$repo"
stamps=.ws/stamps
mkdir -p "$stamps"

# ROS from Debian; python3-venv for the environment; xterm for the MDP's own terminal window
# (and the scalable font it draws with, hrc.launch);
# RViz and what it shows (descriptions, joint states, /tf, markers, images); Xvfb, xdotool and
# ImageMagick for the GUI's tests and screenshots under a virtual display.
APT_PACKAGES=(
  ros-core-dev catkin catkin-lint rosbash ros-message-generation ros-message-runtime
  ros-std-msgs ros-std-srvs ros-rosgraph-msgs
  rviz ros-robot-state-publisher python3-tf2-ros python3-geometry-msgs python3-sensor-msgs
  python3-visualization-msgs xvfb xdotool imagemagick
  python3-rospy python3-rostest python3-roslaunch python3-rosservice python3-rostopic
  python3-rosnode python3-rosmsg python3-rosbag python3-std-msgs python3-std-srvs python3-rosgraph-msgs
  python3-catkin-pkg python3-venv python3-dev python3-nose
  cmake g++ make xterm fonts-dejavu-core
)

say() { printf '[setup] %s\n' "$*"; }

stamp_ok() {  # stamp_ok NAME CONTENT: true when the stamp holds exactly CONTENT
  [[ -f "$stamps/$1" ]] && [[ "$(cat "$stamps/$1")" == "$2" ]]
}

# --- 1. apt -----------------------------------------------------------------
missing=()
while read -r pkg status; do
  [[ "$status" == "installed" ]] || missing+=("$pkg")
done < <(for p in "${APT_PACKAGES[@]}"; do
  printf '%s %s\n' "$p" "$(dpkg-query -W -f='${db:Status-Status}' "$p" 2>/dev/null || echo absent)"
done)
if ((${#missing[@]})); then
  say "installing Debian packages: ${missing[*]}"
  SUDO=""; [[ $(id -u) -ne 0 ]] && SUDO=sudo
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# --- 2. virtual environment -------------------------------------------------
req_key=$(sha256sum requirements.txt | cut -d' ' -f1)
if [[ ! -x .venv/bin/python ]]; then
  say "creating .venv from /usr/bin/python3 (with system site packages, for Debian's ROS)"
  /usr/bin/python3 -m venv --system-site-packages .venv
  rm -f "$stamps/pip"
fi
if ! stamp_ok pip "$req_key"; then
  say "installing pinned PyPI packages from requirements.txt"
  .venv/bin/python -m pip install --quiet --disable-pip-version-check -r requirements.txt
  echo "$req_key" > "$stamps/pip"
fi

# --- 3. catkin workspace ----------------------------------------------------
mkdir -p .ws/src
# The package directory links each entry of the repository but not the hidden ones: a link to
# the whole repository would put .ws inside its own package, and rosrun (find -L) would then
# list every executable many times over and ask which one to run.
pkg=.ws/src/ros_hrc
[[ -L $pkg ]] && rm "$pkg"   # the layout of earlier versions
mkdir -p "$pkg"
for entry in "$pkg"/*; do   # entries the repository no longer has
  [[ -L $entry && ! -e $entry ]] && rm "$entry"
done
for entry in *; do
  [[ -e $pkg/$entry ]] || ln -s "../../../$entry" "$pkg/$entry"
done
# media_export: RViz asks rospack for the plugins that export media to it, by this package's
# name (Debian's rviz lists it as a dependency but Debian ships no package of that name), and
# without it rospack printed "[rospack] Error: no such package media_export" at every RViz
# start. Upstream it is a package with nothing in it but its manifest; so is this one.
media=.ws/src/media_export
mkdir -p "$media"
cat > "$media/package.xml.new" <<'XML'
<?xml version="1.0"?>
<package format="2">
  <name>media_export</name>
  <version>0.3.0</version>
  <description>Where RViz finds the media (Ogre paths) other packages export: a package with
    nothing in it, made by ros_hrc's tools/setup.sh because Debian ships none.</description>
  <maintainer email="ros_hrc@example.org">ros_hrc</maintainer>
  <license>BSD</license>
  <buildtool_depend>catkin</buildtool_depend>
</package>
XML
cat > "$media/CMakeLists.txt.new" <<'CMAKE'
cmake_minimum_required(VERSION 3.0.2)
project(media_export)
find_package(catkin REQUIRED)
catkin_package()
CMAKE
for f in package.xml CMakeLists.txt; do   # rewritten only when changed: the build key reads them
  if cmp -s "$media/$f.new" "$media/$f"; then rm "$media/$f.new"; else mv "$media/$f.new" "$media/$f"; fi
done
# The build depends on the package's interface files, not on Python sources (those are
# used in place from src/ by the devel space).
build_key=$( (echo layout-2; cat "$media/package.xml"; cat package.xml CMakeLists.txt setup.py msg/*.msg srv/*.srv; ls scripts test/rostest) | sha256sum | cut -d' ' -f1)
if ! stamp_ok build "$build_key" || [[ ! -f .ws/devel/setup.bash ]]; then
  say "building the workspace with catkin_make"
  (cd .ws && catkin_make -DPYTHON_EXECUTABLE="$repo/.venv/bin/python" -DCATKIN_ENABLE_TESTING=ON \
      -DCMAKE_BUILD_TYPE=Release > build.log 2>&1) || { tail -40 .ws/build.log; exit 1; }
  echo "$build_key" > "$stamps/build"
fi
# The package's bytecode, written once here: this machine's environment (and CI's) sets
# PYTHONDONTWRITEBYTECODE, so without it every process of every stack compiled the modules it
# imports, each time (about 0.2 s of CPU a process, over a second a stack; docs/performance.md).
# By the source's hash, not its time: an edited file is never run from stale bytecode.
.venv/bin/python -m compileall -q --invalidation-mode checked-hash src \
  .ws/devel/lib/python3/dist-packages test > .ws/compileall.log 2>&1 \
  || { tail -20 .ws/compileall.log; exit 1; }
# The tests' bytecode as pytest runs them (their asserts rewritten, cached as
# *.cpython-*-pytest-*.pyc beside the plain ones), written here by one collection for the same
# reason: without it each pytest process (make test's two workers, each time) rewrote and
# compiled every test file, about 4.5 s of CPU (docs/performance.md). pytest checks each
# against its source's time and size, and rewrites an edited file in memory.
test_key=$( (echo pytest-bytecode-1; cat requirements.txt; find test -name '*.py' -print0 | sort -z \
  | xargs -0 sha256sum) | sha256sum | cut -d' ' -f1)
if ! stamp_ok test_bytecode "$test_key"; then
  (set +u; source env.sh; env -u PYTHONDONTWRITEBYTECODE OPENBLAS_NUM_THREADS=1 \
     python -m pytest -q -p no:cacheprovider --collect-only > .ws/test_bytecode.log 2>&1) \
    && echo "$test_key" > "$stamps/test_bytecode" \
    || say "pytest did not collect every test (.ws/test_bytecode.log): the test run will say why"
fi
say "wall time: setup $SECONDS s"
say "ready: source env.sh to use roslaunch, rosrun, rostopic and rosservice by hand"
