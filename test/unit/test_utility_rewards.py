"""The robot model priced by the task's utility (tasks.utility.utility_rewards, issue #40):
summed along a task's true states, its rewards are the task's utility, times the scale."""
import pytest

from ros_hrc import tasks
from ros_hrc.tasks.utility import (AGAINST_WARNING_COST, UTILITY_REWARD_SCALE, TaskOutcome,
                                   task_utility, utility_rewards)

SEED = tasks.get("seed")
STEP = 2.5     # simulated seconds a step


def priced(path):
    """The summed rewards of a path [(state, action), ..., final state], in utility units."""
    R = utility_rewards(SEED, STEP)
    states, actions = list(SEED.robot_states), list(SEED.robot_actions)
    total = 0.0
    for (s, a), (s2, _) in zip(path, path[1:] + [(None, None)]):
        if s2 is None:
            break
        total += R[actions.index(a)][states.index(s)][states.index(s2)]
    return total / UTILITY_REWARD_SCALE


def utility(steps, warnings=0, preemptions=0):
    return task_utility(TaskOutcome("success", "human", warnings, preemptions, steps * STEP,
                                    SEED.task_timeout))


@pytest.mark.parametrize("path, steps, warnings, preemptions", [
    # the human fails once, then succeeds alone
    ([("S0", "rIdle"), ("S2", "rIdle"), ("S1", "rIdle")], 2, 0, 0),
    # the robot takes the object from a human who needed no help: a pre-emption
    ([("S0", "rGrasp_obj"), ("S1", "rIdle")], 1, 0, 1),
    # the robot takes it from one who needs help: no pre-emption
    ([("S0", "rIdle"), ("S3", "rGrasp_obj"), ("S1", "rIdle")], 2, 0, 0),
    # a warning, obeyed, then the human succeeds
    ([("S0", "rIdle"), ("S6", "rStop_all"), ("S1", "rIdle")], 2, 1, 0),
])
def test_a_tasks_rewards_sum_to_its_utility(path, steps, warnings, preemptions):
    assert priced(path) == pytest.approx(utility(steps, warnings, preemptions))


def test_acting_against_a_warning_costs_more_than_any_success():
    obeyed = priced([("S0", "rIdle"), ("S6", "rIdle"), ("S1", "rIdle")])
    against = priced([("S0", "rIdle"), ("S6", "rGrasp_obj"), ("S1", "rIdle")])
    assert obeyed - against == pytest.approx(AGAINST_WARNING_COST + 0.5)  # and a pre-emption
    assert AGAINST_WARNING_COST > 1.0


def test_a_success_is_worth_nothing_once_the_object_is_held():
    R = utility_rewards(SEED, STEP)
    s1 = SEED.robot_states.index("S1")
    assert all(R[a][s1][s1] == 0.0 for a in range(len(SEED.robot_actions))
               if SEED.robot_actions[a] in ("rIdle", "rStop_all"))


def test_a_step_time_that_is_not_positive_is_refused():
    with pytest.raises(ValueError, match="step_seconds must be > 0"):
        utility_rewards(SEED, 0.0)
