"""hrc.launch and world.launch refuse a bad argument or model before anything starts: one line
naming it, roslaunch exits non-zero at once (a refused start once took ~35 s to shut down),
no master and no node were started (hrc_check runs as the launch's first parameter). These run
roslaunch itself, against a port no master listens on."""
import os
import socket
import subprocess

import pytest

from ros_hrc.link.transport import free_port

CASES = [
    ("human_model:=does_not_exist", "hrc.launch: human_model:=does_not_exist"),
    ("robot_port:=70000", "hrc.launch: robot_port:=70000: must be an integer from 1 to 65535"),
    ("human_port:=abc", "hrc.launch: human_port:=abc"),
    ("planner:=bogus", "hrc.launch: planner:=bogus"),
    ("time_per_step:=-1", "hrc.launch: time_per_step:=-1"),
    ("scenarios:=0", "hrc.launch: scenarios:=0"),
    ("step_delay:=-1", "hrc.launch: step_delay:=-1"),
    ("belt_speed:=-5", "hrc.launch: belt_speed:=-5"),
    ("seed:=-1", "hrc.launch: seed:=-1: must be an integer >= 0"),
    ("real_time_factor:=-1", "hrc.launch: real_time_factor:=-1: must be a number >= 0"),
    ("temperature:=nan", "hrc.launch: temperature:=nan"),
]

WORLD_CASES = [
    ("seed:=-1", "world.launch: seed:=-1: must be an integer >= 0"),
    ("real_time_factor:=-1", "world.launch: real_time_factor:=-1: must be a number >= 0"),
    ("camera_rate:=nan", "world.launch: camera_rate:=nan: must be a number from 0 to 30"),
    ("belt_speed:=fast", "world.launch: belt_speed:=fast"),
]


def roslaunch(*args, launch="hrc.launch"):
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}")
    done = subprocess.run(["roslaunch", "-p", str(port), "ros_hrc", launch, *args],
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, env=env,
                          timeout=120)
    with socket.socket() as s:
        master_up = s.connect_ex(("127.0.0.1", port)) == 0
    return done, master_up


@pytest.mark.parametrize("word, line", CASES)
def test_a_bad_launch_argument_stops_the_launch_before_anything_starts(word, line):
    done, master_up = roslaunch(word)
    assert done.returncode != 0
    ours = [x for x in done.stderr.splitlines() if x.startswith("hrc.launch: ")]
    assert len(ours) == 1, done.stderr
    assert ours[0].startswith(line), ours[0]
    assert "process[" not in done.stdout, "a process was started"
    assert not master_up


@pytest.mark.parametrize("word, line", WORLD_CASES)
def test_a_bad_world_launch_argument_stops_it_before_anything_starts(word, line):
    """Before: world.launch started its nodes and ended with exit status 0 once hrc_world
    refused the value."""
    done, master_up = roslaunch(word, launch="world.launch")
    assert done.returncode != 0
    ours = [x for x in done.stderr.splitlines() if x.startswith("world.launch: ")]
    assert len(ours) == 1 and ours[0].startswith(line), done.stderr
    assert "process[" not in done.stdout, "a process was started"
    assert not master_up


def test_a_robot_model_that_does_not_fit_the_task_stops_the_launch(tmp_path):
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(__file__))))
    bad = tmp_path / "o36.pomdp"
    with open(os.path.join(root, "models", "robot", "robot.pomdp")) as f:
        bad.write_text(f.read().replace("O35", "O36"))
    done, master_up = roslaunch(f"robot_model:={bad}")
    assert done.returncode != 0
    ours = [x for x in done.stderr.splitlines() if x.startswith("hrc.launch: ")]
    assert ours == [f"hrc.launch: {bad}: observations O36 are not the task's observations "
                    "(missing: O35)"], done.stderr
    assert not master_up
