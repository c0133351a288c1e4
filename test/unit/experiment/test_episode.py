"""Scoring an episode from its steps, and planning a grid run (what is left to do)."""
import argparse
from types import SimpleNamespace

import pytest

from ros_hrc.experiment.cli import build_parser
from ros_hrc.experiment.grid import plan_cells
from ros_hrc.experiment.episode import (policy_names, robot_policy, discounted_robot_reward,
                                        needs_help_mass, score_episode, step_rows)
from ros_hrc.experiment.stack import (CellSpec, decode_episode, encode_episode,
                                      launch_arguments)
from ros_hrc.model_files import resolve_model
from ros_hrc.pomdp.io import load_model

STATES = ["S0", "S1", "S2", "S3", "S4", "S5", "S6"]


@pytest.fixture(scope="module")
def robot_model():
    return load_model(str(resolve_model("robot", "robot")))


def step(n, robot_state="S0", robot_action="rIdle", bits=35, holder="none", left=False,
         sim_time=None, belief=None, human_action="idle", human_state="evaluating",
         surprise=False):
    return SimpleNamespace(
        step=n, human_action=human_action, human_state=human_state, observation_bits=bits,
        robot_observation=f"O{bits}", robot_state=robot_state, robot_action=robot_action,
        belief_states=STATES, belief=belief or [1.0, 0, 0, 0, 0, 0, 0], decision_ms=2.0 * (n + 1),
        sim_time=10.0 + n if sim_time is None else sim_time, object_holder=holder,
        object_left_belt=left, surprise=surprise)


def test_scoring_counts_who_succeeded_intrusions_warnings_and_times(robot_model):
    steps = [step(0, robot_action="rGrasp_obj", robot_state="S0"),       # intrusive
             step(1, robot_action="rPoint_obj", robot_state="S4"),       # help when needed
             step(2, robot_action="rStop_all", robot_state="S6", bits=16),  # a warning
             step(3, robot_action="rPoint_obj", robot_state="S1"),       # intrusive
             step(4, robot_action="rIdle", robot_state="S1", holder="human")]
    row = score_episode(("tired", "pomdp", 3, 1), steps, "success", 9.5,
                        robot_model, wall_seconds=1.25)
    assert (row.human_model, row.robot_policy, row.seed, row.episode) == ("tired", "pomdp", 3, 1)
    assert (row.success, row.succeeded_by, row.end_reason) == (1, "human", "success")
    assert row.steps == 5
    assert row.intrusive_actions == 2
    assert row.warnings == 1
    assert row.sim_seconds == pytest.approx(14.0 - 9.5)
    assert row.mean_decision_ms == pytest.approx((2 + 4 + 6 + 8 + 10) / 5)
    assert row.wall_seconds == 1.25


def test_observations_the_model_gave_probability_0_are_counted(robot_model):
    steps = [step(0, bits=19, surprise=True),       # a warning the model did not expect at once
             step(1), step(2, surprise=True), step(3)]
    row = score_episode(("humanModel_completed", "pomdp", 0, 0), steps, "step_limit", 10.0,
                        robot_model, 1.0)
    assert row.zero_probability_observations == 2
    assert [r.zero_probability for r in step_rows(("h", "pomdp", 0, 0), steps)] == [1, 0, 1, 0]
    from ros_hrc.experiment.statistics import summarize
    other = score_episode(("humanModel_completed", "pomdp", 0, 1), steps[1:2], "step_limit",
                          10.0, robot_model, 1.0)
    (entry,) = summarize([row, other])
    assert (entry["zero_probability_observations"], entry["observations"]) == (2, 5)
    assert entry["zero_probability_rate"] == pytest.approx(0.4)


def test_a_missed_object_is_no_success_whoever_was_near(robot_model):
    steps = [step(0), step(1, left=True)]
    row = score_episode(("beginner", "no_robot", 0, 0), steps, "object_left_belt",
                        10.0, robot_model, 0.5)
    assert (row.success, row.succeeded_by, row.end_reason) == (0, "none", "object_left_belt")


def test_the_robot_reward_is_discounted_over_the_true_states(robot_model):
    steps = [step(0, robot_state="S3", robot_action="rGrasp_obj"),
             step(1, robot_state="S2", robot_action="rIdle"),
             step(2, robot_state="S6", robot_action="rStop_all")]
    g = robot_model.discount
    R = robot_model.R_sa
    a = robot_model.actions.index
    s = robot_model.states.index
    expected = (R[a("rGrasp_obj"), s("S3")] + g * R[a("rIdle"), s("S2")]
                + g * g * R[a("rStop_all"), s("S6")])
    assert discounted_robot_reward(steps, robot_model) == pytest.approx(expected)
    assert expected != 0.0



def test_a_model_of_types_scores_the_reward_expected_under_the_steps_type_belief(robot_model):
    """The observer reports the task state (S3), never the type: R is the type belief's mix."""
    import dataclasses
    import scipy.sparse as sp
    from ros_hrc.pomdp.typed import compose
    doubled = dataclasses.replace(robot_model, R=[sp.csr_matrix(r * 2.0) for r in robot_model.R])
    typed = compose({"calm": robot_model, "keen": doubled})
    steps = [step(0, robot_state="S3", robot_action="rGrasp_obj")]
    one = robot_model.R_sa[robot_model.actions.index("rGrasp_obj"), 3]
    steps[0].type_belief = [0.25, 0.75]
    assert discounted_robot_reward(steps, typed) == pytest.approx(0.25 * one + 0.75 * 2 * one)
    del steps[0].type_belief            # none reported: the model's own prior (uniform)
    assert discounted_robot_reward(steps, typed) == pytest.approx(1.5 * one)


def test_the_step_trace_carries_the_belief_in_needs_help_and_the_truth():
    belief = [0.1, 0.1, 0.2, 0.3, 0.1, 0.1, 0.1]
    assert needs_help_mass(step(0, belief=belief)) == pytest.approx(0.7)
    rows = step_rows(("tired", "reactive", 0, 2),
                     [step(0, belief=belief, robot_state="S5"), step(1)])
    assert [r.step for r in rows] == [0, 1]
    assert rows[0].needs_help == 1 and rows[1].needs_help == 0
    assert rows[0].belief_needs_help == pytest.approx(0.7)
    assert rows[0].observation == "O35" and rows[0].episode == 2


def test_a_worker_line_carries_a_whole_episode_and_other_lines_are_ignored(robot_model):
    steps = [step(0), step(1, holder="robot")]
    key = ("expert", "reactive", 1, 0)
    row = score_episode(key, steps, "success", 10.0, robot_model, 2.0)
    line = encode_episode(row, step_rows(key, steps))
    assert "\n" not in line
    back, trace = decode_episode(line)
    assert back.as_dict() == row.as_dict() and [t.step for t in trace] == [0, 1]
    assert decode_episode("[INFO] something else a worker printed") is None


def test_each_robot_policy_starts_its_own_planner_on_its_own_ports():
    spec = CellSpec("tired", "reactive", 4, episodes=[0, 1], reactive_budget=5)
    args = launch_arguments(spec, {"master": 1, "pomdp": 7071, "human": 9091})
    assert "planner:=reactive" in args and "reactive_budget:=5" in args
    assert {"pomdp_port:=7071", "human_port:=9091"} <= set(args)
    assert {"use_sim_time:=false", "real_time_factor:=0", "gui:=false", "seed:=4"} <= set(args)
    assert set(policy_names()) >= {"pomdp", "pomdp_fitted", "pomdp_considerate", "pomdp_types",
                                   "reactive", "no_robot", "explore"}
    assert robot_policy("pomdp_fitted").robot_model == "robot_fitted"
    assert robot_policy("pomdp_types").robot_model == "robot_types"
    with pytest.raises(ValueError, match="unknown robot policy"):
        launch_arguments(CellSpec("tired", "telepathic", 0, episodes=[0]), {
            "master": 1, "pomdp": 2, "robot": 3, "human": 4})


def test_a_resumed_grid_runs_only_the_episodes_not_yet_recorded(tmp_path):
    args = build_parser().parse_args(["--human-models", "tired,expert", "--policies",
                                      "pomdp,no_robot", "--seeds", "0,1", "--episodes", "2",
                                      "--out", str(tmp_path)])
    assert len(plan_cells(args, set())) == 8
    done = {("tired", "pomdp", 0, 0), ("tired", "pomdp", 0, 1), ("expert", "no_robot", 1, 0)}
    cells = plan_cells(args, done)
    assert len(cells) == 7
    partial = [c for c in cells if (c.human_model, c.robot_policy, c.seed) ==
               ("expert", "no_robot", 1)]
    assert list(partial[0].episodes) == [1]


def test_bad_grid_arguments_are_refused_with_a_reason(capsys):
    from ros_hrc.experiment.cli import main
    assert main(["--policies", "pomdp,psychic", "--out", "/nonexistent/never"]) == 2
    assert "psychic" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--seeds", "one,two"])
    assert isinstance(build_parser().parse_args([]), argparse.Namespace)


@pytest.mark.parametrize("words, why", [
    (["--seeds", "1,,2"], "--seeds: an empty item between commas in '1,,2'"),
    (["--seeds", "1,1"], "--seeds: '1' is given twice in '1,1'"),
    (["--human-models", "tired,"], "--human-models: an empty item between commas in 'tired,'"),
])
def test_a_comma_list_with_an_empty_or_repeated_item_is_refused(words, why, capsys):
    """Before: '--seeds 1,,2' ran as seeds 1 and 2."""
    with pytest.raises(SystemExit) as ended:
        build_parser().parse_args(words)
    assert ended.value.code == 2
    assert why in capsys.readouterr().err


def test_a_fabric_episode_is_scored_in_fabric_s_names():
    """The scoring reads the task from the belief's states: fabric's grasp and point intrude,
    its needs-help states are its own, a warning right after the robot's grasp is what the
    intrusion cost, and the human's own success after a point is counted."""
    from ros_hrc import tasks
    fabric = tasks.get("fabric")
    model = load_model(str(resolve_model("base", "robot", fabric.model_dirs["robot"])))

    def fabric_step(n, robot_action="idle", robot_state="TaskHuman", bits=3, holder="none",
                    human_action="idle"):
        belief = [0.0] * len(fabric.robot_states)
        belief[fabric.robot_states.index("NeedsHelp")] = 1.0
        return replace_states(step(n, robot_state=robot_state, robot_action=robot_action,
                                   bits=bits, holder=holder, human_action=human_action),
                              fabric.robot_states, belief)

    steps = [fabric_step(0, robot_action="grasp", robot_state="TaskHuman"),   # intrudes
             fabric_step(1, bits=16, human_action="warnRobot"),                 # what it cost
             fabric_step(2, robot_action="point", robot_state="NeedsHelp", bits=16),
             fabric_step(3, robot_action="idle", bits=8 | 3, holder="human",
                         human_action="graspAttempt")]
    row = score_episode(("beginner_nontired_collaborative", "pomdp", 0, 0), steps, "success",
                        9.0, model, 1.0)
    assert row.intrusive_actions == 1          # the grasp; the point came when he needed it
    assert row.warnings == 2
    assert row.warnings_after_help == 1        # the warning after the grasp
    assert row.against_warning == 1            # the point while the warning held
    assert row.points == 1
    assert row.wasted_actions == 1             # the grasp did not take the object
    assert [r.needs_help for r in step_rows(("h", "pomdp", 0, 0), steps)] == [0, 0, 1, 0]
    assert step_rows(("h", "pomdp", 0, 0), steps)[0].belief_needs_help == 1.0


def replace_states(s, states, belief):
    s.belief_states, s.belief = list(states), belief
    return s


def test_a_cell_knows_its_task_from_its_launch_arguments():
    assert CellSpec("h", "pomdp", 0, [0]).task == "seed"
    assert CellSpec("h", "pomdp", 0, [0], extra_args=["task:=fabric", "x:=1"]).task == "fabric"
