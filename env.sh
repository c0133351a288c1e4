# Source this file (`source env.sh`) after `make setup` (or `make run` / `make test`):
# it puts the virtual environment and the built catkin workspace on this shell's path,
# so roslaunch, rosrun, rostopic, rosservice and the package's scripts work by hand.
_ros_hrc_root=$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")" && pwd)
if [ ! -f "$_ros_hrc_root/.ws/devel/setup.bash" ]; then
  echo "ros_hrc: no built workspace yet; run 'make setup' in $_ros_hrc_root first" >&2
else
  # setup.bash resets PYTHONPATH and PATH entries of its own; the venv goes first after it.
  . "$_ros_hrc_root/.ws/devel/setup.bash"
  export VIRTUAL_ENV="$_ros_hrc_root/.venv"
  export PATH="$VIRTUAL_ENV/bin:$PATH"
  export ROS_HRC_ROOT="$_ros_hrc_root"
  # ROS's own Python tools (roslaunch, rostest: rosclean imports distutils.spawn) get the
  # standard library's distutils, not setuptools' shim (Debian's distutils-precedence.pth),
  # which imports the whole of setuptools and pkg_resources first: 0.2 s of CPU at every
  # roslaunch start (docs/performance.md, "The CPU the suite spends"). The same
  # find_executable either way.
  export SETUPTOOLS_USE_DISTUTILS=stdlib
fi
unset _ros_hrc_root
