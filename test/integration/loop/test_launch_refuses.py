"""hrc.launch and world.launch refuse a bad argument or model before anything starts: one line
naming it, roslaunch exits non-zero at once (a refused start once took ~35 s to shut down),
no master and no node were started (hrc_check runs as the launch's first parameter). These run
roslaunch itself, against a port no master listens on."""
import os
import signal
import socket
import subprocess

import pytest

from ros_hrc.link.transport import free_port

CASES = [
    ("human_model:=does_not_exist", "hrc.launch: human_model:=does_not_exist"),
    ("pomdp_port:=70000", "hrc.launch: pomdp_port:=70000: must be an integer from 1 to 65535"),
    ("human_port:=abc", "hrc.launch: human_port:=abc"),
    ("planner:=bogus", "hrc.launch: planner:=bogus"),
    ("time_per_step:=-1", "hrc.launch: time_per_step:=-1"),
    ("scenarios:=0", "hrc.launch: scenarios:=0"),
    ("step_delay:=-1", "hrc.launch: step_delay:=-1"),
    ("belt_speed:=-5", "hrc.launch: belt_speed:=-5"),
    ("seed:=-1", "hrc.launch: seed:=-1: must be an integer from 0 to 2147483647"),
    ("real_time_factor:=-1",
     "hrc.launch: real_time_factor:=-1: must be 0 or a number from 0.001 to 1000"),
    ("temperature:=nan", "hrc.launch: temperature:=nan"),
    # Past int32 the parameter server cannot carry them: roslaunch ended in a traceback.
    (f"seed:={2**64}", f"hrc.launch: seed:={2**64}: must be an integer from 0 to 2147483647"),
    (f"seed:={2**31}", f"hrc.launch: seed:={2**31}: must be an integer from 0 to 2147483647"),
    (f"max_steps:={2**40}",
     f"hrc.launch: max_steps:={2**40}: must be an integer from 0 to 2147483647"),
    # A value with a space is one argument: it was split ("'with': expected name:=value").
    ("robot_model:=my models/r.pomdp", "hrc.launch: robot_model:=my models/r.pomdp: no model "
     "file "),
    ("human_model:=it's here.pomdpx", "hrc.launch: human_model:=it's here.pomdpx: no model "
     "file "),
]

WORLD_CASES = [
    ("seed:=-1", "world.launch: seed:=-1: must be an integer from 0 to 2147483647"),
    (f"seed:={2**31}", f"world.launch: seed:={2**31}: must be an integer from 0 to 2147483647"),
    ("real_time_factor:=-1",
     "world.launch: real_time_factor:=-1: must be 0 or a number from 0.001 to 1000"),
    ("camera_rate:=nan", "world.launch: camera_rate:=nan: must be a number from 0 to 30"),
    ("belt_speed:=fast", "world.launch: belt_speed:=fast"),
]


def roslaunch(*args, launch="hrc.launch", cwd=None, environ=None, ros_home=None):
    """(roslaunch's run, whether a master answered on its port afterwards)."""
    port = free_port()
    env = dict(os.environ if environ is None else environ,
               ROS_MASTER_URI=f"http://127.0.0.1:{port}")
    if ros_home is not None:
        env["ROS_HOME"] = str(ros_home)
    # A session of its own: a launch that starts after all (a refusal that regressed) is
    # stopped whole, its nodes with it, instead of leaving a stack on the machine's ports.
    launch_process = subprocess.Popen(["roslaunch", "-p", str(port), "ros_hrc", launch, *args],
                                      stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                      stderr=subprocess.PIPE, text=True, env=env, cwd=cwd,
                                      start_new_session=True)
    try:
        out, err = launch_process.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        os.killpg(launch_process.pid, signal.SIGKILL)
        out, err = launch_process.communicate()
        pytest.fail(f"roslaunch {' '.join(args)} started instead of refusing: {out[-2000:]}")
    done = subprocess.CompletedProcess(launch_process.args, launch_process.returncode, out, err)
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


def refused_in_one_line(done, master_up, prefix="hrc.launch: "):
    assert done.returncode != 0
    ours = [x for x in done.stderr.splitlines() if x.startswith(prefix)]
    assert len(ours) == 1, done.stderr
    assert "Traceback" not in done.stderr + done.stdout
    assert "process[" not in done.stdout, "a process was started"
    assert not master_up
    return ours[0]


def test_a_missing_relative_model_stops_the_launch_naming_it_as_typed(tmp_path):
    """Resolved in the directory roslaunch runs in: before, hrc_check took it there and the
    solver (which runs in $ROS_HOME) died on "no model file" and respawned forever."""
    done, master_up = roslaunch("human_model:=./tired.pomdpx", cwd=tmp_path)
    line = refused_in_one_line(done, master_up)
    assert line == (f"hrc.launch: human_model:=./tired.pomdpx: no model file "
                    f"./tired.pomdpx (looked for {tmp_path / 'tired.pomdpx'})")


def test_a_missing_relative_policy_file_stops_the_launch(tmp_path):
    done, master_up = roslaunch("planner:=policy", "policy_file:=robot.policy", cwd=tmp_path)
    line = refused_in_one_line(done, master_up)
    assert line == (f"hrc.launch: policy_file:=robot.policy: no readable file there "
                    f"(looked for {tmp_path / 'robot.policy'})")


def without_display():
    return {k: v for k, v in os.environ.items() if k != "DISPLAY"}


@pytest.mark.parametrize("word", ["rviz:=true", "gui:=true"])
def test_a_window_without_a_display_stops_the_launch(word):
    """Before: RViz died (or the world's window could not open) and the stack ran on."""
    done, master_up = roslaunch(word, environ=without_display())
    name = word.split(":=")[0]
    assert refused_in_one_line(done, master_up) == (
        f"hrc.launch: {name}:=true: needs a display, but DISPLAY is not set (run it on a "
        f"desktop or under Xvfb, or leave {name}:=false)")


def test_rviz_on_a_display_nobody_serves_stops_the_launch():
    number = next(n for n in range(190, 290) if not os.path.exists(f"/tmp/.X11-unix/X{n}"))
    environ = dict(os.environ, DISPLAY=f":{number}")
    done, master_up = roslaunch("rviz:=true", environ=environ)
    assert refused_in_one_line(done, master_up).startswith(
        f"hrc.launch: rviz:=true: needs a display, but no X server answers on "
        f"DISPLAY=:{number}")
    done, master_up = roslaunch("rviz:=true", launch="world.launch", environ=environ)
    assert refused_in_one_line(done, master_up, "world.launch: ").startswith(
        "world.launch: rviz:=true: needs a display")


@pytest.mark.parametrize("launch", ["hrc.launch", "world.launch", "experiment.launch"])
def test_ros_args_lists_every_argument_as_optional_with_its_doc(launch):
    """Before: every argument of hrc.launch was "Required" (an empty default) and the
    derived _mdp_prefix showed as "undocumented"."""
    done = subprocess.run(["roslaunch", "ros_hrc", launch, "--ros-args"], capture_output=True,
                          text=True, timeout=120, stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "Optional Arguments:" and "Required Arguments:" not in lines
    for line in lines[1:]:
        assert not line.strip().startswith("_"), line
        assert "undocumented" not in line, line


LAUNCHER = """
import signal, subprocess, sys, time
from ros_hrc.link.token import mint_token, write_session_settings
from ros_hrc import settings
got = []
signal.signal(signal.SIGINT, lambda *_: got.append(1))
config = settings.resolve({})
config["robot_model"] = sys.argv[1]          # checked, then gone before the solver starts
mint_token("hrc_link_gone", launcher_pid=__import__("os").getpid())
write_session_settings("hrc_link_gone", config)
code = subprocess.call([sys.executable, "-m", "ros_hrc.processes.despot_pomdp",
                        "--link-session=hrc_link_gone", "__name:=despot_pomdp"])
time.sleep(0.5)
print(code, bool(got))
"""


def test_a_solver_that_cannot_start_on_its_launch_s_settings_stops_the_launch(tmp_path):
    """Respawned, it would fail the same way about once a second and nothing would step:
    it asks its launcher (roslaunch, named in the session's token file) to stop, as Ctrl-C."""
    import sys
    env = dict(os.environ, ROS_HOME=str(tmp_path))
    done = subprocess.run([sys.executable, "-c", LAUNCHER, str(tmp_path / "gone.pomdp")],
                          capture_output=True, text=True, env=env, timeout=120)
    assert done.stdout.split() == ["2", "True"], done.stderr
    assert done.stderr.splitlines() == [
        f"despot_pomdp: no model file {tmp_path / 'gone.pomdp'} (looked for {tmp_path / 'gone.pomdp'})",
        "despot_pomdp: cannot start on this launch's settings: stopping the launch"]
