"""The learning robot's model of its human (ros_hrc.agents.learning, issue #40): carried and
forgotten across tasks, its refusals, its figure, and with a prior of infinite strength the
pooled robot's decisions."""
from __future__ import annotations

import numpy as np
import pytest

from ros_hrc import settings, tasks
from ros_hrc.agents.learning import LearntHuman
from ros_hrc.models import load_robot_model, model_path
from ros_hrc.pomdp.bayes_adaptive import expected_counts
from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner
from ros_hrc.pomdp.typed import TypeLayout

SEED = tasks.get("seed")


@pytest.fixture(scope="module")
def pooled():
    """The seed task's learning prior: the pooled fit priced by the task's utility."""
    return load_robot_model(str(model_path("robot_utility_fitted", "robot", SEED)), SEED)


def steps_of(model, actions, observations):
    """(action, observation) index pairs as the robot's belief update takes them."""
    return [(model.index("action", a), model.index("observation", o))
            for a, o in zip(actions, observations)]


def failed_then_recovered(model):
    """A human who fails a grasp, then takes the object while the robot idles."""
    return steps_of(model, ["rIdle", "rIdle", "rIdle"], ["O7", "O7", "O11"])


def test_the_counts_are_carried_from_task_to_task_and_forgotten(pooled):
    """After each task: n <- (1 - rate) n + the task's expected counts (under the posterior
    mean as it was when the task ended)."""
    task = failed_then_recovered(pooled)
    for rate in (0.0, 0.5, 1.0):
        learner = LearntHuman(pooled, SEED, strength=10, forgetting=rate, planning="mean",
                              draws=1)
        learner.learn(task)
        first = learner.posterior.transitions.copy()
        assert first.sum() == pytest.approx(len(task))
        second, _ = expected_counts(learner.posterior.mean(), task)
        learner.learn(task)
        assert np.allclose(learner.posterior.transitions, (1 - rate) * first + second)
        assert learner.tasks_learnt == 2
    learner.restart(seed=3)                                        # a new sequence: the prior
    assert learner.posterior.transitions.sum() == 0 and learner.tasks_learnt == 0


@pytest.mark.parametrize("strength, forgetting, draws, says", [
    (0, 0.1, 8, "the prior's strength must be a finite number > 0"),
    (-1, 0.1, 8, "the prior's strength must be a finite number > 0"),
    (float("inf"), 0.1, 8, "the prior's strength must be a finite number > 0"),
    (10, -0.1, 8, "the forgetting rate must be from 0 to 1"),
    (10, 1.5, 8, "the forgetting rate must be from 0 to 1"),
    (10, 0.1, 0, "the number of posterior draws must be a whole number from 1 to 64"),
])
def test_bad_numbers_are_refused_in_one_line(pooled, strength, forgetting, draws, says):
    with pytest.raises(ValueError) as caught:
        LearntHuman(pooled, SEED, strength, forgetting, "sampled", draws)
    assert says in str(caught.value) and "\n" not in str(caught.value)


def test_a_negative_exploration_bonus_is_refused_in_one_line(pooled):
    with pytest.raises(ValueError) as caught:
        LearntHuman(pooled, SEED, 20, 0.1, "sampled", 8, bonus=-0.5)
    assert "the exploration bonus must be a finite number >= 0" in str(caught.value)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize("word, value, says", [
    ("learning_strength", "0", "learning_strength"),
    ("learning_forgetting", "1.5", "learning_forgetting"),
    ("learning_draws", "0", "learning_draws"),
    ("learning_bonus", "-1", "learning_bonus"),
])
def test_the_launch_refuses_bad_learning_settings(word, value, says):
    with pytest.raises(settings.SettingError) as caught:
        settings.resolve({word: value, "tasks": "5", "selector": "pomdp_learning"}, environ={})
    assert says in str(caught.value)


def test_the_learning_robot_needs_despot():
    with pytest.raises(settings.SettingError) as caught:
        settings.resolve({"tasks": "5", "selector": "pomdp_learning", "planner": "reactive"},
                         environ={})
    assert "planner:=despot" in str(caught.value)


def test_the_figure_is_a_probability_that_moves_with_what_the_task_showed(pooled):
    learner = LearntHuman(pooled, SEED, strength=5, forgetting=0.0, planning="mean", draws=1)
    before = learner.figure()
    assert "S2" in before.name and "rIdle" in before.name
    assert 0.0 <= before.value <= 1.0 and before.spread > 0.0
    for _ in range(5):
        learner.learn(failed_then_recovered(pooled))
    after = learner.figure()
    assert after.value > before.value        # it saw a failed grasp recovered from alone
    assert after.spread < before.spread      # and is surer of it


def test_a_fixed_models_figure_is_the_learners_before_it_learnt_anything(pooled):
    """The figure a ceiling's fit is drawn at (figure_of) is the learner's own figure: before
    any task the posterior mean is the prior."""
    learner = LearntHuman(pooled, SEED, strength=5, forgetting=0.0, planning="mean", draws=1)
    assert LearntHuman.figure_of(pooled, SEED) == pytest.approx(learner.figure().value)


def test_a_tasks_end_tells_whether_the_human_left_alone_recovered(pooled):
    """A human fails twice while the robot idles and the task then ends, the robot still
    idle: a success says he recovered alone (the figure rises above what the failures alone
    left it at), a task that ran out says he did not (it falls below)."""
    failed = steps_of(pooled, ["rIdle", "rIdle"], ["O7", "O7"])
    idle = pooled.index("action", "rIdle")
    figures = {}
    for ending in (None, True, False):
        learner = LearntHuman(pooled, SEED, strength=5, forgetting=0.0, planning="mean",
                              draws=1)
        for _ in range(5):
            learner.learn(failed, last_action=idle, succeeded=ending)
        figures[ending] = learner.figure().value
        counted = learner.posterior.transitions.sum()
        assert counted == pytest.approx(5 * (len(failed) + (ending is not None)))
    assert figures[True] > figures[None] > figures[False]


def test_root_sampling_plans_on_draws_of_the_posterior(pooled):
    learner = LearntHuman(pooled, SEED, strength=10, forgetting=0.0, planning="sampled",
                          draws=4, seed=1)
    model = learner.model_for_task()
    layout = TypeLayout.of(model)
    assert layout.types == ("d0", "d1", "d2", "d3")
    assert model.n_states == 4 * pooled.n_states
    assert np.allclose(layout.type_marginal(np.asarray(model.initial_belief)), 0.25)


def test_an_infinitely_strong_prior_decides_as_the_pooled_robot(pooled):
    """With kappa -> inf nothing a task shows moves the model: on a pinned seeded run the
    learning robot (posterior mean, without the exploration bonus, whose purpose is to
    decide otherwise) makes the pooled robot's every decision."""
    learner = LearntHuman(pooled, SEED, strength=1e12, forgetting=0.0, planning="mean",
                          draws=1)
    for _ in range(3):
        learner.learn(failed_then_recovered(pooled))
    learnt = learner.model_for_task()
    config = DespotConfig(scenarios=200, depth=30, time_per_step=float("inf"), max_trials=80)
    ours, theirs = DespotPlanner(learnt, config, seed=7), DespotPlanner(pooled, config, seed=7)
    observations = ["O7", "O7", "O35", "O2", "O7", "O19", "O35", "O11"]
    last = pooled.index("action", "rIdle")
    for name in observations:
        o = pooled.index("observation", name)
        ours.update(last, o)
        theirs.update(last, o)
        mine, pooled_action = ours.act(), theirs.act()
        assert mine == pooled_action
        last = mine


def failed_twice(model):
    """A human who fails a grasp and fails again: the belief is on the failure states."""
    return steps_of(model, ["rIdle", "rIdle"], ["O7", "O35"])


def test_the_look_bonus_moves_only_the_first_step_and_the_search_still_closes(pooled):
    """The exploration bonus is paid at the root only: a bonus of 0 decides as none does, a
    large one makes the robot watch (idle), and with it the search still closes the root's
    bounds before its trial cap (a bonus in the model's rewards never let them meet)."""
    config = DespotConfig(scenarios=200, depth=30, time_per_step=float("inf"), max_trials=300)
    idle = pooled.index("action", "rIdle")

    def decide(per_state):
        planner = DespotPlanner(pooled, config, seed=7)
        for a, o in failed_twice(pooled):
            planner.update(a, o)
        if per_state is not None:
            planner.root_bonus = (idle, per_state)
        return planner.act(), planner.last_stats

    plain, plain_stats = decide(None)
    assert plain != idle                                 # the pooled robot helps here
    zero, zero_stats = decide(np.zeros(pooled.n_states))
    assert zero == plain and zero_stats.action_values == plain_stats.action_values
    watched, stats = decide(np.full(pooled.n_states, 50.0))
    assert watched == idle
    assert stats.trials < config.max_trials
    assert stats.upper - stats.lower <= config.gap_tolerance


def test_the_learning_robot_takes_its_bonus_from_what_it_has_seen(pooled):
    """Each task's bonus starts from the posterior's counts of idling in each state; no bonus
    at 0."""
    assert LearntHuman(pooled, SEED, 20, 0.1, "sampled", 8).look_bonus() is None
    learner = LearntHuman(pooled, SEED, 20, 0.1, "sampled", 8, bonus=10.0)
    fresh = learner.look_bonus()
    assert np.allclose(fresh.per_state(), 10.0)
    learner.learn(failed_then_recovered(pooled))
    seen = learner.look_bonus().per_state()
    assert (seen <= 10.0).all() and seen.sum() < 10.0 * pooled.n_states
