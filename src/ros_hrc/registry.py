"""Where a planner, a selector or a robot policy is found by its name: the extension surface
(docs/extending.md).

A researcher's package declares its own in its ``pyproject.toml``::

    [project.entry-points."ros_hrc.planners"]
    my_planner = "my_robot.planner:MyPlanner"

    [project.entry-points."ros_hrc.selectors"]
    my_selector = "my_robot.selector:MySelector"

    [project.entry-points."ros_hrc.policies"]
    my_robot = "my_robot.policy:MY_ROBOT"

and, once installed (``pip install``), ``planner:=my_planner``, ``selector:=my_selector`` and
``hrc_experiment --policies my_robot`` find them through :func:`importlib.metadata.entry_points`.
Without installing anything, ``module:Class`` names the same thing wherever a name goes
(``planner:=my_robot.planner:MyPlanner``), its module imported from ``sys.path``.

Our own are found by the same lookup (:func:`entry_points`): :data:`BUILT_IN` is what
``setup.py`` would declare as ros_hrc's entry points, but catkin's devel space, which is how
``make setup`` installs the package (``.ws/devel``: a ``ros_hrc/__init__.py`` that points at
``src/``), writes no ``dist-info``, so ``importlib.metadata`` cannot see entry points of
ros_hrc; they are made here as the same :class:`importlib.metadata.EntryPoint` objects and
loaded the same way. A name of ours is ours: a package that declares it too is not asked
(and the installed distributions are not read for it, which keeps a start-up that names one of
ours as fast as before).

Every refusal is a :class:`RegistryError`, one line: an unknown name lists the known ones with
the nearest (did you mean); a ``module:Class`` that does not import, or is not of the kind the
group holds, is named with the reason. Nothing of ours is imported here (the ground floor):
the kinds are given by the callers, each a floor above.
"""
from __future__ import annotations

import functools
import importlib
import re
import sys
from importlib import metadata
from typing import Any, Dict, List, Mapping, Tuple

from ros_hrc.errors import did_you_mean

__all__ = ["PLANNERS", "SELECTORS", "POLICIES", "WHAT", "BUILT_IN", "RegistryError",
           "entry_points", "names", "known_text", "check_name", "load", "is_object_path"]

#: The entry-point groups: robot planners (``planner:=``), selectors (``selector:=``), and the
#: robot policies of a study (``hrc_experiment --policies``).
PLANNERS = "ros_hrc.planners"
SELECTORS = "ros_hrc.selectors"
POLICIES = "ros_hrc.policies"
#: What one thing of each group is called in a message.
WHAT: Mapping[str, str] = {PLANNERS: "planner", SELECTORS: "selector", POLICIES: "robot policy"}

#: ros_hrc's own, as its entry points would be declared (module docstring: why here).
BUILT_IN: Mapping[str, Mapping[str, str]] = {
    PLANNERS: {
        "despot": "ros_hrc.pomdp.despot:DespotPlanner",
        "policy": "ros_hrc.pomdp.planner:PolicyPlanner",
        "reactive": "ros_hrc.agents.robots:ReactiveRobot",
        "none": "ros_hrc.agents.robots:NoRobotPlanner",
        "explore": "ros_hrc.agents.robots:ExplorePlanner",
    },
    SELECTORS: {
        "random": "ros_hrc.agents.selectors:RandomSelector",
        "bpr": "ros_hrc.agents.selectors:BprSelector",
        "bpr-pi": "ros_hrc.agents.selectors:BprPiSelector",
        "bpr-fabric": "ros_hrc.agents.selectors:FabricBprSelector",
        "bandit": "ros_hrc.agents.selectors:BanditSelector",
        "oracle": "ros_hrc.agents.selectors:OracleSelector",
    },
    POLICIES: {
        "pomdp": "ros_hrc.experiment.episode:POMDP",
        "pomdp_fitted": "ros_hrc.experiment.episode:POMDP_FITTED",
        "pomdp_considerate": "ros_hrc.experiment.episode:POMDP_CONSIDERATE",
        "pomdp_types": "ros_hrc.experiment.episode:POMDP_TYPES",
        "reactive": "ros_hrc.experiment.episode:REACTIVE_ROBOT",
        "no_robot": "ros_hrc.experiment.episode:NO_ROBOT",
        "explore": "ros_hrc.experiment.episode:EXPLORE",
    },
}

#: ``module.path:Attribute`` (or ``module:Outer.Inner``), as an entry point's value is written.
_OBJECT_PATH = re.compile(r"[A-Za-z_][\w]*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*(\.[A-Za-z_]\w*)*")


class RegistryError(ValueError):
    """A name that finds nothing usable: one line (what was asked for, and why not);
    ``reason`` is the why alone, for a caller whose line names the argument already."""

    def __init__(self, message: str, reason: str = "") -> None:
        super().__init__(message)
        self.reason = reason or message


def is_object_path(text: str) -> bool:
    """Whether ``text`` is written ``module:Class`` rather than as a registered name."""
    return bool(_OBJECT_PATH.fullmatch(text.strip()))


def entry_points(group: str) -> Tuple[metadata.EntryPoint, ...]:
    """The group's entry points: ours (:data:`BUILT_IN`) then every installed distribution's
    (:func:`importlib.metadata.entry_points`), the same declaration found twice (one package on
    two paths) once. The installed ones are read once for each ``sys.path`` (a scan of every
    distribution: a study's summary asks for a policy per row)."""
    ours = tuple(metadata.EntryPoint(name, value, group)
                 for name, value in BUILT_IN.get(group, {}).items())
    seen = {(ep.name, ep.value) for ep in ours}
    found: List[metadata.EntryPoint] = []
    for ep in _installed(tuple(sys.path)).get(group, ()):
        if (ep.name, ep.value) not in seen:
            seen.add((ep.name, ep.value))
            found.append(ep)
    return ours + tuple(found)


@functools.lru_cache(maxsize=4)
def _installed(path: Tuple[str, ...]) -> Dict[str, Tuple[metadata.EntryPoint, ...]]:
    """Our groups' entry points of the distributions on ``path`` (``sys.path`` as it was)."""
    return {group: tuple(metadata.entry_points(group=group)) for group in WHAT}


def names(group: str) -> Tuple[str, ...]:
    """The names the group knows: ours first, in their order, then installed ones, sorted."""
    eps = entry_points(group)
    ours = tuple(BUILT_IN.get(group, {}))
    return ours + tuple(sorted({ep.name for ep in eps} - set(ours)))


def known_text(group: str) -> str:
    """The known names and the other way to name one, for a message or a setting's doc."""
    return f"{', '.join(names(group))}, or module:Class"


def check_name(group: str, text: str) -> str:
    """``text`` stripped when it is a known name or is written ``module:Class`` (nothing is
    imported: :func:`load` does that); RegistryError (one line, with the nearest known name)
    otherwise. A name of ours is known without reading the installed distributions."""
    name = str(text).strip()
    if is_object_path(name) or name in BUILT_IN.get(group, {}) or name in names(group):
        return name
    hint = did_you_mean(name, names(group))
    hint = f"; {hint}" if hint else ""
    raise RegistryError(f"unknown {WHAT.get(group, group)} {name!r}{hint} (known: "
                        f"{known_text(group)})")


def load(group: str, text: str, kind: type, instance: bool = False) -> Any:
    """What ``text`` names in ``group`` (a registered name, or ``module:Class``), imported and
    checked to be a subclass of ``kind`` (``instance``: an instance of it). RegistryError (one
    line naming it and why) for an unknown name, an import that fails, an attribute that is
    not there, an object of another kind, or a name two packages declare differently."""
    name = check_name(group, text)
    what = WHAT.get(group, group)
    if is_object_path(name):
        where = name
        entry = metadata.EntryPoint(name, name, group)
    elif name in BUILT_IN.get(group, {}):
        # Ours: a package that declares the same name does not replace it (nor is it read).
        entry = metadata.EntryPoint(name, BUILT_IN[group][name], group)
        where = f"{name!r} ({_origin(entry)})"
    else:
        declared = [ep for ep in entry_points(group) if ep.name == name]
        if len({ep.value for ep in declared}) > 1:
            reason = (f"declared more than once: "
                      f"{'; '.join(_origin(ep) for ep in declared)}")
            raise RegistryError(f"{what} {name!r} is {reason}", reason)
        entry = declared[0]
        where = f"{name!r} ({_origin(entry)})"
    try:
        importlib.import_module(entry.module)
    except Exception as exc:    # whatever the researcher's module raises, said in one line
        reason = f"cannot import {entry.module} ({type(exc).__name__}: {_one_line(exc)})"
        raise RegistryError(f"{what} {where}: {reason}", reason) from None
    try:
        found = entry.load()
    except AttributeError:
        reason = f"module {entry.module} has no {entry.attr}"
        raise RegistryError(f"{what} {where}: {reason}", reason) from None
    right = isinstance(found, kind) if instance else (isinstance(found, type)
                                                      and issubclass(found, kind))
    if not right:
        wanted = f"a {kind.__name__}" if instance else f"a subclass of {kind.__module__}." \
                                                       f"{kind.__qualname__}"
        reason = f"{entry.attr} is not {wanted} (it is {_shown(found)})"
        raise RegistryError(f"{what} {where}: {reason}", reason)
    return found


def _origin(ep: metadata.EntryPoint) -> str:
    """Who declares ``ep``: ``my_robot 0.1: my_robot.planner:MyPlanner`` (ros_hrc's own)."""
    who = f"{ep.dist.name} {ep.dist.version}" if ep.dist is not None else "ros_hrc"
    return f"{who}: {ep.value}"


def _shown(thing: Any) -> str:
    if isinstance(thing, type):
        return f"class {thing.__module__}.{thing.__qualname__}"
    return f"{type(thing).__name__} {thing!r}"[:120]


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or "no message"

