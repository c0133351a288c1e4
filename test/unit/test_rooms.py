"""The three ROS-free rooms import without rospy, and none of them imports it."""
import subprocess
import sys


def _imported_modules_after(statement: str) -> set:
    code = f"import sys; {statement}; print('\\n'.join(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return set(out.stdout.split())


def test_pomdp_world_and_link_import_without_ros():
    # The experiments' scoring, results and stack driver too: rospy comes in only inside a
    # worker, once it knows its own master.
    for room in ("ros_hrc.pomdp", "ros_hrc.world", "ros_hrc.link", "ros_hrc.errors",
                 "ros_hrc.robot_policies", "ros_hrc.experiment.results",
                 "ros_hrc.experiment.episode", "ros_hrc.experiment.stack"):
        modules = _imported_modules_after(f"import {room}")
        assert room in modules
        assert not {"rospy", "rosgraph", "roslib"} & modules, f"{room} pulls in ROS"


def test_only_the_world_imports_pybullet():
    for room in ("ros_hrc.pomdp", "ros_hrc.link"):
        assert "pybullet" not in _imported_modules_after(f"import {room}")
