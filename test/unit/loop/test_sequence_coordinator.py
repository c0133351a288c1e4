"""A sequence of tasks in the episode coordinator (tasks:=N; docs/sequences.md), driven by hand
with the loop's fake interfaces: each end (success, failure, timeout) gives its outcome and
utility, the task's status carries the coordinator's and the robot's fields, the reset between
tasks tells the MDP the next task's human and the robot the task's number, and after the last
task the loop waits."""
import pytest

from ros_hrc import tasks
from ros_hrc.loop.coordinator import CoordinatorConfig
from ros_hrc.loop.effects import (Decision, EndTask, Fault, MdpReset, MdpStepDone, Note,
                                  PublishTask, ResetDone, ResetPlanner, ResetWorld, TaskAnswer)
from ros_hrc.model_files import model_names
from ros_hrc.streams import EpisodeSchedule
from ros_hrc.tasks.schedule import parse_schedule
from loop_fakes import Driver, calls, of, one, snap

SEED = tasks.get("seed")
START = 1.5     # the episode-start snapshot's sim time (Driver.finish_reset)
REPORT = TaskAnswer(selector="bpr", policy="policy3", robot_model="/m/policy3.pomdp",
                    type_names=("tired", "expert"), type_belief=(0.7, 0.3),
                    signature=(3, 19), total_disc_reward=4.5)


def sequence(count=3, schedule="tired,expert*2", **more):
    config = CoordinatorConfig(tasks=count, human_model="humanModel", schedule=parse_schedule(
        schedule, model_names(SEED.model_dirs["human"]), "humanModel"), **more)
    d = Driver(config)
    first = d.ready()
    return d, first


def end_task(d, outcome, action="lookAround", state="evaluating", decision="rPoint_obj"):
    """Play one step whose outcome snapshot is ``outcome``: the EndTask it ends with."""
    played = d.play_step(action=action, state=state, outcome=outcome,
                         decision=Decision(decision))
    return played, one(played.effects, EndTask)


def test_each_task_starts_with_its_number_and_human_for_robot_and_mdp():
    d, first = sequence()
    assert (first.task_index, first.human_model, first.true_type) == (1, "tired", "tired")
    planner = one(d.log, ResetPlanner)
    assert (planner.task_index, planner.true_type) == (1, "tired")
    _, end = end_task(d, snap("is_ho", holder="human", sim_time=START + 4.0))
    after = d.answer(end, REPORT)
    planner = one(after, ResetPlanner)
    assert (planner.task_index, planner.true_type) == (2, "expert")
    out = d.finish_reset(after)
    second = one(out, MdpReset)
    assert (second.task_index, second.human_model, second.episode) == (2, "expert", 2)
    assert "task 2/3 (expert)" in one(out, Note, level="info").text


def test_a_success_is_the_human_or_the_robot_taking_the_object():
    d, _ = sequence()
    played, end = end_task(d, snap("is_ho", holder="human", sim_time=START + 4.0))
    assert played.done.episode_over and played.done.end_reason == "success"
    assert end.task_index == 1 and end.steps == 1
    assert (end.outcome.outcome, end.outcome.who_succeeded) == ("success", "human")
    assert end.outcome.duration == pytest.approx(4.0) and end.outcome.timeout == 80.0
    assert end.utility == pytest.approx(1.0 - 0.5 * 4.0 / 80.0)
    status = one(d.answer(end, REPORT), PublishTask).report
    assert (status.task_index, status.tasks, status.episode) == (1, 3, 1)
    assert (status.human_model, status.true_type, status.outcome) == ("tired", "tired",
                                                                       "success")
    assert (status.who_succeeded, status.steps, status.end_reason) == ("human", 1, "success")
    assert status.utility == pytest.approx(end.utility)
    # the robot's part, as its report says
    assert (status.selector, status.policy, status.robot_model) == ("bpr", "policy3",
                                                                    "/m/policy3.pomdp")
    assert status.type_names == ("tired", "expert") and status.type_belief == (0.7, 0.3)
    assert status.estimation_correct and status.signature == (3, 19)
    assert status.total_disc_reward == 4.5 and not status.robot_problem


def test_a_human_given_as_a_file_is_named_by_its_stem_in_the_task_status():
    # The MDP is told the file (it loads it); the task's status names the model as
    # msg/TaskStatus.msg says, by its file's stem, as FABRIC's human_model names a model.
    path = str(SEED.model_dirs["human"] / "tired.pomdpx")
    d = Driver(CoordinatorConfig(tasks=2, human_model=path, schedule=parse_schedule(
        "", model_names(SEED.model_dirs["human"]), path)))
    first = d.ready()
    assert first.human_model == path
    _, end = end_task(d, snap("is_ho", holder="human", sim_time=START + 4.0))
    status = one(d.answer(end, REPORT), PublishTask).report
    assert (status.human_model, status.true_type) == ("tired", "tired")


def test_a_failure_is_the_object_leaving_the_belt():
    d, _ = sequence()
    _, end = end_task(d, snap(left_belt=True, sim_time=START + 69.0))
    assert (end.outcome.outcome, end.outcome.who_succeeded) == ("fail", "")
    assert end.utility == pytest.approx(-0.5 * 69.0 / 80.0)
    assert one(d.answer(end, REPORT), PublishTask).report.end_reason == "object_left_belt"


def test_a_task_times_out_after_task_timeout_simulated_seconds_or_the_step_limit():
    d, _ = sequence(task_timeout=20.0)
    played = d.play_step(outcome=snap("is_ov", sim_time=START + 19.9))
    assert not of(played.effects, EndTask) and not played.done.episode_over
    _, end = end_task(d, snap("is_ov", sim_time=START + 20.0))
    assert end.outcome.outcome == "timeout" and end.steps == 2
    assert end.utility == pytest.approx(-0.5)
    assert one(d.answer(end, REPORT), PublishTask).report.end_reason == "task_timeout"

    d, _ = sequence(max_steps=1)
    _, end = end_task(d, snap("is_ov", sim_time=START + 3.0))
    assert end.outcome.outcome == "timeout"
    assert one(d.answer(end, REPORT), PublishTask).report.end_reason == "step_limit"


def test_warnings_and_a_preemption_are_counted_in_the_task():
    d, _ = sequence()
    d.play_step(action="warnRobot", state="warningTheRobot", decision=Decision("rIdle"))
    # the robot grasps while the human, evaluating for the first time, needs no help (S0)
    _, end = end_task(d, snap("is_ov", holder="robot", sim_time=START + 9.0),
                      decision="rGrasp_obj")
    assert (end.outcome.warnings, end.outcome.preemptions) == (1, 1)
    assert end.outcome.who_succeeded == "robot"
    assert end.utility == pytest.approx(1.0 - 0.5 * 9.0 / 80.0 - 0.1 - 0.5)
    # the next task counts afresh
    d.finish_reset(d.answer(end, REPORT))
    _, end = end_task(d, snap("is_ho", holder="human", sim_time=START + 2.0))
    assert (end.outcome.warnings, end.outcome.preemptions) == (0, 0)


def test_grasps_and_points_while_a_warning_is_in_force_are_counted_in_the_task():
    """From the observation that carries the warning until the human acts on the object
    again (episode.against_warning's rule, Task.warning_in_force): a point then counts, an
    idle does not; after the human's grasp attempt a point counts no more; a new task
    starts with no warning in force."""
    d, _ = sequence()
    d.play_step(action="warnRobot", state="warningTheRobot", observe=snap("is_ov", "is_h4"),
                decision=Decision("rPoint_obj"))                       # against: 1
    d.play_step(observe=snap("is_ov"), decision=Decision("rIdle"))      # idle: not counted
    d.play_step(observe=snap("is_ov"), decision=Decision("rPoint_obj"))  # still in force: 2
    d.play_step(action="graspAttempt", state="evaluating", observe=snap("is_ov", "is_a0"),
                decision=Decision("rPoint_obj"))                       # lifted: not counted
    _, end = end_task(d, snap("is_ho", holder="human", sim_time=START + 9.0))
    after = d.answer(end, REPORT)
    assert one(after, PublishTask).report.against_warning == 2
    d.finish_reset(after)
    _, end = end_task(d, snap("is_ho", holder="human", sim_time=START + 2.0))
    assert one(d.answer(end, REPORT), PublishTask).report.against_warning == 0


def test_a_robot_that_takes_the_object_from_a_human_who_needs_help_preempts_nothing():
    d, _ = sequence()
    for _ in range(3):   # evaluating four steps in a row, never having grasped: S3
        d.play_step(decision=Decision("rIdle"))
    _, end = end_task(d, snap("is_ov", holder="robot", sim_time=START + 9.0),
                      decision="rGrasp_obj")
    assert end.outcome.preemptions == 0


def test_after_the_last_task_the_sequence_is_over_and_a_reset_starts_a_new_one():
    d, _ = sequence(count=2)
    _, end = end_task(d, snap(holder="human", sim_time=START + 1.0))
    d.finish_reset(d.answer(end, REPORT))
    _, end = end_task(d, snap(holder="human", sim_time=START + 1.0))
    out = d.answer(end, REPORT)
    assert one(out, PublishTask).report.task_index == 2
    assert not calls(out)    # on_episode_end:=wait (the default): it waits
    assert ("the sequence is over: its 2 tasks are played (/hrc/task_status has one message "
            "each); Enter") in one(out, Note).text
    assert d.c.tasks_done == 2
    # Enter: a new sequence, from its first task, with the schedule's first human again.
    out = d.reset(reason="Enter pressed")
    planner = one(out, ResetPlanner)
    assert (planner.task_index, planner.true_type) == (1, "tired")
    first = one(d.finish_reset(out), MdpReset)
    assert (first.task_index, first.human_model) == (1, "tired")
    assert (d.c.tasks_done, d.c.sequences_started) == (0, 2)


def test_with_on_episode_end_reset_the_sequences_follow_one_another_until_the_episodes_asked_for():
    d, _ = sequence(count=2, on_episode_end="reset", episodes=EpisodeSchedule.parse("0-3"))
    seen = []
    for _ in range(2):
        for index in (1, 2):
            _, end = end_task(d, snap(holder="human", sim_time=START + 1.0))
            out = d.answer(end, REPORT)
            status = one(out, PublishTask).report
            seen.append((status.episode, status.task_index))
            if of(out, ResetPlanner):
                d.finish_reset(out)
    assert seen == [(0, 1), (1, 2), (2, 1), (3, 2)]
    assert "the episodes asked for" not in one(out, Note).text
    assert not of(out, ResetPlanner)      # episodes 0-3 are played: no third sequence
    assert one(d.reset(), ResetDone).success is False


def test_a_task_cut_short_is_played_again_under_its_number():
    d, _ = sequence()
    d.play_step()
    out = d.finish_reset(d.reset())
    again = one(out, MdpReset)
    assert (again.task_index, again.human_model) == (1, "tired")
    assert one(d.log[-len(out) - 4:], ResetPlanner).task_index == 1


def test_an_older_robot_process_without_a_report_still_gets_its_task_published_and_the_next():
    d, _ = sequence()
    _, end = end_task(d, snap(holder="human", sim_time=START + 1.0))
    out = d.answer(end, Fault("the POMDP process refused: unknown message type task_end"))
    status = one(out, PublishTask).report
    assert status.outcome == "success" and status.policy == "" and not status.estimation_correct
    assert "sent no task report" in status.robot_problem
    assert one(out, ResetPlanner).task_index == 2


def test_a_drifting_human_is_reset_with_both_models_and_the_weight():
    d, first = sequence(count=3, schedule="expert>tired*3")
    assert (first.human_model, first.drift_to, first.drift) == ("expert", "tired", 0.0)
    _, end = end_task(d, snap(holder="human", sim_time=START + 1.0))
    second = one(d.finish_reset(d.answer(end, REPORT)), MdpReset)
    assert (second.drift, second.true_type) == (0.5, "expert>tired@0.50")


def test_without_a_sequence_resets_carry_no_task_and_episodes_end_as_before():
    d = Driver(CoordinatorConfig())
    first = d.ready()
    assert (first.task_index, first.human_model) == (0, "")
    assert one(d.log, ResetPlanner).task_index == 0
    played = d.play_step(outcome=snap(holder="human", sim_time=500.0))
    assert not of(played.effects, EndTask) and played.done.end_reason == "success"
