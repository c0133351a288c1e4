"""FABRIC's models (models/fabric/): the seed authors' successor task, written by
tools/make_fabric_models.py from the authors' figures in tools/fabric_tables/
(cangorur/human_robot_collaboration; models/README.md, "FABRIC (the successor task)")."""
import importlib.util
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from ros_hrc.pomdp import pomdpx
from ros_hrc.commands.pomdp import run

ROOT = Path(__file__).resolve().parents[3]
FABRIC = ROOT / "models" / "fabric"
BUILDER = ROOT / "tools" / "make_fabric_models.py"

HUMAN_STATES = ["TaskHuman", "GlobalSuccess", "GlobalFail", "FailedToGrasp", "NoAttention",
                "Evaluating", "Tired", "Recovery", "RobotInterfered", "WarningTheRobot",
                "RobotIsWarned", "TaskRobot"]
HUMAN_ACTIONS = ["graspAttempt", "lookAround", "idle", "walkAway", "warnRobot"]
HUMAN_TYPES = [f"{e}_{t}_{c}" for e in ("beginner", "expert") for t in ("nontired", "tired")
               for c in ("collaborative", "noncollaborative")] + \
              ["distracted_collaborative", "distracted_noncollaborative"]
ROBOT_STATES = ["TaskHuman", "MayNotBeCapable", "MayBeTired", "NoFocus", "NeedsToBeReminded",
                "NeedsHelp", "NoNeedHelp", "WarningReceived", "GlobalSuccess", "GlobalFail",
                "TaskRobot"]
ROBOT_ACTIONS = ["idle", "grasp", "cancel", "point", "graspPlanning"]
ROBOT_OBSERVATIONS = ["O0", "O2", "O3", "O6", "O7", "O8", "O16", "O32", "O34", "O35", "O40",
                      "O64"]
#: The authors' twelve policy variants of the base but policy2, which the repository index
#: holds in no folder (models/README.md).
POLICIES = [f"policy{n}" for n in (1, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12)]
REACTIVE_STATES = ["TaskHuman", "GlobalSuccess", "HumanNeedsHelp", "WarningReceived",
                   "TaskRobot", "GlobalFail"]


def human(name):
    return pomdpx.load(FABRIC / "human" / f"{name}.pomdpx")


def robot(name):
    return pomdpx.load(FABRIC / "robot" / f"{name}.pomdpx")


def prob(model, action, s, s2):
    return model.T[model.actions.index(action)][model.states.index(s), model.states.index(s2)]


def obs(model, action, s2, o):
    return model.O[model.actions.index(action)][model.states.index(s2),
                                                model.observations.index(o)]


def reward(model, action, s, s2):
    return model.R[model.actions.index(action)][model.states.index(s), model.states.index(s2)]


def test_the_shipped_files_are_the_ten_humans_the_base_eleven_policies_and_the_reactive_mdp():
    assert sorted(p.stem for p in (FABRIC / "human").glob("*.pomdpx")) == sorted(HUMAN_TYPES)
    assert sorted(p.stem for p in (FABRIC / "robot").glob("*.pomdpx")) == \
        sorted(["base", "reactive"] + POLICIES)


@pytest.mark.parametrize("path", sorted(FABRIC.glob("*/*.pomdpx")), ids=lambda p: p.stem)
def test_every_file_passes_hrc_pomdp_info(path, capsys):
    assert run(["info", str(path)]) == 0
    assert "checks passed" in capsys.readouterr().out


@pytest.mark.parametrize("name", HUMAN_TYPES)
def test_each_human_is_a_12_state_mdp_with_the_seeds_actions(name):
    m = human(name)
    m.validate()
    assert m.fully_observable
    assert m.states == HUMAN_STATES and m.actions == HUMAN_ACTIONS
    assert m.discount == 0.98 and m.initial_belief[0] == 1.0
    for a in HUMAN_ACTIONS:                      # the task's end is absorbing for the human
        for end in ("GlobalSuccess", "GlobalFail"):
            assert prob(m, a, end, end) == 1.0


@pytest.mark.parametrize("name", ["base"] + POLICIES)
def test_each_robot_pomdp_has_11_states_5_actions_12_observations(name):
    m = robot(name)
    m.validate()
    assert not m.fully_observable
    assert m.states == ROBOT_STATES and m.actions == ROBOT_ACTIONS
    assert m.observations == ROBOT_OBSERVATIONS
    assert m.discount == 0.98 and m.initial_belief[0] == 1.0


def test_the_reactive_robot_is_a_6_state_mdp_with_idle_grasp_cancel():
    m = robot("reactive")
    m.validate()
    assert m.fully_observable and m.states == REACTIVE_STATES
    assert m.actions == ["idle", "grasp", "cancel"] and m.discount == 0.98


# -- figures spot-checked against the authors' files ---------------------------------------------
# (type, graspAttempt Evaluating->GlobalSuccess, idle TaskHuman->Evaluating, ->Tired,
#  idle RobotInterfered->GlobalSuccess, ->WarningTheRobot, R graspAttempt->GlobalSuccess,
#  R idle->Evaluating, R lookAround->NoAttention): models/README.md's table
HUMAN_FIGURES = [
    ("beginner_nontired_collaborative", 0.24, 0.76, 0.05, 0.3, 0.15, 4, 2, 1),
    ("beginner_nontired_noncollaborative", 0.25, 0.76, 0.05, 0.09, 0.58, 4, 2, 1),
    ("beginner_tired_collaborative", 0.25, 0.51, 0.3, 0.2, 0.15, 3, 4, 1),
    ("beginner_tired_noncollaborative", 0.25, 0.51, 0.3, 0.09, 0.58, 3, 4, 1),
    ("expert_nontired_collaborative", 0.72, 0.8, 0.01, 0.5, 0.07, 5, 2, 1),
    ("expert_nontired_noncollaborative", 0.67, 0.76, 0.05, 0.1, 0.57, 5, 2, 1),
    ("expert_tired_collaborative", 0.63, 0.51, 0.3, 0.3, 0.07, 5, 2, 1),
    ("expert_tired_noncollaborative", 0.63, 0.51, 0.3, 0.1, 0.57, 5, 2, 1),
    ("distracted_collaborative", 0.38, 0.8, 0.01, 0.5, 0.07, 3, 0, 5),
    ("distracted_noncollaborative", 0.48, 0.8, 0.01, 0.05, 0.73, 2, 3.5, 7.5),
]


@pytest.mark.parametrize("row", HUMAN_FIGURES, ids=lambda r: r[0])
def test_what_sets_the_human_types_apart_is_the_authors_figures(row):
    name, grasp_ev, idle_ev, idle_tired, ri_gs, ri_warn, r_grasp, r_eval, r_look = row
    m = human(name)
    assert prob(m, "graspAttempt", "Evaluating", "GlobalSuccess") == grasp_ev
    assert prob(m, "idle", "TaskHuman", "Evaluating") == idle_ev
    assert prob(m, "idle", "TaskHuman", "Tired") == idle_tired
    assert prob(m, "idle", "RobotInterfered", "GlobalSuccess") == ri_gs
    assert prob(m, "idle", "RobotInterfered", "WarningTheRobot") == ri_warn
    # rewards are on the state reached, whatever the state left
    for s in ("TaskHuman", "Evaluating", "Tired"):
        assert reward(m, "graspAttempt", s, "GlobalSuccess") == r_grasp
        assert reward(m, "idle", s, "Evaluating") == r_eval
        assert reward(m, "lookAround", s, "NoAttention") == r_look


@pytest.mark.parametrize("name", HUMAN_TYPES)
def test_rows_every_human_type_shares(name):
    m = human(name)
    # a task the robot holds ends or draws a warning when the human idles
    assert [prob(m, "idle", "TaskRobot", s) for s in HUMAN_STATES] == \
        [0, 0.4, 0.1, 0, 0, 0, 0, 0, 0, 0.2, 0, 0.3]
    assert prob(m, "graspAttempt", "TaskHuman", "GlobalSuccess") == 0.09
    assert prob(m, "graspAttempt", "Recovery", "Recovery") == 0.9
    # warnRobot moves only RobotInterfered, WarningTheRobot and RobotIsWarned
    for s in HUMAN_STATES[:8] + ["TaskRobot"]:
        assert prob(m, "warnRobot", s, s) == 1.0
    assert reward(m, "warnRobot", "TaskHuman", "TaskHuman") == -3


def test_a_few_more_human_figures():
    assert prob(human("expert_tired_collaborative"), "walkAway", "Tired", "Recovery") == 0.9
    assert prob(human("beginner_tired_noncollaborative"), "lookAround", "RobotInterfered",
                "NoAttention") == 0.3          # Evaluate/'s row, not human_models/'s 0.2
    assert prob(human("beginner_nontired_collaborative"), "warnRobot", "RobotIsWarned",
                "GlobalFail") == 0.6
    assert reward(human("expert_nontired_collaborative"), "warnRobot", "RobotInterfered",
                  "RobotIsWarned") == 1
    assert reward(human("distracted_collaborative"), "walkAway", "TaskHuman",
                  "RobotInterfered") == -1


def test_the_robot_base_figures():
    m = robot("base")
    assert [prob(m, "idle", "TaskHuman", s) for s in ROBOT_STATES] == \
        [0.3, 0.15, 0.22, 0.15, 0.01, 0.01, 0.01, 0.01, 0.12, 0.01, 0.01]
    assert prob(m, "grasp", "NeedsHelp", "GlobalSuccess") == 0.81
    assert prob(m, "graspPlanning", "NoFocus", "NeedsToBeReminded") == 0.25
    assert prob(m, "cancel", "WarningReceived", "GlobalSuccess") == 0.42
    assert obs(m, "idle", "MayBeTired", "O32") == 0.001
    assert obs(m, "point", "WarningReceived", "O16") == 0.89
    assert obs(m, "grasp", "GlobalSuccess", "O8") == obs(m, "grasp", "GlobalSuccess", "O40") \
        == 0.45
    for table in m.O:                            # one observation table for every action
        assert (table != m.O[0]).nnz == 0
    assert reward(m, "cancel", "WarningReceived", "GlobalSuccess") == 3
    assert reward(m, "grasp", "NeedsHelp", "GlobalSuccess") == 6
    assert reward(m, "idle", "TaskHuman", "WarningReceived") == -3
    assert reward(m, "point", "NoFocus", "GlobalFail") == -3
    assert reward(m, "graspPlanning", "NoFocus", "NoFocus") == 0


def test_each_policy_differs_from_the_base_where_the_authors_file_does():
    base = robot("base")
    changed = {}                                 # (action, state) rows, in the models' order
    for name in POLICIES:
        m = robot(name)
        changed[name] = [(a, ROBOT_STATES[s]) for i, a in enumerate(ROBOT_ACTIONS)
                         for s in np.flatnonzero(abs(m.T[i] - base.T[i]).sum(axis=1))]
    assert changed["policy1"] == [("grasp", "MayNotBeCapable"), ("grasp", "MayBeTired"),
                                  ("grasp", "NoFocus"), ("grasp", "NeedsHelp")]
    policy3 = [("idle", "MayNotBeCapable"), ("idle", "NoFocus"), ("idle", "WarningReceived"),
               ("grasp", "NeedsHelp"), ("cancel", "WarningReceived"),
               ("graspPlanning", "WarningReceived")]
    assert changed["policy3"] == changed["policy6"] == changed["policy9"] == \
        changed["policy12"] == policy3
    assert changed["policy5"] == changed["policy7"] == changed["policy11"] == changed["policy1"]
    assert changed["policy4"] == changed["policy10"] == [
        ("idle", "GlobalSuccess"), ("grasp", "MayNotBeCapable"), ("grasp", "NeedsHelp"),
        ("point", "MayBeTired"), ("point", "GlobalSuccess"), ("graspPlanning", "MayBeTired")]
    assert changed["policy8"] == [("grasp", "NeedsHelp")] + [
        ("point", s) for s in ("MayNotBeCapable", "MayBeTired", "NoFocus", "NeedsToBeReminded",
                               "NeedsHelp", "WarningReceived")] + [("graspPlanning", "NoFocus")]
    assert prob(robot("policy1"), "grasp", "NeedsHelp", "GlobalFail") == 0.3
    assert prob(robot("policy3"), "grasp", "NeedsHelp", "GlobalSuccess") == 0.82
    assert prob(robot("policy6"), "grasp", "NeedsHelp", "GlobalSuccess") == 0.64
    assert prob(robot("policy9"), "idle", "WarningReceived", "NoNeedHelp") == 0.9
    assert prob(robot("policy12"), "grasp", "NeedsHelp", "GlobalSuccess") == 0.64
    assert prob(robot("policy5"), "grasp", "NeedsHelp", "GlobalSuccess") == 0.79
    assert prob(robot("policy11"), "grasp", "NeedsHelp", "GlobalSuccess") == 0.79
    assert prob(robot("policy7"), "grasp", "NeedsHelp", "GlobalFail") == 0.3
    assert prob(robot("policy4"), "idle", "GlobalSuccess", "NeedsHelp") == 0.86
    assert prob(robot("policy10"), "point", "MayBeTired", "NeedsHelp") == 0.9
    assert prob(robot("policy8"), "point", "WarningReceived", "WarningReceived") == 0.34
    assert prob(robot("policy8"), "graspPlanning", "NoFocus", "NoFocus") == 0.47
    # The failure penalty after point and graspPlanning (the base's -3, or -1).
    for name, point, planning in (("policy1", -1, -1), ("policy3", -1, -1), ("policy4", -1, -1),
                                  ("policy5", -1, -1), ("policy6", -1, -1), ("policy7", -1, -3),
                                  ("policy8", -3, -3), ("policy9", -3, -3), ("policy10", -3, -3),
                                  ("policy11", -3, -1), ("policy12", -3, -3)):
        m = robot(name)
        assert reward(m, "point", "TaskHuman", "GlobalFail") == point, name
        assert reward(m, "graspPlanning", "TaskHuman", "GlobalFail") == planning, name
        assert reward(m, "idle", "TaskHuman", "GlobalFail") == -3
    # The rewards only policy8 and policy11 change (the authors leave some entries out).
    assert reward(robot("policy8"), "grasp", "TaskHuman", "TaskHuman") == 0
    assert reward(robot("policy8"), "point", "TaskHuman", "WarningReceived") == -3
    assert reward(robot("policy11"), "cancel", "TaskHuman", "TaskHuman") == 0
    assert reward(robot("policy11"), "idle", "TaskHuman", "WarningReceived") == -3.5
    assert reward(robot("policy11"), "grasp", "TaskHuman", "WarningReceived") == -3.5


def test_the_reactive_figures_and_its_optimal_policy():
    m = robot("reactive")
    assert [prob(m, "idle", "TaskHuman", s) for s in REACTIVE_STATES] == \
        [0.39, 0.29, 0.1, 0.01, 0.01, 0.2]
    assert prob(m, "grasp", "HumanNeedsHelp", "GlobalSuccess") == 0.75
    assert prob(m, "cancel", "WarningReceived", "WarningReceived") == 0.58
    assert reward(m, "grasp", "TaskHuman", "TaskHuman") == -3
    assert reward(m, "cancel", "HumanNeedsHelp", "GlobalSuccess") == 3
    V = np.zeros(m.n_states)                     # value iteration (as models/README.md says)
    for _ in range(3000):
        Q = m.R_sa + m.discount * m.dense_T @ V
        V = Q.max(axis=0)
    policy = dict(zip(m.states, (m.actions[i] for i in Q.argmax(axis=0))))
    assert {s: policy[s] for s in ("TaskHuman", "HumanNeedsHelp", "WarningReceived",
                                   "TaskRobot")} == \
        {"TaskHuman": "idle", "HumanNeedsHelp": "grasp", "WarningReceived": "cancel",
         "TaskRobot": "grasp"}


# -- the builder ---------------------------------------------------------------------------------
def _builder():
    spec = importlib.util.spec_from_file_location("make_fabric_models", BUILDER)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module              # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_the_builder_rerun_writes_the_shipped_files_byte_for_byte(tmp_path):
    assert _builder().main(["--out", str(tmp_path)]) == 0
    written = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*.pomdpx"))
    shipped = sorted(p.relative_to(FABRIC) for p in FABRIC.rglob("*.pomdpx"))
    assert written == shipped
    for rel in shipped:
        assert (tmp_path / rel).read_bytes() == (FABRIC / rel).read_bytes(), rel


def test_the_builder_changed_no_figure():
    _, notes = _builder().model_texts()
    assert notes.normalised == []


def test_each_file_names_its_source_in_a_comment():
    for path in FABRIC.glob("*/*.pomdpx"):
        second = path.read_text().splitlines()[1]
        assert "cangorur/human_robot_collaboration code/models/" in second, path


def test_the_builder_refuses_an_unwritable_folder_in_one_line(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert _builder().main(["--out", str(blocker)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(blocker) in err[0]


def test_the_tables_are_beside_the_builder_and_name_their_source():
    tables = BUILDER.parent / "fabric_tables"
    assert sorted(p.relative_to(tables).with_suffix(".pomdpx")
                  for p in tables.rglob("*.toml")) == \
        sorted(p.relative_to(FABRIC) for p in FABRIC.rglob("*.pomdpx"))
    builder = _builder()
    for path in tables.rglob("*.toml"):
        figures = builder.read_figures(str(path.relative_to(tables).with_suffix("")))
        assert figures["repository"] == "cangorur/human_robot_collaboration", path
        assert figures["file"].startswith("code/models/") and len(figures["commit"]) == 40


@pytest.mark.parametrize("table, problem", [
    ({"Nowhere": "stay"}, "unknown state 'Nowhere'"),
    ({"NoFocus": "stay", "TaskHuman": "stay"}, "TaskHuman is out of order"),
    ({"TaskHuman": [1.0, 0.0]}, "TaskHuman is [1.0, 0.0], not \"stay\" or a list of 11"),
    ({"TaskHuman": "go"}, "TaskHuman is 'go'"),
])
def test_the_builder_refuses_a_malformed_table_row(table, problem):
    with pytest.raises(ValueError, match=re.escape(problem)):
        _builder().table_rows(table, ROBOT_STATES, len(ROBOT_STATES), range(11), "test")


def test_the_builder_refuses_a_table_for_an_unknown_action():
    with pytest.raises(ValueError, match="unknown actions \\['wave'\\]"):
        _builder().action_rows({"wave": {}}, ROBOT_STATES, ROBOT_ACTIONS, range(11), "test")
