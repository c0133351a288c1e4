"""The README's "What you see" says which processes `make run` starts: its count and its table
agree with the nodes roslaunch itself finds in hrc.launch (``roslaunch --nodes``, which loads
the launch file as a run does, pre-flight included, and starts nothing), with the default
``viz:=true`` and with ``viz:=false``."""
import os
import re
import subprocess
from pathlib import Path

README = Path(__file__).resolve().parents[3] / "README.md"
NUMBERS = {"one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7,
           "eight": 8, "nine": 9, "ten": 10}


def launch_nodes(tmp_path, *words):
    env = dict(os.environ, ROS_HOME=str(tmp_path / "ros_home"))
    listed = subprocess.run(["roslaunch", "--nodes", "ros_hrc", "hrc.launch", *words],
                            capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert listed.returncode == 0, listed.stderr
    return [line.strip().lstrip("/") for line in listed.stdout.splitlines()
            if line.startswith("/")]


def readme_processes():
    """(the count in words, how many the viz:=false sentence says, the table's rows)."""
    text = README.read_text()
    said = re.search(r"`make run` \(= `roslaunch ros_hrc hrc.launch`\) starts roscore and "
                     r"(\w+) processes \((\w+) with\s+`viz:=false`", text)
    assert said, "the README no longer says how many processes make run starts"
    table = text[said.end():].split("\n\n", 2)[1]
    rows = [re.match(r"\| `([^`]+)` \|", line) for line in table.splitlines()[2:]]
    assert all(rows), table
    return NUMBERS[said.group(1)], NUMBERS[said.group(2)], [row.group(1) for row in rows]


def test_the_readme_names_every_process_make_run_starts(tmp_path):
    count, without_viz, names = readme_processes()
    started = launch_nodes(tmp_path)
    assert count == len(started) == len(names)
    assert sorted(names) == sorted(started)
    alone = launch_nodes(tmp_path, "viz:=false")
    assert without_viz == len(alone)
    assert names[:without_viz] == [n for n in names if n in alone]   # "the last three" go
