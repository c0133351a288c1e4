"""The sequence part of the coordinator (loop/sequence.py) alone: which task a reset
starts and who plays it, what a task counts, its end, and the robot's part of its status."""
import pytest

from ros_hrc import tasks
from ros_hrc.loop.config import CoordinatorConfig
from ros_hrc.loop.effects import EndTask, Fault, Note, PublishTask, StepReport, TaskAnswer
from ros_hrc.loop.outbox import Outbox
from ros_hrc.loop.sequence import TaskSequence, sequence_over_line
from ros_hrc.model_files import model_names
from ros_hrc.tasks.schedule import parse_schedule
from loop_fakes import one

SEED = tasks.get("seed")


def sequence(count=2, schedule="tired,expert"):
    outbox = Outbox()
    config = CoordinatorConfig(tasks=count, human_model="humanModel", schedule=parse_schedule(
        schedule, model_names(SEED.model_dirs["human"]), "humanModel"))
    return TaskSequence(config, outbox), outbox


def step(n=0, action="lookAround", robot="rPoint_obj", holder="none", bits=1, sim_time=0.0):
    return StepReport(epoch=9, episode=4, step=n, human_action=action, human_state="evaluating",
                      robot_action=robot, object_holder=holder, observation_bits=bits,
                      sim_time=sim_time)


def test_each_task_is_played_by_the_human_the_schedule_names_and_again_when_cut_short():
    s, _ = sequence()
    assert s.begin_task() and (s.task_index, s.play.true_type) == (1, "tired")
    assert not s.begin_task() and s.task_index == 1       # cut short: the same task again
    assert s.task_started() == ", task 1/2 (tired)"
    assert s.mdp_fields()["human_model"] == "tired"


def test_a_task_counts_warnings_and_a_preemption_and_its_end_asks_the_robot_for_its_part():
    s, outbox = sequence()
    s.begin_task()
    s.task_started()
    s.count_step(step(action="warnRobot"), decided_on="S0")
    s.count_step(step(n=1, holder="robot"), decided_on="S0")   # S0 needs no help
    s.end_task(step(n=1, holder="robot", sim_time=5.0), "success", start_time=1.0)
    end = one(outbox.take(), EndTask)
    assert (end.task_index, end.steps, end.epoch) == (1, 2, 9)
    assert (end.outcome.outcome, end.outcome.who_succeeded) == ("success", "robot")
    assert (end.outcome.warnings, end.outcome.preemptions) == (1, 1)
    assert end.outcome.duration == pytest.approx(4.0)
    assert s.tasks_done == 1 and not s.played


def test_the_robots_answer_fills_the_status_which_is_published():
    s, outbox = sequence()
    s.begin_task()
    s.task_started()
    s.end_task(step(), "object_left_belt", 0.0)
    end = one(outbox.take(), EndTask)
    status = s.task_reported(end, TaskAnswer(selector="bpr", policy="p3",
                                             type_names=("tired", "expert"),
                                             type_belief=(0.8, 0.2)))
    assert status.outcome == "fail" and (status.selector, status.policy) == ("bpr", "p3")
    assert status.estimation_correct
    assert one(outbox.take(), PublishTask).report is status
    assert s.task_reported(end, TaskAnswer(selector="bpr", policy="p3")) is None   # once


def test_a_robot_process_that_sends_no_report_leaves_its_part_empty_and_says_so():
    s, outbox = sequence()
    s.begin_task()
    s.task_started()
    s.end_task(step(), "step_limit", 0.0)
    status = s.task_reported(one(outbox.take(), EndTask), Fault("it left"))
    assert status.outcome == "timeout" and status.robot_problem.endswith("it left")
    assert "task 1: the robot process sent no task report" in one(outbox.take(), Note).text


def test_a_reset_after_the_last_task_starts_a_new_sequence_from_its_first():
    s, outbox = sequence(count=1)
    s.begin_task()
    s.end_task(step(), "success", 0.0)
    assert s.played
    s.reset_begins()
    assert (s.tasks_done, s.sequences_started) == (0, 2)
    s.begin_task()
    assert s.task_index == 1
    assert "with a fresh selector" in sequence_over_line(1)
