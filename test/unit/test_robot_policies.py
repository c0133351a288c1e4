"""The baseline robots: the reactive robot's rules, the no-robot baseline, both keeping the
exact belief, and despot_pomdp choosing them from its command line."""
import dataclasses

import numpy as np
import pytest

from ros_hrc.tasks import seed as task
from ros_hrc.model_files import resolve_model
from ros_hrc.pomdp import belief as belief_mod
from ros_hrc.pomdp.io import load_model
from ros_hrc.processes.despot_pomdp import RobotAgent, build_parser, build_planner
from ros_hrc.agents.robots import (NoRobotConfig, NoRobotPlanner, ReactiveConfig,
                                    ReactivePlanner)

# Observations by what they show (bit sums of ros_hrc.tasks.seed).
NOTHING_WRONG = task.VISIBLE | task.IN_RANGE | task.IDLE              # O35
WARNING = task.WARNING | task.VISIBLE | task.IN_RANGE                 # O19
HAS_OBJECT = task.HAS_OBJECT | task.IN_RANGE | task.VISIBLE           # O11
FAILED_GRASP = task.GRASP_ATTEMPT | task.IN_RANGE | task.VISIBLE      # O7
NOT_DETECTED = 0                                                      # O0
NOT_DETECTED_IDLE = task.IDLE                                         # O32
NOT_ATTENDING = task.IN_RANGE                                         # O2


@pytest.fixture(scope="module")
def model():
    return load_model(str(resolve_model("robot", "robot")))


def obs(model, bits):
    return model.index("observation", task.observation_name(bits))


def act(model, name):
    return model.index("action", name)


def observe(planner, model, *bits_seq):
    """Feed observations as the process does (previous action, then the observation) and
    return the last decision's action name."""
    action = act(model, "rIdle")
    for bits in bits_seq:
        planner.update(action, obs(model, bits))
        action = planner.act()
    return model.actions[action]


@pytest.mark.parametrize("bits, expected, rule", [
    (WARNING, "rStop_all", "warning"),
    (task.WARNING, "rStop_all", "warning"),                  # O16: warning beats "not detected"
    (HAS_OBJECT, "rIdle", "has_object"),
    (task.HAS_OBJECT | task.IN_RANGE, "rIdle", "has_object"),  # O10: beats "not attending"
    (FAILED_GRASP, "rGrasp_obj", "failed_grasp"),
    (NOT_DETECTED, "rGrasp_obj", "not_detected"),
    (NOT_DETECTED_IDLE, "rGrasp_obj", "not_detected"),
    (NOT_ATTENDING, "rGrasp_obj", "not_attending"),
    (task.IN_RANGE | task.IDLE, "rGrasp_obj", "not_attending"),
    (NOTHING_WRONG, "rIdle", "nothing"),
    (task.VISIBLE, "rIdle", "nothing"),
    (task.VISIBLE | task.IN_RANGE, "rIdle", "nothing"),
])
def test_reactive_rule_for_one_observation(model, bits, expected, rule):
    planner = ReactivePlanner(model, ReactiveConfig(budget=8))
    assert observe(planner, model, bits) == expected
    assert planner.last_rule == rule


def test_reactive_idles_before_any_observation(model):
    planner = ReactivePlanner(model)
    assert model.actions[planner.act()] == "rIdle"
    assert planner.last_rule == "start"


def test_reactive_never_helps_while_the_warning_holds(model):
    planner = ReactivePlanner(model, ReactiveConfig(budget=2))
    # Past the budget, the warning still wins on every step it holds.
    assert observe(planner, model, *[WARNING] * 5) == "rStop_all"
    assert observe(planner, model, task.WARNING | task.IN_RANGE) == "rStop_all"
    assert observe(planner, model, NOTHING_WRONG) == "rGrasp_obj"   # warning gone, budget spent
    assert planner.last_rule == "budget"


def test_reactive_helps_once_the_budget_passes(model):
    planner = ReactivePlanner(model, ReactiveConfig(budget=3))
    assert observe(planner, model, NOTHING_WRONG) == "rIdle"
    assert observe(planner, model, NOTHING_WRONG) == "rIdle"
    assert observe(planner, model, NOTHING_WRONG) == "rGrasp_obj"
    assert planner.last_rule == "budget" and planner.steps == 3
    assert observe(planner, model, NOTHING_WRONG) == "rGrasp_obj"


def test_default_budget_is_eight_steps(model):
    planner = ReactivePlanner(model)
    assert observe(planner, model, *[NOTHING_WRONG] * 7) == "rIdle"
    assert observe(planner, model, NOTHING_WRONG) == "rGrasp_obj"


def test_budget_zero_switches_the_budget_rule_off(model):
    planner = ReactivePlanner(model, ReactiveConfig(budget=0))
    assert observe(planner, model, *[NOTHING_WRONG] * 50) == "rIdle"


def test_budget_does_not_fire_after_the_human_had_the_object(model):
    planner = ReactivePlanner(model, ReactiveConfig(budget=2))
    assert observe(planner, model, HAS_OBJECT, NOTHING_WRONG, NOTHING_WRONG) == "rIdle"
    assert planner.human_succeeded and planner.last_rule == "nothing"


def test_reset_restarts_the_step_count(model):
    planner = ReactivePlanner(model, ReactiveConfig(budget=3))
    assert observe(planner, model, HAS_OBJECT, NOTHING_WRONG, NOTHING_WRONG) == "rIdle"
    planner.reset()
    assert planner.steps == 0 and not planner.human_succeeded
    assert model.actions[planner.act()] == "rIdle"            # no observation yet
    assert observe(planner, model, NOTHING_WRONG, NOTHING_WRONG) == "rIdle"
    assert observe(planner, model, NOTHING_WRONG) == "rGrasp_obj"
    planner.reset()
    assert observe(planner, model, NOTHING_WRONG) == "rIdle"


def test_help_action_is_configurable(model):
    planner = ReactivePlanner(model, ReactiveConfig(help_action="rPoint_obj"))
    assert observe(planner, model, FAILED_GRASP) == "rPoint_obj"


@pytest.mark.parametrize("budget", [-1, 2.5, "8", True])
def test_a_bad_budget_is_refused(budget):
    with pytest.raises(ValueError, match="budget"):
        ReactiveConfig(budget=budget)


@pytest.mark.parametrize("make", [lambda m: ReactivePlanner(m, ReactiveConfig(budget=2)),
                                  lambda m: NoRobotPlanner(m)], ids=["reactive", "none"])
def test_the_exact_belief_is_kept(model, make):
    planner = make(model)
    b = np.array(model.initial_belief, dtype=float)
    assert np.allclose(planner.belief, b)
    action = act(model, "rIdle")
    # A run the model allows under either robot's actions (no zero-probability fallback).
    for bits in (NOTHING_WRONG, FAILED_GRASP, HAS_OBJECT, HAS_OBJECT):
        o = obs(model, bits)
        planner.update(action, o)
        expected, _ = belief_mod.update(model, b, action, o)
        assert np.allclose(planner.belief, expected)
        assert planner.belief.sum() == pytest.approx(1.0)
        assert not planner.last_update_zero_probability
        b = expected
        action = planner.act()
    planner.reset()
    assert np.allclose(planner.belief, model.initial_belief)


def test_the_belief_follows_a_warning(model):
    # Only S6 ("the human warned the robot") emits warnings, and the model reaches S6 only
    # by fetching for a human who may need help: idle, failed grasp (-> rGrasp_obj), warning.
    planner = ReactivePlanner(model)
    assert observe(planner, model, NOTHING_WRONG, FAILED_GRASP, WARNING) == "rStop_all"
    assert not planner.last_update_zero_probability
    assert planner.belief[model.index("state", "S6")] == pytest.approx(1.0)
    help_mass = sum(planner.belief[model.index("state", s)] for s in task.NEEDS_HELP_STATES)
    assert help_mass == pytest.approx(0.0)


def test_no_robot_always_idles(model):
    planner = NoRobotPlanner(model, NoRobotConfig())
    assert model.actions[planner.act()] == "rIdle"
    for bits in (WARNING, FAILED_GRASP, NOT_DETECTED, NOT_ATTENDING, HAS_OBJECT,
                 *[NOTHING_WRONG] * 20):
        assert observe(planner, model, bits) == "rIdle"


def parse(*argv):
    return build_parser().parse_args(list(argv))


def test_build_planner_picks_the_baselines_from_argv(model):
    reactive = build_planner(model, parse("--planner", "reactive", "--reactive-budget", "3"))
    assert isinstance(reactive, ReactivePlanner) and reactive.config.budget == 3
    default = build_planner(model, parse("--planner", "reactive"))
    assert isinstance(default, ReactivePlanner) and default.config.budget == 8
    assert isinstance(build_planner(model, parse("--planner", "none")), NoRobotPlanner)


def test_unknown_planner_is_refused_by_the_parser():
    with pytest.raises(SystemExit):
        parse("--planner", "bogus")


def test_the_process_agent_runs_the_reactive_robot(model):
    agent = RobotAgent(model, build_planner(model, parse("--planner", "reactive",
                                                         "--reactive-budget", "2")))
    assert model.actions[agent.step("O35")[0]] == "rIdle"
    assert model.actions[agent.step("O35")[0]] == "rGrasp_obj"   # budget of 2 spent
    agent.reset()
    assert model.actions[agent.step("O35")[0]] == "rIdle"
    assert model.actions[agent.step("O7")[0]] == "rGrasp_obj"
    assert model.actions[agent.step("O19")[0]] == "rStop_all"


def without_action(model, name):
    return dataclasses.replace(model, actions=[a if a != name else "rHalt"
                                               for a in model.actions])


def test_a_model_without_rStop_all_is_refused_by_name(model):
    broken = without_action(model, "rStop_all")
    with pytest.raises(ValueError, match="rStop_all"):
        ReactivePlanner(broken)
    with pytest.raises(ValueError, match="rStop_all"):
        build_planner(broken, parse("--planner", "reactive"))
    NoRobotPlanner(broken)   # the no-robot baseline needs only rIdle


def test_a_model_without_rIdle_is_refused_by_both(model):
    broken = without_action(model, "rIdle")
    for make in (ReactivePlanner, NoRobotPlanner):
        with pytest.raises(ValueError, match="rIdle"):
            make(broken)


def test_a_model_without_a_needed_observation_is_refused_by_name(model):
    names = [o if o != "O7" else "Ograsp" for o in model.observations]
    broken = dataclasses.replace(model, observations=names)
    with pytest.raises(ValueError, match="needs observation.*O7"):
        ReactivePlanner(broken)


def test_the_exploring_robot_tries_every_action_the_same_way_for_a_seed(model):
    from ros_hrc.agents.robots import ExplorePlanner

    def actions(seed):
        planner = ExplorePlanner(model, seed=seed)
        planner.reset()
        return [planner.act() for _ in range(400)]

    run = actions(7)
    assert run == actions(7) and run != actions(8)
    counts = np.bincount(run, minlength=model.n_actions)
    assert counts.min() > 400 / model.n_actions * 0.7      # uniform: about 100 each
