"""Observation bits and the robot's true state, as the observer computes them."""
import dataclasses

import pytest

from ros_hrc.tasks import seed as task


def test_every_legal_pattern_maps_to_itself_and_is_named():
    for bits in task.LEGAL_BITS:
        assert task.legal_bits(bits) == bits
        assert task.observation_name(bits) == f"O{bits}"
    assert len(task.LEGAL_BITS) == 15


def test_every_pattern_maps_to_a_legal_observation():
    for bits in range(64):
        assert task.legal_bits(bits) in task.LEGAL_BITS


def test_holding_the_object_survives_the_mapping():
    # 8 alone (has object, neither visible nor in range) is not legal: keep "has object".
    assert task.legal_bits(task.HAS_OBJECT) & task.HAS_OBJECT
    assert task.legal_bits(task.HAS_OBJECT | task.VISIBLE) == 11


def test_a_warning_while_idle_keeps_the_warning():
    assert task.legal_bits(task.WARNING | task.IDLE | task.VISIBLE) & task.WARNING


def test_grasp_attempt_out_of_range_keeps_the_attempt():
    assert task.legal_bits(task.GRASP_ATTEMPT | task.VISIBLE) == 7


def test_bits_from_predicates_sums_the_true_ones():
    preds = {"is_ov": True, "is_oir": True, "is_a0": False, "is_ho": False,
             "is_h4": False, "is_a2": True}
    assert task.bits_from_predicates(preds) == 35
    assert task.describe_bits(35) == "visible+in_range+idle"


def test_out_of_range_bits_are_refused():
    with pytest.raises(ValueError):
        task.legal_bits(64)
    with pytest.raises(ValueError):
        task.observation_name(5)


def test_robot_state_follows_the_humans_history():
    tracker = task.RobotStateTracker()
    assert tracker.update("task_assigned") == "S0"
    assert tracker.update("evaluating") == "S0"
    assert tracker.update("failed_to_grasp") == "S2"
    assert tracker.update("evaluating") == "S2"
    assert tracker.update("failed_to_grasp") == "S3"
    assert tracker.update("no_attention") == "S4"
    assert tracker.update("no_attention") == "S5"
    assert tracker.update("warningTheRobot") == "S6"
    assert tracker.update("success") == "S1"
    tracker.reset()
    assert tracker.update("evaluating") == "S0"


def test_a_human_who_keeps_evaluating_comes_to_need_help():
    tracker = task.RobotStateTracker()
    labels = [tracker.update("evaluating") for _ in range(6)]
    assert labels == ["S0", "S2", "S2", "S3", "S3", "S3"]
    assert tracker.update("task_assigned") == "S0"
    assert tracker.update("evaluating") == "S0"          # a new streak starts
    tracker.reset()
    tracker.update("failed_to_grasp")
    assert [tracker.update("evaluating") for _ in range(5)] == ["S2"] * 5   # he did grasp


def test_tired_and_recovering_humans_need_help_grasping():
    tracker = task.RobotStateTracker()
    assert tracker.update("tired") == "S3"
    assert tracker.update("recovery") == "S3"


def test_a_successful_grasp_attempt_uses_the_grasp_service():
    assert task.human_service_for("graspAttempt", "success") == "grasp"
    assert task.human_service_for("graspAttempt", "failed_to_grasp") == "attempt_grasp"
    assert task.human_service_for("walkAway", "recovery") == "walk_away"
    with pytest.raises(ValueError):
        task.human_service_for("dance", "success")


def test_a_warning_is_labelled_only_when_the_human_warned():
    # warnRobot shows the warning (bit 16): the robot has been warned.
    tracker = task.RobotStateTracker()
    assert tracker.update("warningTheRobot", "warnRobot") == "S6"
    # A grasp attempt that lands in warningTheRobot shows a failed grasp (O7), not a warning.
    tracker.reset()
    assert tracker.update("warningTheRobot", "graspAttempt") == "S2"
    assert tracker.update("warningTheRobot", "graspAttempt") == "S3"
    assert tracker.update("warningTheRobot", "warnRobot") == "S6"
    # Any other way in keeps the label the human had.
    tracker.reset()
    assert tracker.update("no_attention", "lookAround") == "S4"
    assert tracker.update("warningTheRobot", "lookAround") == "S4"
    assert tracker.update("task_assigned", "idle") == "S0"


@pytest.mark.parametrize("bonus", [-1.0, float("nan"), float("inf")])
def test_a_task_refuses_a_learning_bonus_that_is_not_a_finite_number_at_least_0(bonus):
    with pytest.raises(ValueError, match="learning_bonus must be a finite number >= 0"):
        dataclasses.replace(task.SEED, learning_bonus=bonus)
