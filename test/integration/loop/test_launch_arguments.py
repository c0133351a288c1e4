"""What roslaunch says when it refuses to start: an argument the launch file does not declare
is refused (roslaunch alone ignores it in silence), and every refusal is the pre-flight's one
line and a non-zero exit status, without roslaunch's red RLException dumping the launch file,
with nothing started and no file left behind. These run the real roslaunch, with a ROS_HOME
of the test's own, against a master port nobody serves."""
import os
import subprocess
from pathlib import Path

import pytest

from ros_hrc.commands.launch_arguments import (check_launch_command_line, declared_arguments,
                                               split_command_line)
from test_launch_refuses import roslaunch as roslaunch_in

ROOT = Path(__file__).resolve().parents[3]


def roslaunch(tmp_path, *args, launch="hrc.launch", environ=None):
    """test_launch_refuses's roslaunch, run in ``tmp_path`` with a ROS_HOME of its own there
    (a refused session must leave no file in it)."""
    return roslaunch_in(*args, launch=launch, cwd=tmp_path, environ=environ,
                        ros_home=tmp_path / "ros_home")


def refusal_line(done, master_up, tmp_path):
    """The one line a refused launch printed besides roslaunch's own start lines (which are
    on stdout); checks that nothing started and nothing was left behind."""
    assert done.returncode != 0, done.stdout + done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    for text in (done.stdout, done.stderr):
        assert "RLException" not in text and "Param xml" not in text, text
        assert "Traceback" not in text, text
    assert "process[" not in done.stdout, "a process was started"
    assert not master_up
    links = tmp_path / "ros_home" / "ros_hrc" / "links"
    assert not links.exists() or list(links.iterdir()) == [], list(links.iterdir())
    return lines[0]


@pytest.mark.parametrize("launch, word, line", [
    ("hrc.launch", "human_modle:=tired",
     "hrc.launch: human_modle:=tired: no such argument (did you mean human_model?)"),
    ("world.launch", "sede:=3", "world.launch: sede:=3: no such argument (did you mean seed?)"),
    ("experiment.launch", "episode:=3",
     "experiment.launch: episode:=3: no such argument (did you mean episodes?)"),
])
def test_an_argument_the_launch_file_does_not_declare_stops_it(tmp_path, launch, word, line):
    """Before: roslaunch started the defaults and said nothing."""
    done, master_up = roslaunch(tmp_path, word, launch=launch)
    assert refusal_line(done, master_up, tmp_path) == line


def test_without_a_close_name_the_line_says_where_the_arguments_are_listed(tmp_path):
    # (tasks and selector were the words here until issue #30 made them arguments)
    done, master_up = roslaunch(tmp_path, "tsk:=5", "chooser:=bpr")
    assert refusal_line(done, master_up, tmp_path) == (
        "hrc.launch: tsk:=5: no such argument (did you mean task?); chooser:=bpr: no such "
        "argument (the arguments: rosrun ros_hrc hrc_check -h, or docs/settings.md)")


def without_display():
    return {k: v for k, v in os.environ.items() if k != "DISPLAY"}


@pytest.mark.parametrize("words, start", [
    (["seed:=-1"], "hrc.launch: seed:=-1: must be an integer from 0 to 2147483647"),
    (["human_model:=tierd"], "hrc.launch: human_model:=tierd: no human model named 'tierd'"),
    (["human_model:=./some/relative.pomdpx"],
     "hrc.launch: human_model:=./some/relative.pomdpx: no model file ./some/relative.pomdpx"),
    (["gui:=true"], "hrc.launch: gui:=true: needs a display, but DISPLAY is not set"),
    (["planner:=policy", "policy_file:=robot.policy"],
     "hrc.launch: policy_file:=robot.policy: no readable file there"),
])
def test_each_refusal_is_one_line_and_roslaunch_s_exit_status(tmp_path, words, start):
    """Before: the line, then ~2 KB of red RLException dumping the whole <param command=...>."""
    done, master_up = roslaunch(tmp_path, *words, environ=without_display())
    assert refusal_line(done, master_up, tmp_path).startswith(start)


def test_a_world_launch_refusal_is_one_line_too(tmp_path):
    done, master_up = roslaunch(tmp_path, "gui:=true", launch="world.launch",
                                environ=without_display())
    assert refusal_line(done, master_up, tmp_path).startswith(
        "world.launch: gui:=true: needs a display")


def test_the_declared_arguments_are_the_user_s_own():
    """Not the derived _-arguments (value=), not those an <include> passes on."""
    names = declared_arguments(ROOT / "launch" / "hrc.launch")
    assert "human_model" in names and "read_stdin" in names
    assert not [name for name in names if name.startswith("_")]
    assert "publish_rate" not in names          # world.launch's, not given to hrc.launch
    assert "publish_rate" in declared_arguments(ROOT / "launch" / "world.launch")


def test_roslaunch_s_own_options_and_remappings_are_not_launch_arguments():
    positional, words = split_command_line(
        ["-p", "11311", "--wait", "ros_hrc", "hrc.launch", "seed:=3", "__log:=/tmp/x",
         "--sigint-timeout", "5"])
    assert positional == ["ros_hrc", "hrc.launch"] and words == ["seed:=3"]
    assert check_launch_command_line(["roslaunch", "ros_hrc", "hrc.launch", "seed:=3",
                                      "__name:=x"], ROOT) is None


def test_a_launch_file_given_by_path_is_read_there(tmp_path):
    launch = tmp_path / "mine.launch"
    launch.write_text('<launch><arg name="speed" default="1"/>'
                      '<include file="x.launch"><arg name="inner" value="2"/></include></launch>')
    assert check_launch_command_line(["roslaunch", "mine.launch", "sped:=2"], tmp_path) == (
        "mine.launch", "sped:=2: no such argument (did you mean speed?)")
    assert check_launch_command_line(["roslaunch", "mine.launch", "inner:=2"], tmp_path)[1] \
        .startswith("inner:=2: no such argument")
    # another package's file: nothing known to compare with
    assert check_launch_command_line(["roslaunch", "other_pkg", "x.launch", "a:=1"],
                                     tmp_path) is None


def test_hrc_check_run_by_hand_takes_no_status_pipe_and_exits_2():
    """rosrun ros_hrc hrc_check on its own: the line and exit status 2, as before."""
    done = subprocess.run(["rosrun", "ros_hrc", "hrc_check", "seed:=-1", "--no-port-check"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert done.stderr.splitlines() == [
        "hrc.launch: seed:=-1: must be an integer from 0 to 2147483647"]
