"""An argument the launch file does not declare is refused (roslaunch alone ignores it in
silence): through the real roslaunch, each launch file, with a ROS_HOME of the test's own,
against a master port nobody serves; the refusal is the pre-flight's one line and a non-zero
exit status, nothing started, no file left behind (test_launch_refuses.refused_in_one_line).
How the words are read is checked in-process."""
import subprocess
from pathlib import Path

import pytest

from ros_hrc.commands.launch_arguments import (check_launch_command_line, declared_arguments,
                                               split_command_line)
from test_launch_refuses import refused_in_one_line, roslaunch as roslaunch_in

ROOT = Path(__file__).resolve().parents[3]


def roslaunch(tmp_path, *args, launch="hrc.launch", environ=None):
    """test_launch_refuses's roslaunch, run in ``tmp_path`` with a ROS_HOME of its own there
    (a refused session must leave no file in it)."""
    return roslaunch_in(*args, launch=launch, cwd=tmp_path, environ=environ,
                        ros_home=tmp_path / "ros_home")


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
    assert refused_in_one_line(done, master_up, f"{launch}: ", tmp_path / "ros_home") == line


def test_without_a_close_name_the_line_says_where_the_arguments_are_listed():
    # (tasks and selector were the words here until issue #30 made them arguments)
    assert check_launch_command_line(["roslaunch", "ros_hrc", "hrc.launch", "tsk:=5",
                                      "chooser:=bpr"], ROOT) == (
        "hrc.launch", "tsk:=5: no such argument (did you mean task?); chooser:=bpr: no such "
        "argument (the arguments: rosrun ros_hrc hrc_check -h, or docs/settings.md)")


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
