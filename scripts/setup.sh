#!/usr/bin/env bash
# Installs the Debian 12 packages backlash_servo needs (only when something is missing), then configures and
# builds the package into ./build. Safe to run again. Usage: bash scripts/setup.sh [Release|RelWithDebInfo|Debug]
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH

PACKAGES=(
  build-essential cmake pkg-config
  ros-core-dev catkin libsensor-msgs-dev libstd-msgs-dev libstd-srvs-dev libdiagnostic-msgs-dev python3-diagnostic-msgs libdiagnostic-updater-dev libtrajectory-msgs-dev python3-trajectory-msgs librostest-dev python3-rostest
  python3-roslaunch python3-rostopic python3-rospy libros-rosgraph-msgs-dev
  libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure
  libeigen3-dev librosbag-dev python3-rosbag python3-sensor-msgs python3-std-msgs python3-std-srvs rosbash
  libyaml-cpp-dev googletest libgtest-dev python3-matplotlib python3-scipy python3-numpy libboost-dev
  slurm-wlm munge rviz ros-robot-state-publisher clang libclang-rt-14-dev catkin-lint
  liborocos-kdl-dev liburdfdom-dev libtinyxml2-dev
  pybind11-dev python3-pytest python3-nbclient python3-ipykernel jupyter-nbconvert
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

BUILD_TYPE=${1:-Release}
# catkin snapshots the environment at configure time and only puts the devel space's python path (generated
# messages, used by the rostest clients) into it if the directory already exists.
mkdir -p build/devel/lib/python3/dist-packages
cmake -S . -B build -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE="$BUILD_TYPE" >/dev/null
make -C build -j"$(nproc)" all
echo "setup: built into ./build — 'source build/devel/setup.bash' makes rosrun/roslaunch/rostest find the package"
