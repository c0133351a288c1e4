"""The collaboration tasks the loop can run, as data (DESIGN §13; no ROS, no sockets).

  ros_hrc.tasks.definition  what a task is: :class:`~ros_hrc.tasks.definition.Task`
  ros_hrc.tasks.seed        ``seed``: the manual's task, the default
  ros_hrc.tasks.fabric      ``fabric``: the seed authors' successor, a human who reacts

A task is chosen by name (``task:=`` of hrc.launch, ``--task`` of the programs) through
:func:`get`; nothing else in the package names one. ``docs/tasks.md`` says how to add a third.
"""
from __future__ import annotations

import importlib
from typing import Dict, Iterable, Tuple

from ros_hrc.tasks.definition import Task

__all__ = ["Task", "TASK_NAMES", "DEFAULT_TASK", "get", "of_robot_states", "UnknownTask"]

#: Every task, by name -> the module that defines it (as ``TASK``), in the order of the docs.
_MODULES: Dict[str, str] = {
    "seed": "ros_hrc.tasks.seed",
    "fabric": "ros_hrc.tasks.fabric",
}
TASK_NAMES: Tuple[str, ...] = tuple(_MODULES)
DEFAULT_TASK = "seed"


class UnknownTask(ValueError):
    """No task of that name."""


def get(name: str) -> Task:
    """The task named ``name``; UnknownTask (one line, naming the known ones) otherwise."""
    if isinstance(name, Task):
        return name
    try:
        module = _MODULES[str(name).strip()]
    except KeyError:
        raise UnknownTask(f"no task {name!r}; known: {', '.join(TASK_NAMES)}") from None
    return importlib.import_module(module).TASK


def of_robot_states(names: Iterable[str]) -> Task:
    """The task whose robot states are ``names`` (any order): e.g. a robot model's or a step's
    belief's; the default task when none is."""
    wanted = set(names)
    for name in TASK_NAMES:
        if wanted and wanted == set(get(name).robot_states):
            return get(name)
    return get(DEFAULT_TASK)
