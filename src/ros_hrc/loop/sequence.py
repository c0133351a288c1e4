"""A sequence of tasks in the loop (Sans-I/O; ``CoordinatorConfig.tasks`` N > 0;
docs/sequences.md): which task a reset starts and who plays it, what each task measures, and
its end.

Each task is an episode, played by the human the schedule names (``CoordinatorConfig.schedule``;
the ``human_model`` every task without one); its reset tells the planner the task's number and
true type and the MDP its human model (and drift). A task ends as an episode does, or when
``task_timeout`` simulated seconds have passed since its start; then its
:class:`~ros_hrc.tasks.utility.TaskOutcome` is measured (the human's warnings, the robot's
pre-emption: it took the object while the human's true state, as the robot decided, was not
one that needs help), the robot process is asked for its part (:class:`EndTask`, answered
with its selector's report), the task is published (:class:`PublishTask`) and the loop resets
into the next task by itself, whatever ``on_episode_end`` says. After the N-th task the
sequence is over; a reset then starts a new sequence from its first task (the robot process
makes a fresh selector). A task cut short (a failed step, a reset asked for) is played again,
under the same number.
"""
from __future__ import annotations

from typing import Any, Dict, Optional, Tuple

from ros_hrc.loop.config import CoordinatorConfig
from ros_hrc.command_line import counted
from ros_hrc.loop.effects import (EndTask, Fault, PublishTask, StepReport, TaskAnswer,
                                  TaskStatusReport)
from ros_hrc.loop.outbox import Outbox
from ros_hrc.tasks.schedule import TaskPlay, type_name
from ros_hrc.tasks.utility import TaskOutcome, sim_span, task_utility

#: What a task's status takes from the robot process's answer to its end, under the same names.
ROBOT_PART = ("selector", "policy", "robot_model", "type_names", "type_belief", "signature",
              "total_disc_reward", "learnt_name", "learnt_value", "learnt_spread")


class TaskSequence:
    """The tasks of a sequence: the one under way (``task_index``, who plays it: ``play``),
    how many ended (``tasks_done``), what the task under way counted so far, and its end
    until the robot process answered it."""

    def __init__(self, config: CoordinatorConfig, outbox: Outbox) -> None:
        self.config = config
        self.outbox = outbox
        self.tasks_done = 0             # tasks of the sequence that ended
        self.sequences_started = 1      # sequences begun since the start (a reset after a
                                        # sequence's last task begins the next)
        self.task_index = 0             # the task under way (0: none yet)
        self.play: Optional[TaskPlay] = None   # who plays it
        self.warnings = 0
        #: Grasps and points while a warning was in force in this task (Task.warning_in_force).
        self.against_warning = 0
        self._warning_in_force = False
        self.preempted = False
        self._ending: Optional[Tuple[int, TaskStatusReport]] = None   # (call id, report)

    @property
    def played(self) -> bool:
        """The sequence's last task ended."""
        return self.tasks_done >= self.config.tasks

    def reset_begins(self) -> None:
        """A reset begins: after the sequence's last task it starts a new sequence, from its
        first task (the robot process makes a fresh selector for a first task). One stack can
        so play many sequences: an experiment's cell plays all of its own on one launch."""
        if self.config.tasks and self.played:
            self.tasks_done = 0
            self.sequences_started += 1

    def begin_task(self) -> bool:
        """The reset under way starts the next task of the sequence (a task cut short: the
        same one again), and who plays it (``play``); whether its human is of another type
        than the last task's (his labeller of the robot's true state is then another)."""
        self.task_index = self.tasks_done + 1
        schedule = self.config.schedule
        play = schedule.play(self.task_index) if schedule is not None else \
            TaskPlay(self.config.human_model)
        changed = self.play is None or play.nearest_type != self.play.nearest_type
        self.play = play
        return changed

    def task_started(self) -> str:
        """The task's episode started: nothing is counted yet; what the reset's line adds."""
        self.warnings, self.preempted = 0, False
        self.against_warning, self._warning_in_force = 0, False
        return f", task {self.task_index}/{self.config.tasks} ({self.play.true_type})"

    def mdp_fields(self) -> Dict[str, Any]:
        """What the MDP's reset says of the task: its number and who plays it."""
        play = self.play
        return dict(task_index=self.task_index, true_type=play.true_type,
                    human_model=play.human_model, drift_to=play.drift_to, drift=play.drift)

    def count_step(self, report: StepReport, decided_on: str) -> None:
        """Count what the step ``report`` did towards the task's outcome (``decided_on``: the
        robot's true state when it decided)."""
        task = self.config.task
        if report.human_action == task.human_warning_action:
            self.warnings += 1
        self._warning_in_force = task.warning_in_force(self._warning_in_force,
                                                       int(report.observation_bits))
        if self._warning_in_force and report.robot_action in task.helping_actions:
            self.against_warning += 1
        if report.object_holder == "robot" and decided_on not in task.needs_help_states:
            self.preempted = True   # it took the object from a human who needed no help

    def end_task(self, report: StepReport, reason: str, start_time: float) -> None:
        """Task ``task_index`` ended at the step ``report`` (``reason``: the loop's end
        reason; ``start_time``: its episode's): its outcome measured, the robot process asked
        for its part (:class:`EndTask`)."""
        holder = report.object_holder if report.object_holder in ("human", "robot") else ""
        if reason in ("success", "human_goal"):
            outcome, who = "success", holder or "human"
        elif reason == "object_left_belt":
            outcome, who = "fail", ""
        else:   # task_timeout, step_limit
            outcome, who = "timeout", ""
        duration = sim_span(start_time, report.sim_time)
        measured = TaskOutcome(outcome, who, self.warnings, int(self.preempted), duration,
                               self.config.task_timeout)
        utility = task_utility(measured)
        self.tasks_done += 1
        status = TaskStatusReport(
            task_index=self.task_index, tasks=self.config.tasks, episode=report.episode,
            epoch=report.epoch, human_model=type_name(self.play.human_model),
            true_type=self.play.true_type, outcome=outcome, who_succeeded=who,
            warnings=measured.warnings, preemptions=measured.preemptions,
            against_warning=self.against_warning,
            steps=report.step + 1, duration=duration, utility=utility, end_reason=reason)
        call = self.outbox.call(EndTask, report.epoch, None, task_index=self.task_index,
                                outcome=measured, steps=status.steps, utility=utility)
        self._ending = (call.id, status)

    def task_reported(self, call: EndTask, result: Any) -> Optional[TaskStatusReport]:
        """The robot process answered a task's end (``result``: its :class:`TaskAnswer`, or
        what came instead): the task is published; its status (None: not the end awaited)."""
        pending, self._ending = self._ending, None
        if pending is None or pending[0] != call.id:
            return None
        status = pending[1]
        if isinstance(result, TaskAnswer):
            for name in ROBOT_PART:
                setattr(status, name, getattr(result, name))
            if status.type_belief:
                best = max(range(len(status.type_belief)), key=status.type_belief.__getitem__)
                status.estimation_correct = status.type_names[best] == self.play.nearest_type
        else:
            why = result.message if isinstance(result, Fault) else repr(result)
            status.robot_problem = f"the robot process sent no task report: {why}"
            self.outbox.note("warn", f"task {status.task_index}: {status.robot_problem}")
        self.outbox.emit(PublishTask(status))
        return status


def sequence_over_line(tasks: int, goes_on: bool = False) -> str:
    """What the terminal says once the sequence's last task ended: and what comes next, a new
    sequence at once (``goes_on``: ``on_episode_end:=reset``) or on Enter."""
    over = (f"the sequence is over: its {counted(tasks, 'task')} are played (/hrc/task_status "
            "has one message each)")
    if goes_on:
        return f"{over}; the next sequence starts now, with a fresh selector (on_episode_end:=reset)"
    return (f"{over}; Enter (or `rosservice call /hrc/reset`) starts a new sequence with a "
            "fresh selector, Ctrl-C ends the launch")
