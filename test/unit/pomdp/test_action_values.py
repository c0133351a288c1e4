"""Why a planner chose: the value of each action it compared (PlannerStats.action_values), for
DESPOT (its root's lower bounds), an offline policy (its alpha vectors, or its one-step
lookahead) and the MDP planner; none from a baseline robot. Reported, never used to decide."""
import math

import numpy as np
import pytest

from solver_models import build_tiger
from test_despot import play_tiger_with_a_trial_cap
from ros_hrc.agents.robots import NoRobotConfig, NoRobotPlanner
from ros_hrc.pomdp import offline
from ros_hrc.pomdp.despot import TIE_TOLERANCE, DespotConfig, DespotPlanner
from ros_hrc.pomdp.planner import MdpPlanner, PolicyPlanner
from ros_hrc.pomdp.policy import Policy

LISTEN, OPEN_LEFT, OPEN_RIGHT = 0, 1, 2
HEAR_LEFT = 0

#: Trial-capped, time-generous: the same tree on every machine.
CAPPED = DespotConfig(time_per_step=30.0, max_trials=20)


@pytest.fixture(scope="module")
def tiger_policy():
    return offline.solve(build_tiger(), timeout=30, precision=0.01)


def chose_the_best(action, values):
    """The chosen action's value is the largest, but for DESPOT's tie tolerance."""
    best = max(values.values())
    return values[action] >= best - TIE_TOLERANCE * max(1.0, abs(best))


def test_despot_values_every_action_and_chooses_the_best(tiger):
    planner = DespotPlanner(tiger, CAPPED, seed=1)
    planner.reset()
    action = planner.act()
    values = planner.last_stats.action_values
    assert sorted(values) == [LISTEN, OPEN_LEFT, OPEN_RIGHT]
    assert all(math.isfinite(v) for v in values.values())
    assert action == LISTEN and chose_the_best(action, values)
    # At the uniform belief opening a door is a gamble: listening is worth clearly more.
    assert values[LISTEN] > values[OPEN_LEFT] + 10 and values[LISTEN] > values[OPEN_RIGHT] + 10
    # The value it chose by is the root's lower bound, within the root's bounds.
    assert values[LISTEN] <= planner.last_stats.upper


def test_despot_values_after_hearing_the_tiger_twice_on_the_left(tiger):
    planner = DespotPlanner(tiger, CAPPED, seed=2)
    planner.reset()
    planner.update(LISTEN, HEAR_LEFT)
    planner.update(LISTEN, HEAR_LEFT)
    action = planner.act()
    values = planner.last_stats.action_values
    assert action == OPEN_RIGHT and chose_the_best(action, values)
    assert values[OPEN_RIGHT] > values[LISTEN] > values[OPEN_LEFT]


def test_despot_values_are_the_same_for_the_same_seed_and_trial_cap(tiger):
    first = play_tiger_with_a_trial_cap(tiger, 7)
    assert first == play_tiger_with_a_trial_cap(tiger, 7)
    assert all(chose_the_best(decision[0], decision[-1]) for decision in first)


def test_despot_without_a_trial_values_only_its_default_action(tiger):
    planner = DespotPlanner(tiger, DespotConfig(time_per_step=30.0, max_trials=0), seed=0)
    planner.reset()
    assert planner.act() == LISTEN
    # The default policy's value: listening forever costs 1 a step, -1 / (1 - 0.95).
    assert planner.last_stats.action_values == {LISTEN: pytest.approx(-20.0)}


def test_a_policy_values_each_action_by_its_best_vector_at_the_belief(tiger, tiger_policy):
    planner = PolicyPlanner(tiger, tiger_policy, seed=0)
    for b in ([0.5, 0.5], [0.97, 0.03], [0.03, 0.97]):
        belief = np.array(b)
        planner.reset(belief)
        action = planner.act()
        values = planner.last_stats.action_values
        for a in set(tiger_policy.actions.tolist()):
            mine = tiger_policy.alphas[tiger_policy.actions == a] @ belief
            assert values[a] == pytest.approx(mine.max())
        assert values[action] == max(values.values()) == planner.last_stats.lower


def test_a_policy_with_lookahead_values_every_action(tiger, tiger_policy):
    planner = PolicyPlanner(tiger, tiger_policy, seed=0, lookahead=True)
    planner.reset(np.array([0.97, 0.03]))
    action = planner.act()
    values = planner.last_stats.action_values
    assert action == OPEN_RIGHT and sorted(values) == [LISTEN, OPEN_LEFT, OPEN_RIGHT]
    assert values[action] == max(values.values()) == planner.last_stats.lower
    assert values[OPEN_LEFT] < -50 < values[LISTEN]   # the tiger is behind the left door


def test_an_action_without_a_vector_has_no_value(tiger):
    policy = Policy(alphas=[[1.0, 0.0], [0.0, 2.0], [0.5, 0.5]], actions=[0, 2, 0],
                    state_names=list(tiger.states), action_names=list(tiger.actions),
                    discount=0.95)
    assert policy.action_values(np.array([0.5, 0.5])) == {0: 0.5, 2: 1.0}


def test_the_mdp_planner_values_every_action(chain):
    planner = MdpPlanner(chain)
    planner.reset()
    action = planner.act()
    values = planner.last_stats.action_values
    assert sorted(values) == list(range(chain.n_actions))
    assert values[action] == max(values.values())


def test_a_baseline_robot_carries_no_values(tiger):
    planner = NoRobotPlanner(tiger, NoRobotConfig(idle_action="listen"), seed=0)
    planner.reset()
    planner.act()
    assert planner.last_stats.action_values == {}
