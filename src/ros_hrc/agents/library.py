"""A task's policy library: the robot policies a selector chooses among, one per task of a
sequence (issue #30; Bayesian policy reuse picks from it).

A library is a TOML manifest (``library.toml``)::

    # where each policy came from (a comment header)
    task = "fabric"                       # the task every policy is for

    [[policy]]
    name = "base"                         # letters, digits, _ . @ -: the selector names it so
    planner = "despot"                    # a planner: a value of the planner setting
    model = "robot/base.pomdpx"           # the robot model, relative to this file's folder,
                                          # or a name of the task's robot models ("robot")

    [[policy]]
    name = "reactive"
    planner = "reactive"
    reactive_wait = 15.0                  # an option: a setting of that planner

``planner`` is any name the ``planner`` setting takes: ours, an installed package's, or
``module:Class`` (:mod:`ros_hrc.registry`; docs/extending.md). A policy's other keys are its
options, as its planner class declares them (:class:`ros_hrc.pomdp.planner.Planner`): the
settings of the robot process it reads (``settings_used``) -- DESPOT's ``time_per_step``,
``scenarios``, ``depth``, ``lambda``, ``max_trials``; the offline policy's ``policy_file`` (a
path, relative to the manifest's folder like ``model``); the reactive robot's tuning, the
task's ``reactive_parameter`` (``reactive_budget`` for the seed's, ``reactive_wait`` for
fabric's), each checked as the launch checks it -- and its own ``options``, each of the type
of its default, passed to the planner as they are. ``model`` is needed by a planner that
``plans_on_model`` (``despot``, ``policy``); for the others it may be left out (None: the
robot process keeps the launch's ``robot_model``, whose belief it reports).

:func:`load_library` reads a manifest (or a folder holding ``library.toml``; ``auto``: the
task's own, :func:`library_manifest`), loads every robot model and checks it against the task
(:func:`ros_hrc.models.load_robot_model`: a model of another task is refused naming the task
it fits). Anything wrong -- a missing file or folder, malformed TOML, a manifest of another
task, a policy of another task, a missing model, a name given twice, an unknown planner or
option, no policy at all -- raises :class:`LibraryError`, one line naming the file and, where
the manifest says it, the line; nothing is loaded. No ROS.
"""
from __future__ import annotations

import os
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Tuple, Union

from ros_hrc import settings, tasks
from ros_hrc.errors import HrcError, did_you_mean
from ros_hrc.pomdp.planner import planner_class
from ros_hrc.registry import RegistryError
from ros_hrc.model_files import MODELS_DIR, names_a_file, user_path
from ros_hrc.models import load_robot_model, model_path, shown_path
from ros_hrc.tasks.definition import Task

__all__ = ["LibraryPolicy", "PolicyLibrary", "LibraryError", "UnknownPolicy", "load_library",
           "library_manifest", "MANIFEST_NAME", "AUTO", "POLICY_NAME", "planner_options"]

#: The manifest's file name: a library given as a folder is this file in it.
MANIFEST_NAME = "library.toml"
#: ``library:=auto``: the task's own manifest.
AUTO = settings.AUTO_WORD
#: A policy name: what ``selector:=fixed:<policy>`` and a comma-separated list can carry.
POLICY_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.@-]*")
#: A policy's keys that are not options.
_POLICY_KEYS = ("name", "planner", "model")
#: The manifest's top-level keys.
_MANIFEST_KEYS = ("task", "policy")


class LibraryError(HrcError):
    """A policy library cannot be loaded: one line naming the file (and its line)."""


class UnknownPolicy(LibraryError, KeyError):
    """No policy of that name in the library: one line naming the nearest known one."""

    def __str__(self) -> str:        # KeyError would quote the message
        return str(self.args[0])


@dataclass(frozen=True)
class LibraryPolicy:
    """One policy of a library: a planner, the robot model it plans on and its options."""

    name: str
    #: A value of the ``planner`` setting: "despot", "reactive", ..., "module:Class"
    planner: str
    #: The robot model's absolute path (None: the planner needs none of its own).
    robot_model: Optional[Path]
    #: Other settings for this policy, checked and typed, e.g. ``{"reactive_budget": 2}``.
    options: Mapping[str, Any] = field(default_factory=dict)

    def settings(self) -> Dict[str, Any]:
        """The launch settings this policy sets: ``planner``, ``robot_model`` (when it has
        one, as an absolute path) and its options."""
        out: Dict[str, Any] = {"planner": self.planner}
        if self.robot_model is not None:
            out["robot_model"] = str(self.robot_model)
        out.update(self.options)
        return out


@dataclass(frozen=True)
class PolicyLibrary:
    """A task's policies, in the manifest's order."""

    task: str
    #: The manifest's absolute path.
    manifest: Path
    policies: Tuple[LibraryPolicy, ...]

    def names(self) -> Tuple[str, ...]:
        """The policies' names, in the manifest's order."""
        return tuple(policy.name for policy in self.policies)

    def get(self, name: str) -> LibraryPolicy:
        """The policy named ``name``; UnknownPolicy (a KeyError, one line naming the nearest
        known name and every name) otherwise."""
        for policy in self.policies:
            if policy.name == name:
                return policy
        known = self.names()
        hint = did_you_mean(name, known)
        hint = f"; {hint}" if hint else ""
        raise UnknownPolicy(f"no policy {name!r} in the library {shown_path(self.manifest)}"
                            f"{hint} (known: {', '.join(known)})")


def library_manifest(task: Union[Task, str]) -> Path:
    """The task's own manifest (``library:=auto``): ``library.toml`` in the folder the task's
    model folders share (fabric's ``models/fabric/``) or, when they share only the package's
    ``models/`` (the seed's ``models/human`` and ``models/robot``), in its robot folder
    (``models/robot/``). LibraryError for a task without model folders."""
    which = tasks.get(task)
    dirs = [Path(folder) for folder in which.model_dirs.values()]
    if not dirs:
        raise LibraryError(f"task {which.name} has no model folders, so no library of its own: "
                           f"name a manifest (library:=FILE)")
    shared = Path(os.path.commonpath([str(folder) for folder in dirs]))
    if shared == MODELS_DIR and "robot" in which.model_dirs:
        return Path(which.model_dirs["robot"]) / MANIFEST_NAME
    return shared / MANIFEST_NAME


def planner_options(planner: Union[str, type], task: Union[Task, str]) -> Tuple[str, ...]:
    """The options a policy of ``planner`` (its name or class) may set on ``task``: the
    settings it reads, then its own options (:class:`ros_hrc.pomdp.planner.Planner`)."""
    kind = planner_class(planner) if isinstance(planner, str) else planner
    return tuple(kind.settings_used(tasks.get(task))) + tuple(kind.options)


def load_library(path_or_auto: Union[str, Path], task: Union[Task, str]) -> PolicyLibrary:
    """The library of a manifest (TOML), of a folder holding ``library.toml``, or ``auto``
    (the task's own: :func:`library_manifest`); a relative path is the user's, against the
    directory the command runs in. Every robot model is loaded and checked against the task.
    Raises LibraryError (one line naming the file, and the manifest's line where it can)."""
    which = tasks.get(task)
    manifest = _manifest_path(path_or_auto, which)
    where = shown_path(manifest)
    try:
        text = manifest.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise LibraryError(f"{where}: cannot read the manifest ({_reason(exc)})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise LibraryError(f"{where}: not a valid TOML manifest: {_one_line(exc)}") from None
    lines = _Lines(text, where)
    unknown = [key for key in data if key not in _MANIFEST_KEYS]
    if unknown:
        raise LibraryError(f"{lines.of_key(unknown[0])}: unknown key {unknown[0]!r} "
                           f"(a manifest has {' and '.join(_MANIFEST_KEYS)} and nothing else)")
    _check_task(data.get("task"), which, lines)
    entries = data.get("policy", [])
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise LibraryError(f"{lines.of_key('policy')}: policy must be [[policy]] tables")
    if not entries:
        raise LibraryError(f"{where}: no policies (a library needs at least one [[policy]] "
                           f"table)")
    policies: List[LibraryPolicy] = []
    first_line: Dict[str, str] = {}
    for index, entry in enumerate(entries):
        policy = _policy(entry, index, manifest.parent, which, lines)
        if policy.name in first_line:
            raise LibraryError(f"{lines.of_policy(index, 'name')}: policy {policy.name!r} is "
                               f"named twice (first at {first_line[policy.name]})")
        first_line[policy.name] = lines.of_policy(index, "name")
        policies.append(policy)
    return PolicyLibrary(task=which.name, manifest=manifest, policies=tuple(policies))


# -- reading ------------------------------------------------------------------------------------
def _manifest_path(path_or_auto: Union[str, Path], which: Task) -> Path:
    """The manifest a ``library`` argument names (absolute); LibraryError when there is none."""
    text = str(path_or_auto).strip()
    if text in ("", AUTO):
        path = library_manifest(which)
        if not path.is_file():
            raise LibraryError(f"task {which.name} has no policy library (looked for "
                               f"{shown_path(path)})")
        return path
    path = user_path(text)
    if path.is_dir():
        inside = path / MANIFEST_NAME
        if not inside.is_file():
            raise LibraryError(f"{text}: a folder without a {MANIFEST_NAME} (looked for {inside})")
        return inside
    if not path.exists():
        raise LibraryError(f"{text}: no such manifest or folder (looked for {path})")
    return path


def _check_task(named: Any, which: Task, lines: "_Lines") -> None:
    """LibraryError unless the manifest's ``task`` line names ``which``."""
    if named is None:
        raise LibraryError(f"{lines.where}: no task line (task = \"{which.name}\": the task "
                           f"the library's policies are for)")
    if not isinstance(named, str) or named not in tasks.TASK_NAMES:
        raise LibraryError(f"{lines.of_key('task')}: task = {named!r} is not a task (known: "
                           f"{', '.join(tasks.TASK_NAMES)})")
    if named != which.name:
        raise LibraryError(f"{lines.of_key('task')}: a library of task {named}, not of task "
                           f"{which.name} (task:={named})")


def _policy(entry: Mapping[str, Any], index: int, folder: Path, which: Task,
            lines: "_Lines") -> LibraryPolicy:
    """One [[policy]] table, checked: its name, planner, model (loaded) and options."""
    name = entry.get("name")
    if not isinstance(name, str) or not POLICY_NAME.fullmatch(name):
        shown = "no name" if name is None else f"name {name!r}"
        raise LibraryError(f"{lines.of_policy(index, 'name')}: policy {index + 1} has {shown} "
                           f"(a name is letters, digits and _ . @ -, not starting with . @ -)")
    label = f"policy {name!r}"
    if "planner" not in entry:
        raise LibraryError(f"{lines.of_policy(index, 'name')}: {label} has no planner (a "
                           f"name the planner setting takes: {settings.SETTINGS['planner'].accepted()})")
    try:
        planner = settings.parse("planner", entry["planner"])
        kind = planner_class(planner)
    except (settings.SettingError, RegistryError) as exc:
        raise LibraryError(f"{lines.of_policy(index, 'planner')}: {label}: {exc}") from None
    given = {key: value for key, value in entry.items() if key not in _POLICY_KEYS}
    options = _options(given, planner, kind, label, index, folder, which, lines)
    robot_model = _robot_model(entry.get("model"), planner, kind, label, index, folder, which,
                               lines)
    return LibraryPolicy(name=name, planner=planner, robot_model=robot_model, options=options)


def _options(given: Mapping[str, Any], planner: str, kind: type, label: str, index: int,
             folder: Path, which: Task, lines: "_Lines") -> Dict[str, Any]:
    """The policy's options: each setting its planner reads parsed as the launch parses it and
    checked with the planner as a whole (:func:`ros_hrc.settings.resolve`); each of its own
    options checked to be of its default's type, and passed on as it is."""
    allowed = planner_options(kind, which)
    for key in given:
        if key not in allowed:
            what = "option" if key in settings.SETTINGS else "key"
            takes = f"its options: {', '.join(allowed)}" if allowed else "it takes no option"
            raise LibraryError(f"{lines.of_policy(index, key)}: {label}: unknown {what} {key!r} "
                               f"for planner {planner} ({takes}; a policy's keys: "
                               f"{', '.join(_POLICY_KEYS)})")
    own = {key: value for key, value in given.items() if key in kind.options}
    for key, value in own.items():
        try:
            own.update(kind.checked_options({key: value}))
        except ValueError as exc:
            raise LibraryError(f"{lines.of_policy(index, key)}: {label}: {exc}") from None
    values = {key: _in_folder(value, folder) if settings.SETTINGS[key].kind == "file" else value
              for key, value in given.items() if key not in own}
    try:
        resolved = settings.resolve({"task": which.name, "planner": planner, **values})
    except settings.SettingError as exc:
        key = exc.name if exc.name in given else ""
        line = lines.of_policy(index, key) if key else lines.of_policy(index, "planner")
        raise LibraryError(f"{line}: {label}: {exc}") from None
    return {key: own[key] if key in own else resolved[key] for key in given}


def _robot_model(model: Any, planner: str, kind: type, label: str, index: int, folder: Path,
                 which: Task, lines: "_Lines") -> Optional[Path]:
    """The policy's robot model (absolute), loaded and checked against the task; None when
    it names none and its planner plans on none."""
    if model is None:
        if kind.plans_on_model:
            raise LibraryError(f"{lines.of_policy(index, 'name')}: {label}: planner {planner} "
                               f"needs a model (model = \"FILE\", relative to the manifest)")
        return None
    where = lines.of_policy(index, "model")
    if not isinstance(model, str) or not model.strip():
        raise LibraryError(f"{where}: {label}: model must be a file name, got {model!r}")
    if not names_a_file(model.strip()):
        # A name, as robot_model:= takes one: the task's model of that name (a library kept
        # outside the package names the shipped models so).
        try:
            path = model_path(model.strip(), "robot", which)
        except HrcError as exc:
            raise LibraryError(f"{where}: {label}: {_one_line(exc)}") from None
    else:
        path = Path(_in_folder(model, folder))
    try:
        load_robot_model(str(path), which)
    except HrcError as exc:
        raise LibraryError(f"{where}: {label}: {_one_line(exc)}") from None
    return path


def _in_folder(text: Any, folder: Path) -> Any:
    """A path of the manifest (``~`` expanded) made absolute against its folder, wherever the
    command runs; anything but a string as it is (the check that follows refuses it)."""
    if not isinstance(text, str):
        return text
    path = Path(os.path.expanduser(text.strip()))
    return os.path.normpath(path if path.is_absolute() else folder / path)


class _Lines:
    """Where a key of the manifest is: ``file:line`` for the messages (tomllib keeps no
    positions, so the text is searched: a [[policy]] header and the key's line after it)."""

    _HEADER = re.compile(r"^\s*\[\[\s*policy\s*\]\]")
    _TABLE = re.compile(r"^\s*\[")

    def __init__(self, text: str, where: str) -> None:
        self.where = where
        self._lines = text.splitlines()
        self._headers = [i for i, line in enumerate(self._lines) if self._HEADER.match(line)]

    def _key(self, key: str, start: int, stop: int) -> Optional[int]:
        pattern = re.compile(rf"^\s*[\"']?{re.escape(key)}[\"']?\s*=")
        for i in range(start, stop):
            if pattern.match(self._lines[i]):
                return i
        return None

    def _at(self, line: Optional[int]) -> str:
        return self.where if line is None else f"{self.where}:{line + 1}"

    def of_key(self, key: str) -> str:
        """A top-level key's place (before the first table)."""
        stop = next((i for i, line in enumerate(self._lines) if self._TABLE.match(line)),
                    len(self._lines))
        return self._at(self._key(key, 0, stop))

    def of_policy(self, index: int, key: str) -> str:
        """The place of ``key`` in the ``index``-th [[policy]] table (its header's when the
        key is not written there)."""
        if index >= len(self._headers):
            return self.where
        start = self._headers[index]
        stop = next((i for i in range(start + 1, len(self._lines))
                     if self._TABLE.match(self._lines[i])), len(self._lines))
        found = self._key(key, start + 1, stop)
        return self._at(start if found is None else found)


def _reason(exc: BaseException) -> str:
    return getattr(exc, "strerror", None) or str(exc)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())
