"""hrc_experiment before the stacks, in-process: the whole grid is checked before any stack
starts (a stand-in ``roslaunch`` on PATH records any start, so a refusal is seen to start
none), the cells' plan, ports and settings, and --out locked for the run. Around the stacks
(a second process, signals, stacks that die): test/integration/experiment/test_grid_stacks.py."""
import json
import os
import sys
from pathlib import Path

import pytest

from ros_hrc.experiment.arguments import names_argument
from ros_hrc.experiment.cli import budgets_argument, build_parser, main, validate_grid
from ros_hrc.experiment.grid import plan_cells
from ros_hrc.experiment import stack
from ros_hrc.experiment.stack import (CellSpec, EpisodeRanges, cell_name, check_launch_settings,
                                      launch_arguments, read_spec, worker_command, write_spec)
from ros_hrc.experiment.lock import DirectoryLocked, lock_directory
from experiment_runs import fake_ros  # noqa: F401  (a fixture)
from in_process import run_main
from ros_hrc.settings import SettingError

ROOT = Path(__file__).resolve().parents[3]

def o36_robot_model(tmp_path) -> Path:
    bad = tmp_path / "o36.pomdp"
    bad.write_text((ROOT / "models" / "robot" / "robot.pomdp").read_text().replace("O35", "O36"))
    return bad


def refused_in_process(monkeypatch, fake_ros, *args) -> str:
    """hrc_experiment's ``main`` on ``args`` in this process, with the recording roslaunch
    first on PATH: its one line (exit status 2)."""
    env, _ = fake_ros
    monkeypatch.setenv("PATH", env["PATH"])
    monkeypatch.setenv("FAKE_ROSLAUNCH_LOG", env["FAKE_ROSLAUNCH_LOG"])
    status, _, err = run_main(main, args)
    lines = err.splitlines()
    assert status == 2 and len(lines) == 1 and lines[0].startswith("hrc_experiment: "), err
    return lines[0]


def test_a_robot_model_with_other_observation_names_is_refused_before_any_stack(
        tmp_path, fake_ros, monkeypatch):
    _, log = fake_ros
    bad = o36_robot_model(tmp_path)
    out = tmp_path / "out"
    line = refused_in_process(monkeypatch, fake_ros, "--robot-model", str(bad),
                              "--human-models", "tired", "--out", str(out))
    assert line == (f"hrc_experiment: {bad}: observations O36 are not the task's "
                    "observations (missing: O35)")
    assert not log.exists(), "a stack was started"
    assert not out.exists(), "the results directory was touched"


def test_a_missing_human_model_is_refused_before_any_stack(tmp_path, fake_ros, monkeypatch):
    _, log = fake_ros
    out = tmp_path / "out"
    line = refused_in_process(monkeypatch, fake_ros, "--human-models",
                              "tired,does_not_exist", "--out", str(out))
    assert line.startswith("hrc_experiment: --human-models: no human model named "
                           "'does_not_exist'")
    assert "known: beginner, " in line and ", tired" in line
    assert not log.exists() and not out.exists()


def test_a_human_model_file_that_does_not_fit_is_refused(tmp_path, capsys):
    bad = tmp_path / "h.pomdpx"
    bad.write_text((ROOT / "models" / "human" / "tired.pomdpx").read_text()
                   .replace("warnRobot", "shout"))
    assert main(["--human-models", f"tired,{bad}", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err == (f"hrc_experiment: {bad}: actions shout are not the task's actions "
                   "(missing: warnRobot)\n")


@pytest.mark.parametrize("args, message", [
    (["--time-per-step", "0.1"], "unrecognized arguments: --time-per-step 0.1"),
    (["--seeds", "0,-1"], "argument --seeds: seeds are comma-separated; each must be an "
                          "integer from 0 to 2147483647, got '-1'"),
    (["--episodes", "0"], "argument --episodes: must be an integer >= 1, got '0'"),
    (["--step-limit", "x"], "argument --step-limit: must be an integer >= 1, got 'x'"),
    (["--scenarios", "0"], "argument --scenarios: must be an integer from 1 to 100000, got '0'"),
    (["--human-choice", "lazy"], "argument --human-choice: must be one of optimal, softmax, "
                                 "random, got 'lazy'"),
    # numbers past what their consumers take (before: accepted; a 5000-digit --episodes
    # was a traceback)
    (["--episodes", str(2**32)], "argument --episodes: must be an integer from 1 to 4294967295, "
                                 "got '4294967296'"),
    (["--episodes", "9" * 5000], "argument --episodes: must be an integer from 1 to "
                                 f"4294967295, got '{'9' * 40}... (5000 characters)'"),
    (["--step-limit", str(2**31)], "argument --step-limit: must be an integer from 1 to "
                                   "2147483647, got '2147483648'"),
    (["--jobs", "1000000"], "argument --jobs: must be an integer from 0 to 1000, "
                            "got '1000000'"),
    (["--seeds", "0,2147483648"], "argument --seeds: seeds are comma-separated; each must be "
                                  "an integer from 0 to 2147483647, got '2147483648'"),
])
def test_a_bad_option_is_one_line(args, message, capsys):
    with pytest.raises(SystemExit) as info:
        build_parser().parse_args(args)
    assert info.value.code == 2
    assert capsys.readouterr().err == f"hrc_experiment: {message}\n"


def test_the_grid_takes_its_defaults_from_the_settings():
    args = build_parser().parse_args([])
    assert not hasattr(args, "time_per_step")   # cells are bounded by trials, never by time
    assert (args.max_trials, args.reactive_budget, args.scenarios, args.depth, args.lambda_) == (
        0, 8, 500, 90, 0.1)
    assert args.robot_model == "robot" and args.human_choice == "optimal"
    validate_grid(args)   # the default grid is good
    cell = plan_cells(args, set())[0]
    assert cell.max_trials == 0    # 0: EXPERIMENT_TRIALS per decision (stack.launch_settings)


def test_every_cell_s_launch_arguments_pass_the_launch_s_checks():
    spec = CellSpec("tired", "reactive", 4, episodes=[0], scenarios=7, lambda_=0.5)
    config = check_launch_settings(spec)
    assert (config["planner"], config["scenarios"], config["lambda"]) == ("reactive", 7, 0.5)
    assert config["pause_when_idle"] is True and config["use_sim_time"] is False
    ports = {"master": 1, "pomdp": 7071, "robot": 8081, "human": 9091}
    assert {"scenarios:=7", "lambda:=0.5", "depth:=90"} <= set(launch_arguments(spec, ports))
    with pytest.raises(SettingError, match="^belt_speed:=9: must be a number from 0 to 0.5"):
        check_launch_settings(CellSpec("tired", "pomdp", 0, [0], extra_args=["belt_speed:=9"]))


def test_a_cell_runs_in_the_node_module_and_its_spec_travels_in_a_file(tmp_path):
    """Before: the spec was one argv word; at --episodes >= ~22,000 it passed 128 KiB and every
    cell failed with "Argument list too long"."""
    spec = CellSpec("/data/my model.pomdpx", "no_robot", 2, episodes=[1, 3])
    path = write_spec(spec, tmp_path)
    command = worker_command(path)
    assert command == [sys.executable, "-m", "ros_hrc.nodes.experiment_cell", str(path)]
    assert read_spec(command[3]) == spec
    assert json.loads(path.read_text())["human_model"] == "/data/my model.pomdpx"
    assert cell_name(spec) == "my_model-no_robot-seed2"
    assert cell_name(CellSpec("tired", "pomdp", 0, [0])) == "tired-pomdp-seed0"
    # every other episode recorded: the spec lists ranges, and no command line grows with it
    many = CellSpec("tired", "pomdp", 0, EpisodeRanges.missing(100_000, range(0, 100_000, 2)))
    assert len(many.episodes) == 50_000 and list(many.episodes)[:3] == [1, 3, 5]
    assert read_spec(write_spec(many, tmp_path)) == many
    assert sum(len(word) for word in worker_command(write_spec(many, tmp_path))) < 4096


def test_the_grid_is_planned_lazily(tmp_path):
    """Before: --episodes 1000000000 built every episode's entry (MemoryError at 4 GB)."""
    args = build_parser().parse_args(["--human-models", "tired", "--policies", "no_robot",
                                      "--seeds", "0", "--episodes", str(10**9),
                                      "--out", str(tmp_path)])
    cells = plan_cells(args, {("tired", "no_robot", 0, 5), ("tired", "no_robot", 0, 6)})
    assert len(cells) == 1 and len(cells[0].episodes) == 10**9 - 2
    assert cells[0].episodes.spans == ((0, 5), (7, 10**9))
    assert len(cells[0].to_json()) < 4096


def test_file_arguments_are_made_absolute_once_for_the_cells(tmp_path, monkeypatch):
    """Before: a relative --robot-model reached the robot process, which runs in $ROS_HOME,
    as typed: "no model file", respawned every second, and the cell waited 600 s."""
    work = tmp_path / "work"
    (work / "mine").mkdir(parents=True)
    for kind, name in (("robot", "robot.pomdp"), ("human", "tired.pomdpx")):
        (work / "mine" / name).write_text((ROOT / "models" / kind / name).read_text())
    monkeypatch.chdir(work)
    args = build_parser().parse_args(["--robot-model", "mine/robot.pomdp", "--human-models",
                                      "./mine/tired.pomdpx,expert", "--policies",
                                      "pomdp,pomdp_fitted", "--seeds", "1", "--episodes", "1",
                                      "--out", "results"])
    validate_grid(args)
    cells = plan_cells(args, set())
    assert [(c.human_model, c.robot_policy) for c in cells] == [
        ("./mine/tired.pomdpx", "pomdp"), ("./mine/tired.pomdpx", "pomdp_fitted"),
        ("expert", "pomdp"), ("expert", "pomdp_fitted")]
    for cell in cells:
        assert Path(cell.robot_model).is_absolute() and Path(cell.robot_model).is_file()
        values = dict(w.split(":=", 1) for w in launch_arguments(cell, {
            "master": 1, "pomdp": 2, "robot": 3, "human": 4}))
        assert Path(values["human_model"]).is_absolute() and Path(values["robot_model"]) \
            .is_absolute(), values
        assert Path(cell.log_dir) == work / "results" / "logs"
    assert cells[0].robot_model == str(work / "mine" / "robot.pomdp")
    assert cells[1].robot_model == str(ROOT / "models" / "robot" / "robot_fitted.pomdp")
    assert cells[0].human_model_file == str(work / "mine" / "tired.pomdpx")
    assert cells[2].human_model_file == str(ROOT / "models" / "human" / "expert.pomdpx")


def test_a_missing_relative_model_is_one_line_before_any_stack(tmp_path, fake_ros, monkeypatch):
    _, log = fake_ros
    monkeypatch.chdir(tmp_path)
    line = refused_in_process(monkeypatch, fake_ros, "--robot-model",
                              "nowhere/robot.pomdp", "--out", "out")
    assert line.startswith("hrc_experiment: --robot-model: no model file ")
    assert line.endswith(f"(looked for {tmp_path}/nowhere/robot.pomdp)")
    assert not log.exists() and not (tmp_path / "out").exists()


# ------------------------------------------------------------------------------------ ports

def test_the_ports_of_a_cell_are_distinct_and_free(monkeypatch):
    """Before: free_port() four times could give the master and the human link one port
    (about 1 cell in 190), and hrc_human died on "Address already in use" until the 600 s
    timeout."""
    handed_out = iter([7001, 7001, 7002, 7001, 7002, 7003, 7004, 7004, 7005])
    monkeypatch.setattr(stack, "free_port", lambda: next(handed_out))
    monkeypatch.setattr(stack, "port_is_free", lambda port: port != 7003)   # taken meanwhile
    ports = stack.pick_ports()
    assert set(ports) == {"master", "pomdp", "human"}
    assert ports == {"master": 7001, "pomdp": 7002, "human": 7004}


def test_a_cell_without_free_ports_fails_with_the_reason(monkeypatch):
    monkeypatch.setattr(stack, "free_port", lambda: 7001)
    with pytest.raises(stack.CellFailed, match="no free port for the pomdp after 50 tries"):
        stack.pick_ports()


def test_real_ports_are_distinct_and_bindable():
    for _ in range(20):
        ports = stack.pick_ports()
        assert len(set(ports.values())) == 3
        assert all(stack.port_is_free(p) for p in ports.values())


# ------------------------------------------------------------------------------------ lock

def test_a_directory_is_locked_by_one_holder_at_a_time(tmp_path):
    out = tmp_path / "out"
    with lock_directory(out) as lock:
        assert lock.held
        assert (out / ".lock").read_text() == f"{os.getpid()}\n"
        with pytest.raises(DirectoryLocked) as info:
            lock_directory(out)
        assert info.value.pid == os.getpid()
        assert str(out) in str(info.value) and f"pid {os.getpid()}" in str(info.value)
    assert not lock.held
    assert not (out / ".lock").exists()     # released: the directory holds results only
    lock_directory(out).release()     # free again
    assert sorted(p.name for p in out.iterdir()) == []


def test_a_lock_file_removed_as_another_opened_it_is_not_taken_by_both(tmp_path):
    """The holder removes the file at its release, still locked: one that opened the old file
    just before must not hold it as well as one that makes the new file."""
    import fcntl

    out = tmp_path / "out"
    first = lock_directory(out)
    stale = os.open(out / ".lock", os.O_RDWR)      # opened before the holder's release
    first.release()
    fcntl.flock(stale, fcntl.LOCK_EX | fcntl.LOCK_NB)   # the old, removed file: free
    with lock_directory(out) as second:           # the path's new file
        assert second.held and (out / ".lock").exists()
    os.close(stale)


def test_a_second_run_on_a_locked_directory_is_refused_touching_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    with lock_directory(out):
        before = sorted(p.name for p in out.iterdir())
        assert main(["--human-models", "tired", "--policies", "no_robot", "--seeds", "0",
                     "--episodes", "1", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1
        assert err.startswith(f"hrc_experiment: {out} is in use by another run "
                              f"(pid {os.getpid()})")
        assert sorted(p.name for p in out.iterdir()) == before == [".lock"]
        assert (out / ".lock").read_text() == f"{os.getpid()}\n"


def test_experiment_launch_defaults_are_the_command_s_own():
    """experiment.launch spells hrc_experiment's defaults out (roslaunch lists an argument
    with an empty default as "Required"): they must stay the command's."""
    import xml.etree.ElementTree as ET
    launch = ET.parse(ROOT / "launch" / "experiment.launch").getroot()
    default = {a.get("name"): a.get("default") for a in launch.iter("arg") if a.get("default")}
    args = build_parser().parse_args([])
    assert names_argument(default["human_models"]) == args.human_models
    assert [int(s) for s in default["seeds"].split(",")] == args.seeds
    assert (int(default["episodes"]), int(default["step_limit"]), default["human_choice"],
            int(default["max_trials"]), int(default["reactive_budget"])) == (
        args.episodes, args.step_limit, args.human_choice, args.max_trials, args.reactive_budget)
    assert budgets_argument(default["reactive_budgets"]) == list(range(1, 11))
    assert budgets_argument("none") == []


def test_the_fabric_study_runs_its_own_humans_and_robots_and_sweeps_the_wait():
    """--task fabric: its ten human types, the human alone, its reactive robot and its POMDP
    robot by default; a reactive@N cell waits N simulated seconds (reactive_wait:=N), the
    seed's keeps its budget in observations."""
    args = build_parser().parse_args(["--task", "fabric", "--reactive-budgets", "5,20"])
    assert len(args.human_models) == 10 and "expert_tired_collaborative" in args.human_models
    assert args.policies == ["pomdp", "reactive", "no_robot"]
    assert args.step_limit == 300      # a safety net: the world ends a fabric episode
    assert build_parser().parse_args([]).step_limit == 15
    validate_grid(args)
    cells = {(c.human_model, c.robot_policy): c for c in plan_cells(args, set())}
    assert {p for _, p in cells} == {"pomdp", "reactive", "no_robot", "reactive@5", "reactive@20"}
    wait = cells[("distracted_collaborative", "reactive@20")]
    assert "task:=fabric" in wait.extra_args and "reactive_wait:=20" in wait.extra_args
    assert cells[("distracted_collaborative", "pomdp")].robot_model.endswith(
        "models/fabric/robot/base.pomdpx")
    seed = build_parser().parse_args(["--reactive-budgets", "3", "--human-models", "tired"])
    cell = [c for c in plan_cells(seed, set()) if c.robot_policy == "reactive@3"][0]
    assert cell.reactive_budget == 3 and not any("reactive_wait" in a for a in cell.extra_args)


def test_a_seed_model_in_a_fabric_grid_is_one_line_naming_its_task(capsys):
    seed_robot = str(ROOT / "models" / "robot" / "robot.pomdp")
    assert main(["--task", "fabric", "--robot-model", seed_robot, "--policies", "pomdp",
                 "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hrc_experiment: ") and "robot.pomdp" in err and "task seed" in err
    assert len(err.strip().splitlines()) == 1
