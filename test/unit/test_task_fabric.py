"""The fabric task (issue #22): a human who hears the robot, the authors' observation table,
noise and true-state labels (docs/tasks_fabric_facts.md), as ros_hrc.tasks.fabric has them.

Before this issue the loop knew one task only (ros_hrc.tasks.seed): the human's next state
never depended on the robot, the robot saw the true predicates, and no task but the seed's
could be chosen."""
from types import SimpleNamespace

import numpy as np
import pytest

from ros_hrc import tasks
from ros_hrc.loop.effects import Snapshot
from ros_hrc.models import load_human_model, load_robot_model
from ros_hrc.streams import generator
from ros_hrc.agents.human import HumanAgent, HumanAgentConfig
from ros_hrc.tasks import fabric
from ros_hrc.tasks.fabric import (FAILURE, GRASP_ATTEMPT, IDLE, IN_RANGE, SUCCESS, VISIBLE,
                                  WARNING, FabricObservationMap, FabricReaction,
                                  FabricStateTracker, noisy_bits)

FABRIC = tasks.get("fabric")
RULES = FabricReaction()


def no_draw(state, action):
    raise AssertionError(f"no draw expected (from {state} after {action})")


def drawn(state, action):
    return f"drawn({state},{action})"


# -- the reaction rules, one by one, in their order ---------------------------------------------

@pytest.mark.parametrize("end, state", [("success", "GlobalSuccess"),
                                        ("object_left_belt", "GlobalFail")])
def test_the_tasks_end_sets_the_humans_terminal_state_whatever_the_robot_did(end, state):
    for robot in ("idle", "grasp", "point"):
        reaction = RULES.next_state("Evaluating", "idle", robot, end, no_draw)
        assert (reaction.state, reaction.rule) == (state, "task_end")


def test_a_terminal_state_stays():
    for state in ("GlobalSuccess", "GlobalFail"):
        assert RULES.next_state(state, "idle", "grasp", "", no_draw).state == state


def test_recovery_stays_and_a_walk_away_leads_to_it_even_when_the_robot_grasps():
    assert RULES.next_state("Recovery", "idle", "point", "", no_draw).state == "Recovery"
    reaction = RULES.next_state("NoAttention", "walkAway", "grasp", "", no_draw)
    assert (reaction.state, reaction.rule) == ("Recovery", "recovery")


def test_after_the_robots_grasp_the_human_is_interfered():
    reaction = RULES.next_state("Evaluating", "idle", "grasp", "", no_draw)
    assert (reaction.state, reaction.rule) == ("RobotInterfered", "robot_grasped")
    # The robot's grasp comes before the human's own grasp's outcome (rule 3 before 4).
    assert RULES.next_state("FailedToGrasp", "graspAttempt", "grasp", "", no_draw).state == \
        "RobotInterfered"


def test_a_robot_that_grasps_on_draws_the_interfered_humans_next_state_from_its_row():
    # The authors draw from RobotInterfered's row at every grasp of the robot: a human it
    # keeps grasping against is not held still (he may warn it).
    reaction = RULES.next_state("RobotInterfered", "idle", "grasp", "", drawn)
    assert (reaction.state, reaction.rule) == ("drawn(RobotInterfered,idle)",
                                               "robot_grasped_again")
    reaction = RULES.next_state("RobotInterfered", "warnRobot", "grasp", "", drawn)
    assert reaction.state == "drawn(RobotInterfered,warnRobot)"


def test_his_own_grasp_keeps_the_outcome_drawn_before_the_robot_acted():
    for robot in ("idle", "point", "cancel", "graspPlanning"):
        reaction = RULES.next_state("FailedToGrasp", "graspAttempt", robot, "", no_draw)
        assert (reaction.state, reaction.rule) == ("FailedToGrasp", "own_grasp")


def test_after_the_robot_points_the_human_evaluates():
    for action in ("idle", "lookAround", "warnRobot"):
        reaction = RULES.next_state("NoAttention", action, "point", "", no_draw)
        assert (reaction.state, reaction.rule) == ("Evaluating", "robot_pointed")


def test_a_warning_the_robot_heeds_leaves_the_human_warned():
    for robot in ("idle", "cancel"):
        reaction = RULES.next_state("WarningTheRobot", "warnRobot", robot, "", no_draw)
        assert (reaction.state, reaction.rule) == ("RobotIsWarned", "robot_warned")
    # A warning the robot does not heed (it plans a grasp) is no such thing: his model draws.
    assert RULES.next_state("WarningTheRobot", "warnRobot", "graspPlanning", "", drawn).rule \
        == "model"


def test_otherwise_his_model_draws_from_his_state_and_action():
    reaction = RULES.next_state("Evaluating", "idle", "idle", "", drawn)
    assert (reaction.state, reaction.rule) == ("drawn(Evaluating,idle)", "model")
    # A step limit is not the task's end: the rules go on.
    assert RULES.next_state("Evaluating", "idle", "idle", "step_limit", drawn).rule == "model"


def test_a_grasp_shows_its_outcome_drawn_before_the_robot_acts_and_nothing_else_does():
    assert RULES.acting_state("Evaluating", "graspAttempt", drawn) == \
        "drawn(Evaluating,graspAttempt)"
    assert RULES.acting_state("Evaluating", "idle", no_draw) == "Evaluating"
    assert RULES.acting_state("GlobalSuccess", "graspAttempt", no_draw) == "GlobalSuccess"


def test_draws_never_give_what_only_the_task_or_a_grasp_may_set():
    assert not RULES.allowed("Evaluating", "idle", "GlobalFail")
    assert not RULES.allowed("Evaluating", "graspAttempt", "GlobalFail")
    assert not RULES.allowed("Evaluating", "idle", "GlobalSuccess")
    assert RULES.allowed("Evaluating", "graspAttempt", "GlobalSuccess")
    assert not RULES.allowed("Evaluating", "idle", "RobotInterfered")
    assert RULES.allowed("RobotInterfered", "idle", "RobotInterfered")
    assert not RULES.allowed("TaskHuman", "idle", "TaskRobot")


def test_a_row_loses_its_floors_to_its_largest_entry():
    states = fabric.HUMAN_STATES
    row = [0.01] * 12
    row[states.index("Evaluating")] = 0.9
    row[states.index("TaskRobot")] = 0.0
    shaped = RULES.row(row, states)
    assert shaped[states.index("Evaluating")] == pytest.approx(1.0)
    assert sum(shaped) == pytest.approx(1.0) and max(shaped) == shaped[states.index("Evaluating")]
    uniform = [1.0 / 11] * 11 + [0.0]
    assert RULES.row(uniform, states) == pytest.approx(uniform)   # no floor below the top


# -- the rules through the human agent, on a FABRIC model ---------------------------------------

@pytest.fixture(scope="module")
def beginner():
    return load_human_model("beginner_nontired_collaborative", FABRIC)


def agent_in(model, state: str, seed: int = 0) -> HumanAgent:
    agent = HumanAgent(model, HumanAgentConfig(seed=seed), reaction=FABRIC.reaction)
    agent.state = model.states.index(state)
    agent.belief = np.eye(model.n_states)[agent.state]
    return agent


def test_the_agent_reacts_to_the_robots_grasp_and_point(beginner):
    idle = beginner.actions.index("idle")
    agent = agent_in(beginner, "Evaluating")
    assert agent.act(idle) == "Evaluating"
    step = agent.react("grasp")
    assert (step.state, step.rule, step.robot_action) == ("RobotInterfered", "robot_grasped",
                                                          "grasp")
    assert agent.state_name == "RobotInterfered" and agent.step == 1
    agent.act(beginner.actions.index("lookAround"))
    assert agent.react("point").state == "Evaluating"


def test_a_typed_state_wins_over_the_rules(beginner):
    agent = agent_in(beginner, "Evaluating")
    agent.act(beginner.actions.index("idle"))
    step = agent.react("grasp", manual_state=beginner.states.index("Tired"))
    assert (step.state, step.rule, step.manual) == ("Tired", "manual", True)
    assert agent.belief[beginner.states.index("Tired")] == pytest.approx(0.8)


def test_model_draws_follow_the_folded_row_and_never_give_a_forbidden_state(beginner):
    idle = beginner.actions.index("idle")
    seen = {}
    for seed in range(400):
        agent = agent_in(beginner, "Evaluating", seed)
        agent.act(idle)
        state = agent.react("idle").state
        seen[state] = seen.get(state, 0) + 1
    # Evaluating's idle row: 0.64 stay, 0.09 GlobalFail, 0.1 RobotInterfered, 0.06 warning,
    # 0.05 tired, 0.01 floors. Floors fold into "stay"; GlobalFail and RobotInterfered are
    # drawn again: stay 0.70 / 0.81, tired 0.05 / 0.81, warning 0.06 / 0.81.
    assert set(seen) == {"Evaluating", "Tired", "WarningTheRobot"}
    assert 0.80 < seen["Evaluating"] / 400 < 0.92


def test_a_grasps_outcome_is_drawn_before_the_robot_acts_and_kept(beginner):
    grasp = beginner.actions.index("graspAttempt")
    outcomes = set()
    for seed in range(60):
        agent = agent_in(beginner, "Evaluating", seed)
        shown = agent.act(grasp)
        assert shown not in ("GlobalFail", "TaskRobot", "RobotInterfered")
        assert agent.react("idle").state == shown
        outcomes.add(shown)
    assert "GlobalSuccess" in outcomes and len(outcomes) > 1


def test_the_seeds_human_does_not_react():
    seed_model = load_human_model("humanModel")
    agent = HumanAgent(seed_model, HumanAgentConfig(seed=0))
    assert not agent.reacts
    with pytest.raises(ValueError):
        agent.act(0)


# -- observation noise: a seeded run counts it ----------------------------------------------------

def noise_counts(bits: int, draws: int = 40000):
    rng = generator(7, 1, "observation")
    counts = {}
    for _ in range(draws):
        seen, what = noisy_bits(bits, rng)
        counts[(seen, what)] = counts.get((seen, what), 0) + 1
    return counts


def within(count: int, draws: int, p: float) -> bool:
    """``count`` of ``draws`` is within 5 standard deviations of p (a fixed seed: exact
    anyway; the margin only says the rate is the authors')."""
    sd = (draws * p * (1 - p)) ** 0.5
    return abs(count - draws * p) <= 5 * sd


def test_a_shown_grasp_is_mixed_up_or_missed_one_time_in_forty_each():
    shown = VISIBLE | IN_RANGE | GRASP_ATTEMPT                                 # 7
    counts = noise_counts(shown)
    mixed = counts[(VISIBLE | IN_RANGE | WARNING, "grasp and warning mixed up")]
    missed = counts[(VISIBLE | IN_RANGE | IDLE, "grasp or warning missed: seen as idle")]
    assert within(mixed, 40000, 1 / 40) and within(missed, 40000, 1 / 40)
    assert counts[(shown, "")] == 40000 - mixed - missed


def test_a_warning_reads_as_a_grasp_as_often():
    counts = noise_counts(VISIBLE | IN_RANGE | WARNING)
    assert within(counts[(VISIBLE | IN_RANGE | GRASP_ATTEMPT, "grasp and warning mixed up")],
                  40000, 1 / 40)


def test_looking_around_and_idling_are_mixed_up_one_time_in_twenty():
    for bits in (IN_RANGE, VISIBLE | IN_RANGE | IDLE):                         # 2, 35
        counts = noise_counts(bits)
        flipped = counts[(bits ^ (VISIBLE | IDLE), "looking around and idling mixed up")]
        assert within(flipped, 40000, 1 / 20)
        assert counts[(bits, "")] == 40000 - flipped


def test_an_attentive_human_who_does_nothing_else_is_never_misread():
    assert noise_counts(VISIBLE | IN_RANGE, 5000) == {(VISIBLE | IN_RANGE, ""): 5000}


def test_noise_draws_two_numbers_whatever_the_bits():
    a, b = generator(1, 2, "observation"), generator(1, 2, "observation")
    noisy_bits(VISIBLE | IN_RANGE, a)
    noisy_bits(GRASP_ATTEMPT, b)
    assert a.random() == b.random()


# -- the authors' observation table --------------------------------------------------------------

def test_every_named_pattern_is_its_observation():
    table = {"O0": (0, 1), "O2": (2,), "O3": (3,), "O6": (6,), "O7": (7,),
             "O8": (8, 9, 10, 11, 14, 15), "O16": (16, 18, 19, 27), "O32": (32,),
             "O34": (34,), "O35": (35,), "O40": (40, 42, 43),
             "O64": (64, 66, 67, 70, 71, 80, 82, 83, 86, 87, 96, 98, 99, 103)}
    for name, patterns in table.items():
        for bits in patterns:
            assert FabricObservationMap()(bits) == (bits, name)
    assert FABRIC.observations.names == tuple(table)


def test_an_unnamed_pattern_is_failure_success_or_the_previous_one():
    m = FabricObservationMap()
    assert m(FAILURE | WARNING | VISIBLE) == (64, "O64")                       # 81: failure
    assert m(SUCCESS | WARNING) == (8, "O8")                                   # 24: success
    assert m(VISIBLE | IN_RANGE | IDLE) == (35, "O35")
    assert m(GRASP_ATTEMPT) == (35, "O35")             # 4 is no observable: the previous one
    fresh = FabricObservationMap()
    assert fresh(GRASP_ATTEMPT) == (0, "O0")           # at the start: observable 0


def test_an_observable_without_an_observation_is_the_previous_observation():
    m = FabricObservationMap()
    assert m(IN_RANGE)[1] == "O2"
    assert m(IN_RANGE | GRASP_ATTEMPT | SUCCESS | IDLE) == (46, "O2")
    # At an episode's start the authors have none: the nearest pattern's.
    assert FabricObservationMap()(46) == (46, "O8")


def test_the_snapshot_bits_say_who_holds_the_object_and_whether_it_left_the_belt():
    seen = Snapshot({"is_ov": True, "is_oir": True, "is_a2": True}, holder="robot")
    assert fabric.snapshot_bits(seen) == VISIBLE | IN_RANGE | IDLE | SUCCESS
    gone = Snapshot({"is_oir": True}, left_belt=True)
    assert fabric.snapshot_bits(gone) == IN_RANGE | FAILURE


# -- the robot's true state -------------------------------------------------------------------

def labels(states, **traits):
    tracker = FabricStateTracker(**traits)
    return [tracker.update(s) for s in states]


def test_the_fixed_labels():
    assert labels(["TaskHuman", "Recovery", "WarningTheRobot", "RobotIsWarned", "GlobalSuccess",
                   "GlobalFail", "TaskRobot"]) == [
        "TaskHuman", "NeedsHelp", "WarningReceived", "NoNeedHelp", "GlobalSuccess",
        "GlobalFail", "TaskRobot"]


def test_a_human_who_keeps_evaluating_after_failing_may_not_be_capable():
    assert labels(["Evaluating", "Evaluating", "FailedToGrasp", "Evaluating"],
                  trusts_robot=True) == ["TaskHuman", "TaskHuman", "NeedsHelp",
                                         "MayNotBeCapable"]
    assert labels(["FailedToGrasp", "FailedToGrasp"], trusts_robot=False) == [
        "MayNotBeCapable", "NoNeedHelp"]
    assert labels(["NoAttention", "Evaluating", "Evaluating", "Evaluating"]) == [
        "NoFocus", "TaskHuman", "TaskHuman", "NoFocus"]


def test_inattention_tiredness_and_mood():
    assert labels(["NoAttention", "NoAttention"]) == ["NoFocus", "NeedsToBeReminded"]
    assert labels(["NoAttention", "Evaluating"], tired=True) == ["MayBeTired", "MayBeTired"]
    assert labels(["Tired", "Tired"], trusts_robot=False) == ["MayBeTired", "NoNeedHelp"]
    assert labels(["Tired", "Tired"], trusts_robot=True) == ["MayBeTired", "NeedsHelp"]
    # TaskHuman starts the counts again; RobotInterfered keeps the label it had.
    assert labels(["NoAttention", "TaskHuman", "NoAttention", "RobotInterfered"]) == [
        "NoFocus", "TaskHuman", "NoFocus", "NoFocus"]


def test_a_tired_type_is_known_by_its_name():
    assert fabric.new_tracker("models/fabric/human/expert_tired_collaborative.pomdpx").tired
    assert not fabric.new_tracker("beginner_nontired_collaborative").tired
    assert not fabric.new_tracker("distracted_collaborative").tired


def test_trust_is_drawn_per_episode_two_times_in_three():
    tracker = FabricStateTracker()
    trusting = 0
    for episode in range(3000):
        tracker.begin_episode(generator(0, episode, "observation"))
        trusting += tracker.trusts_robot
    assert within(trusting, 3000, 2 / 3)


# -- the task as a whole ----------------------------------------------------------------------

def test_fabrics_models_fit_it_and_the_seeds_do_not():
    for name in ("base", "policy1", "policy3", "policy6", "policy9"):
        assert load_robot_model(name, FABRIC).observations == list(FABRIC.observations.names)
    with pytest.raises(Exception, match="it is a model of task seed"):
        load_robot_model(str(__import__("ros_hrc").model_files.MODELS_DIR / "robot" /
                             "robot.pomdp"), FABRIC)


def test_the_robots_fifth_action_is_the_worlds_grasp_planning():
    assert FABRIC.robot_action_services == {"idle": None, "grasp": "grasp",
                                            "cancel": "cancel_action", "point": "point_to_obj",
                                            "graspPlanning": "grasp_planning"}
    assert FABRIC.human_service_for("graspAttempt", "GlobalSuccess") == "grasp"
    assert FABRIC.human_service_for("graspAttempt", "FailedToGrasp") == "attempt_grasp"


# -- its world (issue #30: success that can separate policies) ---------------------------------

def test_fabrics_world_facts_are_the_authors_figures():
    """docs/tasks_fabric_facts.md, "The task's world": TaskManager.cpp's timer, pr2.py's
    planning and grasp; the seed's world has none of them."""
    assert FABRIC.world_facts == {"object_start_x": 0.0, "belt_start": 45.0, "belt_run": 7.0,
                                  "end_tray": True, "robot_plan_time": 4.0,
                                  "robot_delivery_time": 4.2,
                                  "async_actions": ("robot/grasp",)}
    assert getattr(tasks.get("seed"), "world_facts", {}) == {}


@pytest.fixture(scope="module")
def fabric_world():
    from ros_hrc.world import World
    from ros_hrc.world.config import task_world_config
    with World(task_world_config(FABRIC.world_facts, seed=2)) as world:
        yield world


def test_the_product_waits_between_them_45_s_then_reaches_the_tray_7_s_later(fabric_world):
    world = fabric_world
    world.reset()
    assert world.query("is_oir").value and world.robot.can_reach()   # in reach of both
    world.advance(44.5)
    state = world.state()["object"]
    assert state["position"][0] == pytest.approx(0.0, abs=1e-3) and not state["left_belt"]
    assert world.query("is_oir").value and world.robot.can_reach()
    world.advance(7.0)   # 51.5 s: running out
    assert not world.state()["object"]["left_belt"]
    assert not world.query("is_oir").value   # out of the human's reach already
    world.advance(1.0)   # 52.5 s
    assert world.state()["object"]["left_belt"]
    bits = fabric.snapshot_bits(Snapshot(world.state()["predicates"], left_belt=True))
    assert bits & FAILURE and not bits & SUCCESS
    late = world.run("robot", "grasp")
    assert not late.success and "left the belt" in late.message


def test_the_robot_succeeds_only_once_the_product_lies_in_its_tray(fabric_world):
    world = fabric_world
    world.reset()
    start = world.sim_time
    grasped = world.run("robot", "grasp")   # answered as it starts, as the authors' robot is
    assert grasped.success and grasped.duration == 0.0 and "under way" in grasped.message
    world.finish_motions()                  # unplanned: 4 s of planning first
    assert world.sim_time - start == pytest.approx(4.0 + 3.0, abs=0.05)

    def seen():
        state = world.state()
        return fabric.snapshot_bits(Snapshot(state["predicates"],
                                             holder=state["object"]["holder"],
                                             left_belt=state["object"]["left_belt"]))

    assert not seen() & SUCCESS   # carried to the tray: not taken yet
    world.advance(4.2 - 0.8 - 0.1)   # the grasp's lift was the way's first 0.8 s
    assert not seen() & SUCCESS
    world.advance(0.2)
    assert seen() & SUCCESS and world.state()["object"]["holder"] == "robot"
