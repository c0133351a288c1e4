"""docs/extending.md as a researcher follows it: the example package (examples/my_robot, outside
src/ros_hrc) installed with pip into a folder put on PYTHONPATH (the project's environment
stays as it is: the entry points are read from the dist-info wherever it is on the path), then
its planner refused and accepted by hrc.launch's pre-flight, its robot policy run by
hrc_experiment --policies, and its selector choosing among its library's policies (its planner
by name and as module:Class) in hrc_experiment --sequence. Each study runs on one warm stack
(hrc.launch with planner:=my_planner, selector:=my_selector). The doc's code blocks are the
example's files, and the commands it shows are the ones run here."""
import csv
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

# One worker runs them all: the example is installed once (the module's fixture), and the two
# studies' stacks do not share the cores with each other.
pytestmark = pytest.mark.xdist_group("extending")

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "my_robot"
DOC = ROOT / "docs" / "extending.md"
LIBRARY = EXAMPLE / "library.toml"
POLICIES_STUDY = ["--policies", "my_robot,no_robot", "--human-models", "tired", "--seeds", "0",
                  "--episodes", "1", "--step-limit", "5", "--jobs", "1"]
SEQUENCE_STUDY = ["--sequence", "2", "--selectors", "my_selector", "--library",
                  "examples/my_robot/library.toml", "--human-models", "tired", "--seeds", "0",
                  "--episodes", "1", "--step-limit", "5", "--jobs", "1"]


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """The example installed as pip installs it (wheel built from its pyproject.toml, offline,
    with the environment's setuptools) into a fresh folder; the environment to run in."""
    where = tmp_path_factory.mktemp("my_robot")
    source = where / "source"      # pip builds in the source folder: a copy keeps ours clean
    shutil.copytree(EXAMPLE, source)
    target = where / "site"
    done = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
                           "--no-build-isolation", "--no-index", "--disable-pip-version-check",
                           "--target", str(target), str(source)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(target)] + [p for p in env.get(
        "PYTHONPATH", "").split(os.pathsep) if p])
    return env


def run(env, *args, timeout=120):
    return subprocess.run([sys.executable, *args], cwd=ROOT, env=env, stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=timeout)


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_the_doc_shows_the_example_files_and_the_commands_run_here():
    text = DOC.read_text()
    blocks = re.findall(r"<!-- example: (\S+) -->\n```\w*\n(.*?)```", text, re.S)
    shown = {name for name, _ in blocks}
    files = {str(p.relative_to(ROOT)) for p in EXAMPLE.rglob("*")
             if p.is_file() and "__pycache__" not in p.parts and p.name != "__init__.py"}
    assert shown == files
    for name, body in blocks:
        assert body == (ROOT / name).read_text(), name
    assert "hrc_experiment " + " ".join(POLICIES_STUDY) in text
    assert "hrc_experiment " + " ".join(SEQUENCE_STUDY) in text
    assert "roslaunch ros_hrc hrc.launch planner:=my_planner\n" in text


def test_the_launch_s_pre_flight_finds_the_planner_and_refuses_a_wrong_one(installed):
    check = ["-m", "ros_hrc.commands.check", "--no-port-check"]
    ok = run(installed, *check, "planner:=my_planner")
    assert ok.returncode == 0, ok.stderr
    assert "planner: my_planner" in ok.stdout
    ok = run(installed, *check, "planner:=my_planner", "planner_options:=explore=0.1")
    assert ok.returncode == 0, ok.stderr
    for word, says in (
            ("planner:=my_planer", "hrc.launch: planner:=my_planer: unknown planner "
                                   "'my_planer'; did you mean my_planner? (known: despot, "
                                   "policy, reactive, none, explore, my_planner, or "
                                   "module:Class)"),
            ("planner:=my_robot.planner:Greedy", "hrc.launch: planner:=my_robot.planner:Greedy: "
                                                 "module my_robot.planner has no Greedy"),
            ("planner:=my_robot.selector:WinStaySelector",
             "hrc.launch: planner:=my_robot.selector:WinStaySelector: WinStaySelector is not a "
             "subclass of ros_hrc.pomdp.planner.Planner"),
            ("planner_options:=explor=0.1", "hrc.launch: planner_options:=explor=0.1: unknown "
                                            "option 'explor' (its options: explore)")):
        refused = run(installed, *check, word, *([] if word.startswith("planner:=") else
                                                  ["planner:=my_planner"]))
        assert refused.returncode == 2
        assert refused.stderr.strip().startswith(says), refused.stderr
        assert says in DOC.read_text()


def test_my_robot_policy_in_a_study(installed, tmp_path):
    out = tmp_path / "study"
    done = run(installed, "-m", "ros_hrc.experiment.cli", *POLICIES_STUDY, "--out", str(out),
               "--no-plots", timeout=600)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    episodes = rows(out / "episodes.csv")
    assert sorted(e["robot_policy"] for e in episodes) == ["my_robot", "no_robot"]
    steps = [s for s in rows(out / "steps.csv") if s["robot_policy"] == "my_robot"]
    assert steps and all(s["robot_action"] for s in steps)


def test_my_selector_over_my_planner_in_a_sequence_study(installed, tmp_path):
    out = tmp_path / "sequences"
    done = run(installed, "-m", "ros_hrc.experiment.cli", *SEQUENCE_STUDY, "--out", str(out),
               "--no-plots", timeout=600)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    tasks = rows(out / "tasks.csv")
    assert [t["task_index"] for t in tasks] == ["1", "2"]
    assert {t["selector"] for t in tasks} == {"my_selector"}
    assert {t["policy"] for t in tasks} <= {"greedy", "greedy_explore", "reactive"}
    # Win-stay, lose-shift: the second task keeps a policy that won, else takes the next.
    names = ["greedy", "greedy_explore", "reactive"]
    first, second = tasks
    kept = float(first["utility"]) > 0
    expected = first["policy"] if kept else names[(names.index(first["policy"]) + 1) % 3]
    assert second["policy"] == expected
