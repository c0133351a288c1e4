"""``hrc_pomdp solve|simulate|info`` take a shipped model's name as ``policy`` does (issue #39:
``hrc_pomdp solve robot`` said "unknown model format '(no extension)'"), and a relative path
is relative to where the command runs."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

from ros_hrc.commands.pomdp import run

ROOT = Path(__file__).resolve().parents[3]


def test_solve_takes_a_shipped_robot_models_name(capsys):
    assert run(["solve", "robot_completed", "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert facts["converged"] and 1.2466 <= facts["lower"] <= facts["upper"] <= 1.2477


def test_info_names_the_file_a_name_found(capsys):
    assert run(["info", "humanModel", "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert facts["file"] == str(ROOT / "models" / "human" / "humanModel.pomdpx")
    assert facts["kind"] == "MDP"


def test_a_name_is_looked_up_in_the_other_tasks_folders_too(capsys):
    assert run(["info", "beginner_tired_collaborative", "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert facts["file"].endswith("models/fabric/human/beginner_tired_collaborative.pomdpx")


def test_simulate_takes_a_name(capsys):
    assert run(["simulate", "humanModel", "--planner", "mdp", "--sim-len", "5",
                "--sim-num", "3", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["sim_num"] == 3


def test_a_relative_path_is_relative_to_where_the_command_runs(tmp_path, monkeypatch, capsys):
    shutil.copy(ROOT / "models" / "robot" / "robot_completed.pomdp", tmp_path / "mine.pomdp")
    (tmp_path / "robot.pomdp").write_text("not a model\n")    # a path wins over a name
    monkeypatch.chdir(tmp_path)
    assert run(["info", "mine.pomdp", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["states"] == 7
    assert run(["info", "robot.pomdp"]) == 2
    assert capsys.readouterr().err.startswith("hrc_pomdp: robot.pomdp:")


def test_an_unknown_name_is_one_line_listing_the_known_names(capsys):
    assert run(["solve", "no_such_model"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith("hrc_pomdp: no model named 'no_such_model' in models/robot, "
                          "models/human, models/fabric/robot, models/fabric/human; known: ")
    known = err.split("known: ")[1].strip().split(", ")
    assert {"robot", "robot_types", "humanModel", "base", "tired"} <= set(known)
    assert known == sorted(known)
