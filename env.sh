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
fi
unset _ros_hrc_root
