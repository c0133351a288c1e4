"""Which human plays which task of a sequence (``schedule:=``; docs/sequences.md).

A schedule is a list of **blocks**: K tasks played by one human type, whose model may drift
linearly to a second type over the block (its T rows mixed with weight k/(K-1) at the
block's k-th task, k from 0). Task k of a sequence (from 1) is played as
:meth:`Schedule.play` says: the human model, the model it drifts to, the weight, and the
label of the true type (``TYPE``, or ``TYPE>TYPE2@0.40`` while drifting). When the sequence
(``tasks:=N``) is longer than the schedule, the schedule repeats.

Its forms (:func:`parse_schedule`):

* empty: the launch's ``human_model`` for every task;
* inline: ``TYPE*K,TYPE2*K2,...`` (``TYPE`` alone is one task; ``TYPE>TYPE2*K`` drifts);
* ``fabric``: FABRIC's own test schedule, its ten humans in the order of
  ``code/configs/scenario_config_tests.json`` (cangorur/human_robot_collaboration, its
  ``evaluation_models.humans``, with ``interactionNumber`` 30 tasks each; one type,
  beginner_tired_noncollaborative, is played twice and expert_tired_collaborative never);
* a ``.toml`` file: one ``[[block]]`` per block, ``human = "TYPE"``, ``tasks = K`` and
  optionally ``drift_to = "TYPE2"``.

A type is a human model name of the task (its model folder's). Anything else is refused
with one line (:class:`ScheduleError`): the unknown type and the known names, or the file
and line. Pure: no ROS, no models loaded here.
"""
from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence, Tuple

from ros_hrc.errors import did_you_mean

__all__ = ["ScheduleError", "Block", "TaskPlay", "Schedule", "parse_schedule", "nearest_type",
           "MAX_TASKS",
           "FABRIC_SCHEDULE_NAME", "FABRIC_HUMANS", "FABRIC_TASKS_PER_HUMAN"]

#: The word that names FABRIC's own schedule.
FABRIC_SCHEDULE_NAME = "fabric"
#: FABRIC's test humans, in the order of their scenario_config_tests.json
#: (``evaluation_models.humans``).
FABRIC_HUMANS: Tuple[str, ...] = (
    "beginner_tired_noncollaborative", "expert_nontired_noncollaborative",
    "beginner_nontired_noncollaborative", "distracted_collaborative",
    "beginner_tired_collaborative", "distracted_noncollaborative",
    "beginner_tired_noncollaborative", "expert_nontired_collaborative",
    "beginner_nontired_collaborative", "expert_tired_noncollaborative")
#: Their ``interactionNumber``: tasks per human before the switch.
FABRIC_TASKS_PER_HUMAN = 30

#: The most tasks a sequence has, and so a block: ``tasks:=N``'s cap (ros_hrc.settings takes it
#: from here). N is a ROS parameter, an XML-RPC int32, and a task's number travels as uint32
#: (TaskStatus.task_index); a block of more tasks could never be played to its end.
MAX_TASKS = 2**31 - 1

_INLINE_BLOCK = re.compile(r"(?P<human>[^*>\s]+)(?:>(?P<to>[^*>\s]+))?(?:\*(?P<k>[0-9]+))?\Z")


class ScheduleError(ValueError):
    """A schedule that cannot be played: one line saying what and where."""


@dataclass(frozen=True)
class Block:
    """``tasks`` tasks played by ``human`` (drifting to ``drift_to`` when it is given)."""

    human: str
    tasks: int
    drift_to: str = ""


@dataclass(frozen=True)
class TaskPlay:
    """How one task is played: the ``human_model``, and while drifting the model it drifts
    to (``drift_to``) and the weight of that model's rows (``drift``, 0..1)."""

    human_model: str
    drift_to: str = ""
    drift: float = 0.0

    @property
    def true_type(self) -> str:
        """The type's label: ``TYPE``, or ``TYPE>TYPE2@0.40`` while drifting."""
        name = type_name(self.human_model)
        if not self.drift_to:
            return name
        return f"{name}>{type_name(self.drift_to)}@{self.drift:.2f}"

    @property
    def nearest_type(self) -> str:
        """The type it is closest to: the drift's end once its weight is past one half."""
        return nearest_type(self.true_type)


@dataclass(frozen=True)
class Schedule:
    """The blocks of a sequence, played in order and repeated (see the module docstring)."""

    blocks: Tuple[Block, ...]

    @property
    def length(self) -> int:
        """Tasks in one pass of the blocks."""
        return sum(block.tasks for block in self.blocks)

    def play(self, task_index: int) -> TaskPlay:
        """How task ``task_index`` (from 1) is played."""
        if task_index < 1:
            raise ValueError(f"tasks are numbered from 1, not {task_index}")
        k = (task_index - 1) % self.length
        for block in self.blocks:
            if k < block.tasks:
                if not block.drift_to:
                    return TaskPlay(block.human)
                weight = k / (block.tasks - 1) if block.tasks > 1 else 0.0
                return TaskPlay(block.human, block.drift_to, weight)
            k -= block.tasks
        raise AssertionError("unreachable: k < length")

    def text(self) -> str:
        """The inline form of this schedule."""
        return ",".join(f"{b.human}{'>' + b.drift_to if b.drift_to else ''}*{b.tasks}"
                        for b in self.blocks)


def nearest_type(true_type: str) -> str:
    """The type a true type's label (:attr:`TaskPlay.true_type`) is closest to: ``TYPE``
    itself; of ``TYPE>TYPE2@w`` the drift's end once ``w`` is past one half."""
    start, arrow, rest = true_type.partition(">")
    if not arrow:
        return start
    end, _, weight = rest.rpartition("@")
    try:
        return end if float(weight) > 0.5 else start
    except ValueError:
        return start


def type_name(model: str) -> str:
    """A model's type name: a scenario name as it is, a file's stem."""
    return Path(model).stem if ("/" in model or model.endswith((".pomdpx", ".pomdp"))) \
        else model


def _check_type(name: str, known: Sequence[str], where: str) -> str:
    if name not in known:
        hint = did_you_mean(name, known)
        raise ScheduleError(f"{where}unknown human type {name!r}; {hint + ' ' if hint else ''}"
                            f"known: {', '.join(known)}")
    return name


def _inline(text: str, known: Sequence[str]) -> Schedule:
    blocks = []
    for number, part in enumerate(text.split(","), start=1):
        part = part.strip()
        match = _INLINE_BLOCK.match(part)
        if not part or match is None:
            raise ScheduleError(f"block {number} {part!r} is not TYPE, TYPE*K or TYPE>TYPE2*K "
                                "(K a whole number >= 1)")
        k = int(match["k"]) if match["k"] is not None else 1
        if not 1 <= k <= MAX_TASKS:
            shown = part if len(part) <= 60 else f"{part[:40]}... ({len(part)} characters)"
            raise ScheduleError(f"block {number} {shown!r}: K must be a whole number from 1 to "
                                f"{MAX_TASKS} (the most tasks a sequence has, as tasks:=)")
        blocks.append(Block(_check_type(match["human"], known, ""), k,
                            _check_type(match["to"], known, "") if match["to"] else ""))
    return Schedule(tuple(blocks))


def _block_lines(text: str) -> Tuple[int, ...]:
    """The line (from 1) of each ``[[block]]`` header of a TOML text."""
    return tuple(number for number, line in enumerate(text.splitlines(), start=1)
                 if re.match(r"\s*\[\[\s*block\s*\]\]", line))


def _from_file(path: Path, known: Sequence[str]) -> Schedule:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScheduleError(f"{path}: cannot read it ({getattr(exc, 'strerror', None) or exc})"
                            ) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScheduleError(f"{path}: not TOML: {exc}") from None
    unknown = sorted(set(data) - {"block"})
    if unknown:
        raise ScheduleError(f"{path}: unknown key {unknown[0]!r}; a schedule file holds "
                            "[[block]] tables only")
    tables = data.get("block")
    if not isinstance(tables, list) or not tables:
        raise ScheduleError(f"{path}: no [[block]]: each block is a [[block]] table with "
                            "human = \"TYPE\" and tasks = K")
    lines = _block_lines(text)
    blocks = []
    for number, table in enumerate(tables):
        line = lines[number] if number < len(lines) else 0
        where = f"{path}:{line}: " if line else f"{path}: block {number + 1}: "
        extra = sorted(set(table) - {"human", "tasks", "drift_to"})
        if extra:
            raise ScheduleError(f"{where}unknown key {extra[0]!r}; a block has human, tasks "
                                "and drift_to")
        human, tasks, drift = table.get("human"), table.get("tasks"), table.get("drift_to", "")
        if not isinstance(human, str) or not human:
            raise ScheduleError(f"{where}human must be a type name (a string)")
        if isinstance(tasks, bool) or not isinstance(tasks, int) or not 1 <= tasks <= MAX_TASKS:
            raise ScheduleError(f"{where}tasks must be a whole number from 1 to {MAX_TASKS} "
                                f"(the most tasks a sequence has, as tasks:=), not {tasks!r}")
        if not isinstance(drift, str):
            raise ScheduleError(f"{where}drift_to must be a type name (a string)")
        blocks.append(Block(_check_type(human, known, where), tasks,
                            _check_type(drift, known, where) if drift else ""))
    return Schedule(tuple(blocks))


def parse_schedule(text: Optional[str], known: Sequence[str], default_human: str,
                   task: str = "") -> Schedule:
    """The schedule ``text`` names (module docstring); ``known``: the task's human types;
    ``default_human``: the launch's human model (an empty schedule plays it every task);
    ``task``: the task's name, for the refusal of ``fabric`` on another task. Raises
    :class:`ScheduleError` (one line)."""
    text = (text or "").strip()
    if not text:
        return Schedule((Block(default_human, 1),))
    if text == FABRIC_SCHEDULE_NAME:
        missing = [name for name in FABRIC_HUMANS if name not in known]
        if missing:
            raise ScheduleError(f"FABRIC's schedule names human types that task {task or '?'} "
                                f"does not have ({missing[0]} ...): use it with task:=fabric")
        return Schedule(tuple(Block(name, FABRIC_TASKS_PER_HUMAN) for name in FABRIC_HUMANS))
    if text.endswith(".toml") or "/" in text:
        return _from_file(Path(text), known)
    return _inline(text, known)
