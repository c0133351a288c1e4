"""The human and robot models, loaded and checked against the task's tables (no ROS).

A model that does not fit the task would run and misbehave: a robot model whose observations
are not ``O<bits>`` of :data:`task.LEGAL_BITS` refuses the observer's every observation, and
the episode never ends. So every entry point loads models through here, and a mismatch is
refused before the first step, in one line naming the file and the offending names::

    models/robot/x.pomdp: observations O36 are not the task's observations (missing: O35)

Human models: states exactly :data:`task.HUMAN_STATES` in that order (manual mode types state
numbers), actions the keys of :data:`task.HUMAN_ACTION_SERVICES` (any order), fully observable.
Robot models: states :data:`task.ROBOT_STATES`, actions the keys of
:data:`task.ROBOT_ACTION_SERVICES`, observations ``O<bits>`` for :data:`task.LEGAL_BITS` (names
in any order).

A file that cannot be parsed raises the parsers' ModelFormatError (it names file:line); a
model that is not there raises :class:`ModelNotFound`, naming the scenario and what exists.
"""
from __future__ import annotations

from pathlib import Path
from typing import Iterable, Optional, Sequence

from ros_hrc.errors import ModelError
from ros_hrc.loop import task
from ros_hrc.model_files import MODELS_DIR, resolve_model
from ros_hrc.pomdp.io import load_model
from ros_hrc.pomdp.model import Model

__all__ = ["ModelNotFound", "load_human_model", "load_robot_model", "check_human_model",
           "check_robot_model", "model_path", "ROBOT_OBSERVATIONS"]

#: The robot model's observation names the observer sends (O0 ... O35).
ROBOT_OBSERVATIONS = tuple(task.observation_name(b) for b in task.LEGAL_BITS)


class ModelNotFound(ModelError):
    """No model file for this scenario name or path."""


def model_path(name_or_path: str, kind: str) -> Path:
    """The file of a scenario name (``models/<kind>/<name>.pomdpx``, then ``.pomdp``) or path;
    ModelNotFound names the scenario and what exists."""
    try:
        return resolve_model(str(name_or_path), kind)
    except FileNotFoundError as exc:
        raise ModelNotFound(str(exc)) from None


def _shown(path) -> str:
    """The file as the messages show it: relative to the package for its own models."""
    path = Path(str(path))
    try:
        return str(path.resolve().relative_to(MODELS_DIR.parent))
    except ValueError:
        return str(path)


def _load(name_or_path: str, kind: str) -> Model:
    path = model_path(name_or_path, kind)
    try:
        return load_model(str(path))
    except OSError as exc:
        raise ModelError(f"{_shown(path)}: cannot read the file ({exc.strerror or exc})") from None


def load_human_model(name_or_path: str) -> Model:
    """A human MDP by scenario name or path, checked against the task's tables."""
    model = _load(name_or_path, "human")
    check_human_model(model, model.source)
    return model


def load_robot_model(name_or_path: str) -> Model:
    """The robot POMDP by name or path, checked against the task's tables."""
    model = _load(name_or_path, "robot")
    check_robot_model(model, model.source)
    return model


def _names(names: Iterable[str]) -> str:
    return ", ".join(names) or "none"


def _same_names(path: str, label: str, got: Sequence[str], expected: Sequence[str]) -> None:
    """ModelError unless ``got`` holds exactly the names of ``expected`` (any order, once)."""
    extra = [n for n in got if n not in expected]
    missing = [n for n in expected if n not in got]
    twice = sorted({n for n in got if list(got).count(n) > 1})
    if extra:
        tail = f"missing: {_names(missing)}" if missing else f"the task's: {_names(expected)}"
        raise ModelError(f"{path}: {label} {_names(extra)} are not the task's {label} ({tail})")
    if missing:
        raise ModelError(f"{path}: {label} lack the task's {_names(missing)}")
    if twice:
        raise ModelError(f"{path}: {label} {_names(twice)} appear more than once")


def check_human_model(model: Model, path: Optional[str] = None) -> None:
    """ModelError (one line naming ``path`` and the names) unless the human MDP fits the task:
    its states are the task's in the task's order, its actions the task's, fully observable."""
    where = _shown(path or model.source or model.name or "human model")
    states = list(model.states)
    _same_names(where, "states", states, task.HUMAN_STATES)
    if tuple(states) != task.HUMAN_STATES:
        raise ModelError(f"{where}: states are in the order {_names(states)}; the task's order "
                         f"is {_names(task.HUMAN_STATES)} (manual mode types state numbers)")
    _same_names(where, "actions", list(model.actions), tuple(task.HUMAN_ACTION_SERVICES))
    if not model.fully_observable:
        raise ModelError(f"{where}: a human model must be fully observable "
                         "(POMDPX: fullyObs=\"true\")")


def check_robot_model(model: Model, path: Optional[str] = None) -> None:
    """ModelError (one line naming ``path`` and the names) unless the robot POMDP fits the
    task: states S0..S6, the task's robot actions, observations O<bits> of the legal bits."""
    where = _shown(path or model.source or model.name or "robot model")
    _same_names(where, "states", list(model.states), task.ROBOT_STATES)
    _same_names(where, "actions", list(model.actions), tuple(task.ROBOT_ACTION_SERVICES))
    _same_names(where, "observations", list(model.observations), ROBOT_OBSERVATIONS)
