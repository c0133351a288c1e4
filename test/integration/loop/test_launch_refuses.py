"""hrc.launch and world.launch refuse a bad argument or model before anything starts: one line
naming it, roslaunch exits non-zero at once (a refused start once took ~35 s to shut down),
no master and no node were started (hrc_check runs as the launch's first parameter). These run
roslaunch itself, against a port no master listens on: one real launch for each way a word
reaches the pre-flight (a value, a value with a space and a quote, a path relative to where
roslaunch runs, the display in roslaunch's environment, world.launch's own check). Every line
the pre-flight can print is checked in-process: test/unit/loop/test_check.py and
test_settings.py."""
import os
import signal
import socket
import subprocess

import pytest

from ros_hrc.link.transport import free_port


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


def refused_in_one_line(done, master_up, prefix="hrc.launch: ", ros_home=None):
    """The refusal's line: the only line on stderr (roslaunch's own start lines are on stdout),
    no traceback, no RLException dumping the launch file, no process started, no master, and
    no link token left in ``ros_home`` (a refused launch makes none)."""
    assert done.returncode != 0, done.stdout + done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(prefix), done.stderr
    for text in (done.stdout, done.stderr):
        assert "Traceback" not in text and "RLException" not in text, text
    assert "process[" not in done.stdout, "a process was started"
    assert not master_up
    if ros_home is not None:
        links = ros_home / "ros_hrc" / "links"
        assert not links.exists() or list(links.iterdir()) == [], list(links.iterdir())
    return lines[0]


def test_a_bad_launch_argument_stops_the_launch_before_anything_starts(tmp_path):
    done, master_up = roslaunch("pomdp_port:=70000", ros_home=tmp_path / "ros_home")
    assert refused_in_one_line(done, master_up, ros_home=tmp_path / "ros_home") == \
        "hrc.launch: pomdp_port:=70000: must be an integer from 1 to 65535"


def test_a_value_with_a_space_and_a_quote_reaches_the_check_whole():
    """Before: it was split ("'with': expected name:=value")."""
    done, master_up = roslaunch("human_model:=it's here.pomdpx")
    assert refused_in_one_line(done, master_up).startswith(
        "hrc.launch: human_model:=it's here.pomdpx: no model file ")


def test_a_bad_world_launch_argument_stops_it_before_anything_starts():
    """Before: world.launch started its nodes and ended with exit status 0 once hrc_world
    refused the value."""
    done, master_up = roslaunch("seed:=-1", launch="world.launch")
    assert refused_in_one_line(done, master_up, "world.launch: ") == \
        "world.launch: seed:=-1: must be an integer from 0 to 2147483647"


def test_a_missing_relative_model_stops_the_launch_naming_it_as_typed(tmp_path):
    """Resolved in the directory roslaunch runs in: before, hrc_check took it there and the
    solver (which runs in $ROS_HOME) died on "no model file" and respawned forever."""
    done, master_up = roslaunch("human_model:=./tired.pomdpx", cwd=tmp_path)
    line = refused_in_one_line(done, master_up)
    assert line == (f"hrc.launch: human_model:=./tired.pomdpx: no model file "
                    f"./tired.pomdpx (looked for {tmp_path / 'tired.pomdpx'})")


def test_rviz_on_a_display_nobody_serves_stops_the_launch():
    """The display is roslaunch's environment's (before: RViz died and the stack ran on)."""
    number = next(n for n in range(190, 290) if not os.path.exists(f"/tmp/.X11-unix/X{n}"))
    environ = dict(os.environ, DISPLAY=f":{number}")
    done, master_up = roslaunch("rviz:=true", environ=environ)
    assert refused_in_one_line(done, master_up).startswith(
        f"hrc.launch: rviz:=true: needs a display, but no X server answers on "
        f"DISPLAY=:{number}")


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
