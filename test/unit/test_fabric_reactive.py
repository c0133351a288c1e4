"""FABRIC's reactive MDP robot (issue #22): the authors' observation -> MDP-state rules in
order (ros_hrc.tasks.fabric_reactive), the MDP's optimal policy computed by our value
iteration, and the planner that puts them together over the robot model's belief
(ros_hrc.agents.robots.ReactiveMdpPlanner), as the robot process runs it."""
import numpy as np
import pytest

from ros_hrc import tasks
from ros_hrc.link.protocol import Decision, Observation, Reset
from ros_hrc.models import load_robot_model
from ros_hrc.model_files import resolve_model
from ros_hrc.pomdp.io import load_model
from ros_hrc.processes.despot_pomdp import PomdpProcess, RobotAgent, build_parser, build_planner
from ros_hrc.agents.robots import (ReactiveMdpConfig, ReactiveMdpPlanner, ReactivePlanner,
                                    mdp_policy, reactive_planner)
from ros_hrc.tasks.fabric_reactive import (BY_OBSERVATION, DEFAULT_WAIT, MDP_STATES,
                                           ReactiveStateMap)

FABRIC = tasks.get("fabric")


@pytest.fixture(scope="module")
def robot():
    return load_robot_model("base", FABRIC)


@pytest.fixture(scope="module")
def mdp():
    return load_model(resolve_model("reactive", "robot", FABRIC.model_dirs["robot"]))


# -- the rules ----------------------------------------------------------------------------------

@pytest.mark.parametrize("observation, state, rule", [
    ("O0", "HumanNeedsHelp", "not_detected"),
    ("O2", "TaskHuman", "no_change"), ("O3", "TaskHuman", "no_change"),
    ("O34", "TaskHuman", "no_change"), ("O35", "TaskHuman", "no_change"),
    ("O6", "TaskHuman", "grasp_attempt"), ("O7", "TaskHuman", "grasp_attempt"),
    ("O8", "GlobalSuccess", "success"), ("O40", "GlobalSuccess", "success"),
    ("O32", "HumanNeedsHelp", "idle_not_detected"),
    ("O16", "WarningReceived", "warning"),
    ("O64", "GlobalFail", "failure"),
])
def test_rule_3_names_the_state_by_the_observation(observation, state, rule):
    states = ReactiveStateMap()
    assert states(observation, elapsed=1.0) == (state, rule)
    assert (states.state, states.rule) == (state, rule)


def test_rule_3_covers_every_observation_of_the_task():
    assert set(BY_OBSERVATION) == set(FABRIC.observations.names)
    assert {s for _, s in BY_OBSERVATION.values() if s} <= set(MDP_STATES)


def test_looking_or_idling_keeps_the_previous_state():
    states = ReactiveStateMap()
    states("O16", 1.0)
    for observation in ("O2", "O3", "O34", "O35"):
        assert states(observation, 2.0) == ("WarningReceived", "no_change")


def test_not_detected_after_task_robot_stays_task_robot():
    """O0: HumanNeedsHelp, but TaskRobot when the task was the robot's."""
    states = ReactiveStateMap(start="TaskRobot")
    assert states("O0", 1.0) == ("TaskRobot", "not_detected")
    assert states("O35", 2.0) == ("TaskRobot", "no_change")
    states.reset()
    assert states("O0", 1.0) == ("HumanNeedsHelp", "not_detected")


def test_a_grasp_attempt_without_success_is_help_at_the_next_observation():
    """Rule 2: the attempted flag, set by O6/O7, gives HumanNeedsHelp at the next observation
    that shows no product in a tray, and is cleared."""
    states = ReactiveStateMap()
    assert states("O7", 1.0) == ("TaskHuman", "grasp_attempt") and states.attempted
    assert states("O35", 2.0) == ("HumanNeedsHelp", "attempt_failed")
    assert not states.attempted
    # Cleared: a later observation is read by itself again.
    assert states("O16", 3.0) == ("WarningReceived", "warning")
    assert states("O35", 4.0) == ("WarningReceived", "no_change")


def test_a_grasp_attempt_that_succeeded_is_success():
    states = ReactiveStateMap()
    states("O6", 1.0)
    assert states("O8", 2.0) == ("GlobalSuccess", "success")
    states.reset()
    states("O6", 1.0)
    assert states("O64", 2.0) == ("GlobalFail", "failure")


def test_the_flag_waits_while_the_human_is_already_helped():
    """Rules 1 and 2 ask that the previous state was not HumanNeedsHelp."""
    states = ReactiveStateMap()
    states("O0", 1.0)                       # HumanNeedsHelp
    assert states("O7", 2.0) == ("TaskHuman", "grasp_attempt")
    assert states("O7", 3.0) == ("HumanNeedsHelp", "attempt_failed")
    assert states("O7", 4.0) == ("TaskHuman", "grasp_attempt")   # after HumanNeedsHelp: rule 3


def test_the_wait_is_simulated_seconds_since_the_reset():
    """Rule 1: at ``wait`` s without a product in a tray the human needs help, unless he was
    already helped at the previous observation; an unknown time never counts."""
    states = ReactiveStateMap()
    assert DEFAULT_WAIT == 15.0 and states.wait == 15.0
    assert states("O35", 14.9) == ("TaskHuman", "no_change")
    assert states("O35", 15.0) == ("HumanNeedsHelp", "waited")
    assert states("O35", 16.0) == ("HumanNeedsHelp", "no_change")   # previous HumanNeedsHelp
    assert states("O16", 17.0) == ("WarningReceived", "warning")
    assert states("O35", 18.0) == ("HumanNeedsHelp", "waited")      # again, once it is not
    states.reset()
    assert states("O35", None) == ("TaskHuman", "no_change")
    assert states("O35", 1000.0) == ("HumanNeedsHelp", "waited")


def test_the_wait_yields_to_a_product_in_a_tray_and_comes_before_the_flag():
    states = ReactiveStateMap(wait=5.0)
    assert states("O8", 6.0) == ("GlobalSuccess", "success")
    assert states("O64", 7.0) == ("GlobalFail", "failure")
    states.reset()
    states("O7", 1.0)
    assert states("O35", 5.0) == ("HumanNeedsHelp", "waited")
    assert states.attempted        # rule 1 applied, so rule 2 did not clear the flag


def test_a_wait_of_zero_never_helps_for_that_reason():
    states = ReactiveStateMap(wait=0)
    assert states("O35", 1e6) == ("TaskHuman", "no_change")


@pytest.mark.parametrize("wait", [-1, float("nan"), float("inf"), "15", True])
def test_a_bad_wait_is_refused(wait):
    with pytest.raises(ValueError, match="reactive wait"):
        ReactiveStateMap(wait)


def test_an_unknown_observation_is_refused():
    with pytest.raises(ValueError, match="unknown observation 'O5'"):
        ReactiveStateMap()("O5", 1.0)


# -- the MDP's policy ---------------------------------------------------------------------------

def test_the_reactive_mdps_optimal_policy(mdp):
    """Value iteration on models/fabric/robot/reactive.pomdpx gives the authors' rules
    (docs/tasks_fabric_facts.md), except that in TaskRobot it grasps."""
    policy = mdp_policy(mdp)
    assert set(policy) == set(MDP_STATES)
    assert policy["TaskHuman"] == "idle"
    assert policy["HumanNeedsHelp"] == "grasp"
    assert policy["WarningReceived"] == "cancel"
    assert policy["TaskRobot"] == "grasp"


# -- the planner --------------------------------------------------------------------------------

def test_the_planner_keeps_the_belief_and_acts_by_the_mdp(robot, mdp):
    planner = ReactiveMdpPlanner(robot, mdp, ReactiveMdpConfig(wait=15.0), seed=0)
    assert planner.belief.shape == (11,)
    assert robot.actions[planner.act()] == "idle" and planner.last_rule == "start"
    idle = robot.index("action", "idle")
    steps = [("O35", 0.8, "idle", "no_change", "TaskHuman"),
             ("O7", 3.2, "idle", "grasp_attempt", "TaskHuman"),
             ("O35", 6.7, "grasp", "attempt_failed", "HumanNeedsHelp"),
             ("O16", 9.0, "cancel", "warning", "WarningReceived"),
             ("O35", 15.5, "grasp", "waited", "HumanNeedsHelp")]
    action = idle
    for observation, elapsed, expected, rule, state in steps:
        planner.observe_time(elapsed)
        planner.update(action, robot.index("observation", observation))
        action = planner.act()
        assert (robot.actions[action], planner.last_rule, planner.mdp_state) == (
            expected, rule, state), observation
        assert np.isclose(planner.belief.sum(), 1.0)
    planner.reset()
    assert (planner.mdp_state, planner.last_rule, planner.elapsed) == ("TaskHuman", "start", None)
    assert "TaskRobot: grasp" in planner.policy_text()


def test_the_planner_refuses_models_it_cannot_read(robot, mdp):
    seed_robot = load_robot_model("robot", tasks.get("seed"))
    with pytest.raises(ValueError, match="reads observations O0, O2"):
        ReactiveMdpPlanner(seed_robot, mdp)
    with pytest.raises(ValueError, match="needs an MDP over TaskHuman"):
        ReactiveMdpPlanner(robot, robot)


def test_planner_reactive_is_the_tasks_reactive_robot(robot):
    """The seed keeps its rules on bits; fabric's is the reactive MDP, with its wait."""
    seed_robot = load_robot_model("robot", tasks.get("seed"))
    assert type(reactive_planner(tasks.get("seed"), seed_robot, budget=3)) is ReactivePlanner

    def parse(*argv):
        return build_parser().parse_args(["--task", "fabric", *argv])

    planner = build_planner(robot, parse("--planner", "reactive", "--reactive-wait", "5"))
    assert isinstance(planner, ReactiveMdpPlanner) and planner.config.wait == 5.0
    assert build_planner(robot, parse("--planner", "reactive")).config.wait == 15.0


def test_the_robot_process_applies_the_wait_to_the_observations_time(robot, capsys):
    """The observation's elapsed reaches the rules; the decision names the rule, and the
    terminal prints the time, the rule and the MDP state."""
    planner = reactive_planner(FABRIC, robot, wait=10.0, seed=0)
    process = PomdpProcess(RobotAgent(robot, planner, first_action="idle"))
    process.on_reset(Reset(reason="test", episode=0, epoch=1), None)
    answers = [process.on_observation(Observation(step=n, observation="O35", bits=35,
                                                  state="TaskHuman", elapsed=t, epoch=1), None)
               for n, t in enumerate((0.8, 9.9, 10.0))]
    assert all(isinstance(a, Decision) for a in answers)
    assert [(a.action, a.rule) for a in answers] == [
        ("idle", "no_change"), ("idle", "no_change"), ("grasp", "waited")]
    out = capsys.readouterr()
    assert "- Observation = O35 (bits 35) at 10.0 s;" in out.out
    assert "(rule waited, MDP state HumanNeedsHelp, " in out.out
    assert "cannot apply" not in out.err
    # An observation without a time: said once on stderr, and the wait cannot apply.
    process.on_reset(Reset(reason="test", episode=1, epoch=2), None)
    for n in range(2):
        answer = process.on_observation(Observation(step=n, observation="O35", bits=35,
                                                    state="TaskHuman", epoch=2), None)
        assert (answer.action, answer.rule) == ("idle", "no_change")
    assert capsys.readouterr().err.count("the reactive robot's wait (rule waited) cannot "
                                         "apply") == 1
