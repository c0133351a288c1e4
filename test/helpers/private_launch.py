"""A launch of its own for a test that runs roslaunch itself: free ports for its master and both
links, its own ROS_HOME, and no display (the world headless whatever the test's terminal)."""
import os

from ros_hrc.link.transport import free_port


def private_launch(tmp_path):
    """((master, pomdp, human) ports, the environment to run roslaunch in)."""
    ports = set()
    while len(ports) < 3:
        ports.add(free_port())
    master, pomdp, human = sorted(ports)
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{master}",
               ROS_HOME=str(tmp_path / "ros_home"))
    env.pop("DISPLAY", None)
    return (master, pomdp, human), env
