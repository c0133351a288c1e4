"""The human and robot models, loaded and checked against the task's tables (no ROS).

The task is the one the loop runs (:mod:`ros_hrc.tasks`; the seed's when none is given):
every function takes it as ``task``. A model of another task is refused in one line that
says which task it fits (``...; it is a model of task seed (task:=seed)``).

A model that does not fit the task would run and misbehave: a robot model whose observations
are not ``O<bits>`` of :data:`task.LEGAL_BITS` refuses the observer's every observation, and
the episode never ends. So every entry point loads models through here, and a mismatch is
refused before the first step, in one line naming the file and the offending names::

    models/robot/x.pomdp: observations O36 are not the task's observations (missing: O35)

Human models: states exactly the task's human states in that order (manual mode types state
numbers), actions the task's human actions (any order), fully observable.
Robot models: the task's robot states, actions and observations (names in any order); for the
seed's task, observations ``O<bits>`` for :data:`task.LEGAL_BITS`.

Names by position: a list of names (states, actions or observations, each judged on its own)
that is exactly the generic ``s0 s1 ...``, ``a0 ...`` or ``o0 ...`` (what POMDPX ``<NumValues>``
and Cassandra counts produce, as the seed's robot ``pomdp_FINAL.pomdpx`` does) *and* has the
task's size for that list is read as the task's names in the task's order: ``s0`` is ``S0``,
``a1`` is ``rPoint_obj``, ``o4`` is ``O7`` (:data:`task.LEGAL_BITS` order), and for a human
model ``s1`` is ``success``, ``a0`` is ``graspAttempt`` (a fully observable model's
observations, being its states, follow them). The loaded model then carries the task's names
(the tables are the file's, untouched), ``model.meta["positional_names"]`` records the pairs,
and :func:`positional_mapping_line` gives the one line every entry point prints at start-up::

    models/robot/x.pomdpx: names by position: states s0=S0 s1=S1 ...; actions a0=rIdle ...

Generic names in another size are refused (``states s0..s5 are positional but the task has 7
states: S0, ...``); any other names must match the task's as above.

A file that cannot be parsed raises the parsers' ModelFormatError (it names file:line); a
model that is not there raises :class:`ModelNotFound`, naming the scenario and what exists.
"""
from __future__ import annotations

from pathlib import Path
import dataclasses
from typing import Dict, Iterable, List, Optional, Sequence, Tuple

from ros_hrc import tasks
from ros_hrc.errors import ModelError
from ros_hrc.tasks import seed as task
from ros_hrc.model_files import resolve_model, shown_path
from ros_hrc.pomdp.fileformat import default_names
from ros_hrc.pomdp.io import load_model
from ros_hrc.pomdp.typed import TypeLayout
from ros_hrc.pomdp.model import Model
from ros_hrc.tasks.definition import Task

__all__ = ["ModelNotFound", "load_human_model", "load_robot_model", "check_human_model",
           "check_robot_model", "model_path", "ROBOT_OBSERVATIONS", "POSITIONAL_PREFIXES",
           "task_names", "name_by_position", "positional_mapping_lines",
           "positional_mapping_line", "shown_path"]

#: The seed task's robot observation names the observer sends (O0 ... O35).
ROBOT_OBSERVATIONS = tuple(task.observation_name(b) for b in task.LEGAL_BITS)


#: The generic name prefix of each list, as POMDPX ``<NumValues>`` names its values.
POSITIONAL_PREFIXES: Dict[str, str] = {"states": "s", "actions": "a", "observations": "o"}


def _task(which: "Task | str | None") -> Task:
    return tasks.get(tasks.DEFAULT_TASK if which is None else which)


def task_names(kind: str, task: "Task | str | None" = None) -> Dict[str, Tuple[str, ...]]:
    """The task's names, in the task's order, of each list a ``kind`` ("human" or "robot")
    model must name: states and actions (and observations for the robot)."""
    return _task(task).names(kind)


def _whose(which: Task) -> str:
    """How a refusal names the task's lists: "the task's" for the default task, else
    "task <name>'s"."""
    return "the task's" if which.name == tasks.DEFAULT_TASK else f"task {which.name}'s"


class ModelNotFound(ModelError):
    """No model file for this scenario name or path."""


def model_path(name_or_path: str, kind: str, task: "Task | str | None" = None) -> Path:
    """The file of a scenario name (in the task's folder of that kind: the seed's
    ``models/<kind>/<name>.pomdpx``, then ``.pomdp``) or path; ModelNotFound names the
    scenario and what exists."""
    folder = _task(task).model_dirs.get(kind)
    try:
        return resolve_model(str(name_or_path), kind, folder)
    except FileNotFoundError as exc:
        raise ModelNotFound(str(exc)) from None


def _load(name_or_path: str, kind: str, task: "Task | str | None" = None) -> Model:
    path = model_path(name_or_path, kind, task)
    try:
        return load_model(str(path))
    except OSError as exc:
        raise ModelError(f"{shown_path(path)}: cannot read the file ({exc.strerror or exc})") from None


def load_human_model(name_or_path: str, task: "Task | str | None" = None) -> Model:
    """A human MDP by scenario name or path, checked against the task's tables (generic
    names of the task's sizes are renamed by position, see :func:`name_by_position`)."""
    return _load_checked(name_or_path, "human", _task(task))


def load_robot_model(name_or_path: str, task: "Task | str | None" = None) -> Model:
    """The robot POMDP by name or path, checked against the task's tables (generic names of
    the task's sizes are renamed by position, see :func:`name_by_position`)."""
    return _load_checked(name_or_path, "robot", _task(task))


_CHECKS = {"human": lambda *a, **k: check_human_model(*a, **k),
           "robot": lambda *a, **k: check_robot_model(*a, **k)}


def _load_checked(name_or_path: str, kind: str, which: Task) -> Model:
    raw = _load(name_or_path, kind, which)
    try:
        model = name_by_position(raw, kind, task=which)
        _CHECKS[kind](model, model.source, task=which)
        return model
    except ModelError as exc:
        fits = _other_task_it_fits(raw, kind, which)
        if fits is None:
            raise
        raise ModelError(f"{exc}; it is a model of task {fits} (task:={fits})") from None


def _other_task_it_fits(model: Model, kind: str, which: Task) -> Optional[str]:
    """The name of another task whose tables ``model`` fits, or None."""
    for name in tasks.TASK_NAMES:
        if name == which.name:
            continue
        try:
            other = tasks.get(name)
            _CHECKS[kind](name_by_position(model, kind, task=other), model.source, task=other)
        except (ModelError, ValueError):
            continue
        return name
    return None


def _span(names: Sequence[str]) -> str:
    """``s0..s6`` for a run of generic names (``s0`` for one)."""
    return names[0] if len(names) == 1 else f"{names[0]}..{names[-1]}"


def _is_positional(names: Sequence[str], prefix: str) -> bool:
    return bool(names) and list(names) == default_names(prefix, len(names))


def name_by_position(model: Model, kind: str, path: Optional[str] = None,
                     task: "Task | str | None" = None) -> Model:
    """``model`` with each list of generic names (``s0..``, ``a0..``, ``o0..``) of the task's
    size renamed to the task's names by position: a shallow copy (the same tables) whose
    ``meta["positional_names"]`` maps each renamed list to its ``(generic, task)`` pairs, e.g.
    ``{"states": [("s0", "S0"), ...]}``. ``model`` itself when no list is generic.

    ModelError (one line naming ``path``) when a list is generic in another size than the
    task's. Other names are left alone: :func:`check_human_model` / :func:`check_robot_model`
    judge them. ``kind`` is "human" or "robot"."""
    where = shown_path(path or model.source or model.name or f"{kind} model")
    renamed: Dict[str, List[Tuple[str, str]]] = {}
    changes: Dict[str, List[str]] = {}
    for label, expected in task_names(kind, task).items():
        names = list(getattr(model, label))
        if not _is_positional(names, POSITIONAL_PREFIXES[label]):
            continue
        if len(names) != len(expected):
            raise ModelError(f"{where}: {label} {_span(names)} are positional but the task has "
                             f"{len(expected)} {label}: {_names(expected)}")
        renamed[label] = list(zip(names, expected))
        changes[label] = list(expected)
    if not renamed:
        return model
    if model.fully_observable and "states" in changes \
            and list(model.observations) == list(model.states):
        changes["observations"] = list(changes["states"])   # an MDP observes its states
    meta = dict(model.meta or {})
    meta["positional_names"] = renamed
    return dataclasses.replace(model, meta=meta, **changes)


def positional_mapping_lines(model: Model) -> List[str]:
    """One line per list ``model`` had renamed by position, e.g. ``states s0=S0 s1=S1 ...``;
    [] when none was."""
    pairs = (model.meta or {}).get("positional_names") or {}
    return [f"{label} " + " ".join(f"{old}={new}" for old, new in pairs[label])
            for label in POSITIONAL_PREFIXES if pairs.get(label)]


def positional_mapping_line(model: Model, path: Optional[str] = None) -> Optional[str]:
    """The one start-up line of a model renamed by position, naming the file and every pair::

        models/robot/x.pomdpx: names by position: states s0=S0 ...; actions a0=rIdle ...

    None when its names were the task's own."""
    lines = positional_mapping_lines(model)
    if not lines:
        return None
    where = shown_path(path or model.source or model.name or "model")
    return f"{where}: names by position: " + "; ".join(lines)


def _names(names: Iterable[str]) -> str:
    return ", ".join(names) or "none"


def _same_names(path: str, label: str, got: Sequence[str], expected: Sequence[str],
                whose: str = "the task's") -> None:
    """ModelError unless ``got`` holds exactly the names of ``expected`` (any order, once)."""
    extra = [n for n in got if n not in expected]
    missing = [n for n in expected if n not in got]
    twice = sorted({n for n in got if list(got).count(n) > 1})
    if extra:
        tail = f"missing: {_names(missing)}" if missing else f"{whose}: {_names(expected)}"
        raise ModelError(f"{path}: {label} {_names(extra)} are not {whose} {label} ({tail})")
    if missing:
        raise ModelError(f"{path}: {label} lack {whose} {_names(missing)}")
    if twice:
        raise ModelError(f"{path}: {label} {_names(twice)} appear more than once")


def check_human_model(model: Model, path: Optional[str] = None,
                      task: "Task | str | None" = None) -> None:
    """ModelError (one line naming ``path`` and the names) unless the human MDP fits the task:
    its states are the task's in the task's order, its actions the task's, fully observable."""
    which = _task(task)
    whose = _whose(which)
    where = shown_path(path or model.source or model.name or "human model")
    states = list(model.states)
    _same_names(where, "states", states, which.human_states, whose)
    if tuple(states) != which.human_states:
        raise ModelError(f"{where}: states are in the order {_names(states)}; {whose} order "
                         f"is {_names(which.human_states)} (manual mode types state numbers)")
    _same_names(where, "actions", list(model.actions), which.human_actions, whose)
    if not model.fully_observable:
        raise ModelError(f"{where}: a human model must be fully observable "
                         "(POMDPX: fullyObs=\"true\")")


def check_robot_model(model: Model, path: Optional[str] = None,
                      task: "Task | str | None" = None) -> None:
    """ModelError (one line naming ``path`` and the names) unless the robot POMDP fits the
    task: its states, actions and observations are the task's (the seed's: S0..S6, its four
    actions, observations O<bits> of the legal bits). A model of human types
    (:mod:`ros_hrc.pomdp.typed`: states ``<state>__<type>``, every type over the task's states)
    fits when each type's states are the task's."""
    which = _task(task)
    whose = _whose(which)
    where = shown_path(path or model.source or model.name or "robot model")
    layout = TypeLayout.of(model)
    for label, expected in which.names("robot").items():
        names = list(getattr(model, label))
        if label == "states" and layout is not None:
            names = list(layout.states)
        _same_names(where, label, names, expected, whose)
