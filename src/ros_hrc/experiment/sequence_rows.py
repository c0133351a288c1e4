"""The rows of a sequence study: one per task (``tasks.csv``), one per whole sequence
(``sequences.csv``), and the store that holds them. No ROS, no PyBullet.

A cell of a sequence study is (schedule, selector, seed); its unit is a sequence of tasks
played on one stack, the robot's selector keeping what it learnt from task to task
(docs/sequences.md). Its worker hands each sequence over whole: the sequence's task rows,
then its :class:`SequenceRow`, which commits them (:class:`SequenceStore`, the store of
:mod:`ros_hrc.experiment.store` with these two row types). A sequence cut short by a kill
leaves task rows without their sequence row: they are dropped on open and the sequence runs
again, whole (a selector's learning is the sequence's, so half of one is no result).

A task row is made from one ``/hrc/task_status`` message (``ros_hrc/TaskStatus``, or any
object with its fields: :func:`task_row`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence, Tuple

import numpy as np

from ros_hrc.experiment.episode import TYPES_POLICY
from ros_hrc.experiment.rows import Row
from ros_hrc.experiment.store import ResultsStore

#: The files of a sequence study (beside them, as in an episode study, ``logs/``).
SEQUENCES_FILE = "sequences.csv"
TASKS_FILE = "tasks.csv"

#: A task's outcomes (``ros_hrc.tasks.utility.TaskOutcome.outcome``).
TASK_OUTCOMES: Tuple[str, ...] = ("success", "fail", "timeout")
WHO_SUCCEEDED: Tuple[str, ...] = ("human", "robot", "")

TASK_COLUMNS: Tuple[str, ...] = (
    "schedule", "selector", "seed", "episode", "task_index", "human_model", "true_type",
    "policy", "success", "utility", "outcome", "who_succeeded", "belief_argmax",
    "estimation_correct", "warnings", "preemptions", "steps", "duration", "total_disc_reward",
    "end_reason", "task_episode", "type_names", "type_belief", "signature", "learnt_figure",
    "against_warning")

SEQUENCE_COLUMNS: Tuple[str, ...] = (
    "schedule", "selector", "seed", "episode", "tasks", "successes", "mean_utility", "steps",
    "sim_seconds", "wall_seconds")


def _words(text: str) -> Tuple[str, ...]:
    return tuple(text.split())


@dataclass(frozen=True)
class TaskRow(Row):
    """One task of a sequence, as ``/hrc/task_status`` reported it.

    ``schedule``, ``selector``, ``seed`` and ``episode`` (the sequence's number in its cell,
    from 0) name the sequence; ``task_index`` counts its tasks from 1 and ``task_episode`` is
    the loop's episode number the task ran as (its streams, :func:`task_episode`).
    ``human_model`` is the model that played the task, ``true_type`` the type the schedule
    names (a drifting one says where it is: ``A>B@0.40``). ``policy`` is the library policy
    the selector chose; ``belief_argmax`` the selector's most likely type after the task
    ("" for a selector without a type belief). ``type_names``, ``type_belief`` and
    ``signature`` (the task's signature codes) are space-separated lists in one cell, and so
    is ``learnt_figure``: a learning robot's figure after the task and its spread
    (``/hrc/task_status``'s ``learnt_value``, ``learnt_spread``; empty for any other robot).
    """

    COLUMNS: ClassVar[Tuple[str, ...]] = TASK_COLUMNS

    schedule: str
    selector: str
    seed: int
    episode: int
    task_index: int
    human_model: str
    true_type: str
    policy: str
    success: int
    utility: float
    outcome: str
    who_succeeded: str
    belief_argmax: str
    estimation_correct: int
    warnings: int
    preemptions: int
    steps: int
    duration: float
    total_disc_reward: float
    end_reason: str
    task_episode: int
    type_names: str = ""
    type_belief: str = ""
    signature: str = ""
    learnt_figure: str = ""
    against_warning: int = 0

    @property
    def learnt(self) -> Tuple[float, ...]:
        """A learning robot's figure after the task and its spread (empty: none)."""
        return tuple(float(v) for v in _words(self.learnt_figure))

    @property
    def key(self) -> tuple:
        """(schedule, selector, seed, episode): the sequence this task belongs to."""
        return (self.schedule, self.selector, self.seed, self.episode)

    @property
    def belief(self) -> np.ndarray:
        """The selector's belief over :attr:`types` after the task (empty: none)."""
        return np.array([float(v) for v in _words(self.type_belief)], dtype=float)

    @property
    def types(self) -> Tuple[str, ...]:
        return _words(self.type_names)

    @property
    def signature_codes(self) -> Tuple[int, ...]:
        """The task's per-step signature codes (0..63)."""
        return tuple(int(v) for v in _words(self.signature))

    @property
    def block_type(self) -> str:
        """The type a block of the schedule is about: ``true_type`` without a drift's
        position (``A>B@0.40`` -> ``A>B``)."""
        return self.true_type.split("@", 1)[0]

    def _check(self) -> None:
        self._nonempty("schedule", "selector", "human_model", "true_type", "policy")
        self._non_negative("seed", "episode", "warnings", "preemptions", "steps", "duration",
                           "task_episode")
        if self.task_index < 1:
            raise self._bad("task_index", "must be >= 1")
        self._zero_one("success", "estimation_correct")
        if self.outcome not in TASK_OUTCOMES:
            raise self._bad("outcome", f"expected one of {', '.join(TASK_OUTCOMES)}")
        if bool(self.success) != (self.outcome == "success"):
            raise self._bad("success", f"contradicts outcome {self.outcome!r}")
        if self.who_succeeded not in WHO_SUCCEEDED:
            raise self._bad("who_succeeded", "expected human, robot or nothing")
        if bool(self.success) != bool(self.who_succeeded):
            raise self._bad("who_succeeded", f"contradicts success {self.success}")
        for name in ("utility", "total_disc_reward"):
            if not math.isfinite(getattr(self, name)):
                raise self._bad(name, "must be finite")
        try:
            belief, codes = self.belief, self.signature_codes
        except ValueError:
            raise self._bad("type_belief", "expected numbers separated by spaces") from None
        if len(belief) != len(self.types):
            raise self._bad("type_belief", f"{len(belief)} values for {len(self.types)} types")
        if self.belief_argmax and self.belief_argmax not in self.types:
            raise self._bad("belief_argmax", "is not one of type_names")
        if any(not 0 <= c < 64 for c in codes):
            raise self._bad("signature", "codes must be from 0 to 63")


@dataclass(frozen=True)
class SequenceRow(Row):
    """One whole sequence of a cell: what commits its task rows (:class:`SequenceStore`), and
    its totals (the run's figures and progress bar)."""

    COLUMNS: ClassVar[Tuple[str, ...]] = SEQUENCE_COLUMNS

    schedule: str
    selector: str
    seed: int
    episode: int
    tasks: int
    successes: int
    mean_utility: float
    steps: int
    sim_seconds: float
    wall_seconds: float

    @property
    def key(self) -> tuple:
        """(schedule, selector, seed, episode): the sequence."""
        return (self.schedule, self.selector, self.seed, self.episode)

    def progress_text(self) -> str:
        """What the progress bar says of it."""
        return (f"{self.schedule}/{self.selector} seed {self.seed}: {self.successes}/"
                f"{self.tasks} tasks succeeded, mean utility {self.mean_utility:.2f}")

    def _check(self) -> None:
        self._nonempty("schedule", "selector")
        self._non_negative("seed", "episode", "successes", "steps", "sim_seconds",
                           "wall_seconds")
        if self.tasks < 1 or self.successes > self.tasks:
            raise self._bad("tasks", f"must be >= 1 and >= successes ({self.successes})")


class SequenceStore(ResultsStore):
    """``sequences.csv`` and ``tasks.csv`` in a directory: a sequence's tasks, then its row
    (the commit mark), each fsynced; resumed by whole sequences."""

    ROW_TYPE = SequenceRow
    PART_TYPE = TaskRow
    ROWS_FILE = SEQUENCES_FILE
    PARTS_FILE = TASKS_FILE
    UNIT = "sequences"

    def sequences(self) -> list:
        """Every recorded sequence, in the order they were added."""
        return self.episodes()

    def tasks(self) -> list:
        """Every recorded task, in the order they were added."""
        return self.steps()


def task_episode(sequence: int, task_index: int, length: int) -> int:
    """The loop's episode number of task ``task_index`` (from 1) of sequence ``sequence``
    (from 0) of ``length`` tasks: ``sequence * length + task_index - 1``. Each task of a cell
    has its own number, hence its own random streams (:mod:`ros_hrc.streams`), and the same
    (seed, sequence, task) is the same human stream under every selector: the pairs of the
    paired tests."""
    if not 1 <= task_index <= length:
        raise ValueError(f"task {task_index} of a sequence of {length}")
    return sequence * length + task_index - 1


def sequence_of(episode: int, length: int) -> Tuple[int, int]:
    """(sequence, task_index) of a loop episode number: :func:`task_episode` reversed."""
    return episode // length, episode % length + 1


def belief_argmax(type_names: Sequence[str], belief: Sequence[float]) -> str:
    """The most likely type of a belief (the first of equals); "" without a belief."""
    if not len(type_names) or len(belief) != len(type_names):
        return ""
    return str(type_names[int(np.argmax(np.asarray(belief, dtype=float)))])


#: The study's robot that knows its human, labelled as such: the launch's one robot on a
#: model fitted on that very human (other seeds of it), never a competitor (docs/learning.md).
CEILING = "pomdp_ceiling"
#: The learning robot's prior planned on as it is, never learnt: what learning starts from.
POOLED = "pomdp_pooled"


def launched_selector(selector: str) -> str:
    """The ``selector:=`` a cell's stack runs for the study's selector ``selector``: itself,
    but ``fixed`` for ``pomdp_types``, ``pomdp_ceiling`` and ``pomdp_pooled`` (no library
    policy: the launch's one robot, on the model of human types, on the model fitted on this
    human, or on the learning robot's prior, plays every task)."""
    return "fixed" if selector in (TYPES_POLICY, CEILING, POOLED) else selector


def task_row(status: Any, schedule: str, selector: str, seed: int, sequence: int) -> TaskRow:
    """The row of one ``/hrc/task_status`` message (``ros_hrc/TaskStatus``'s fields) of the
    sequence ``sequence`` of cell (``schedule``, ``selector``, ``seed``). ``selector`` is the
    cell's (the one the status names should be it; a mismatch is the stack's bug: ValueError)."""
    if status.selector and status.selector != launched_selector(selector):
        raise ValueError(f"task {status.task_index}: the stack ran selector "
                         f"{status.selector!r}, the cell asked for {selector!r}")
    names = [str(n) for n in status.type_names]
    belief = [float(v) for v in status.type_belief]
    return TaskRow(
        schedule=schedule, selector=selector, seed=seed, episode=sequence,
        task_index=int(status.task_index), human_model=status.human_model,
        true_type=status.true_type or status.human_model, policy=status.policy,
        success=int(status.outcome == "success"), utility=float(status.utility),
        outcome=status.outcome, who_succeeded=status.who_succeeded,
        belief_argmax=belief_argmax(names, belief),
        estimation_correct=int(bool(status.estimation_correct)),
        warnings=int(status.warnings), preemptions=int(status.preemptions),
        steps=int(status.steps), duration=float(status.duration),
        total_disc_reward=float(status.total_disc_reward), end_reason=status.end_reason,
        task_episode=int(status.episode), type_names=" ".join(names),
        type_belief=" ".join(repr(v) for v in belief),
        signature=" ".join(str(c) for c in signature_codes(status.signature)),
        learnt_figure=(f"{float(status.learnt_value)!r} {float(status.learnt_spread)!r}"
                       if status.learnt_name else ""),
        against_warning=int(status.against_warning))


def signature_codes(signature: Any) -> Tuple[int, ...]:
    """A status's ``signature`` as codes: rospy gives a ``uint8[]`` as ``bytes``, a test a
    list."""
    if isinstance(signature, (bytes, bytearray)):
        return tuple(bytearray(signature))
    return tuple(int(c) for c in signature)


def sequence_row(tasks: Sequence[TaskRow], wall_seconds: float) -> SequenceRow:
    """The row that commits a whole sequence's task rows."""
    if not tasks:
        raise ValueError("a sequence has at least one task")
    first = tasks[0]
    return SequenceRow(
        schedule=first.schedule, selector=first.selector, seed=first.seed,
        episode=first.episode, tasks=len(tasks), successes=sum(t.success for t in tasks),
        mean_utility=float(np.mean([t.utility for t in tasks])),
        steps=sum(t.steps for t in tasks), sim_seconds=sum(t.duration for t in tasks),
        wall_seconds=wall_seconds)
