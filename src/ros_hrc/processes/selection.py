"""What the robot process chooses from in a sequence of tasks (issue #30; docs/sequences.md):
the policy library and the selector's model, loaded and checked against the run, and the
selector built on them. ``hrc_check`` (the launch's pre-flight) loads the same, so a launch
that the robot process would refuse is refused before anything starts.

``selector:=fixed`` (the default) is today's robot: nothing here is loaded, the robot process
keeps its one planner (``robot_model``, ``planner``). Any other selector takes the library
(``library:=``, :func:`ros_hrc.agents.library.load_library`) and, when there is one, the
selector model (``selector_model:=``; ``auto``: ``selector_model.json`` beside the library's
manifest, if it exists; the BPR selectors and the oracle cannot run without one). Every
refusal is one line naming the argument (:class:`SelectionError`). No ROS, no sockets.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from ros_hrc import settings
from ros_hrc.agents.library import PolicyLibrary, load_library
from ros_hrc.agents.selector_model import SelectorModel, load_selector_model
from ros_hrc.agents.learning import planning_of
from ros_hrc.agents.selectors import FIXED, Selector, make_selector, selector_class
from ros_hrc.errors import HrcError
from ros_hrc.registry import RegistryError
from ros_hrc.model_files import user_path
from ros_hrc.models import shown_path
from ros_hrc.streams import stream_seed
from ros_hrc.tasks.definition import Task

__all__ = ["SELECTOR_MODEL_NAME", "SelectionError", "Selection", "uses_library",
           "auto_selector_model", "load_selection", "new_selector"]

#: The selector model's file name beside a library's manifest (``selector_model:=auto``).
SELECTOR_MODEL_NAME = "selector_model.json"


class SelectionError(HrcError):
    """The library, the selector or its model cannot be used: one line naming the argument."""


@dataclass(frozen=True)
class Selection:
    """The library a selector chooses from, and its model (None: none, which only the
    selectors that need none accept)."""

    spec: str
    library: PolicyLibrary
    model: Optional[SelectorModel]


def uses_library(selector: str) -> bool:
    """Whether ``selector`` (the setting's value) chooses from a library: every selector but
    ``fixed`` alone (today's single robot) and the learning robot's (one robot, its model
    learnt: ros_hrc.agents.learning)."""
    return selector.strip() != "fixed" and planning_of(selector.strip()) is None


def auto_selector_model(library: PolicyLibrary) -> Path:
    """``selector_model:=auto``'s file: ``selector_model.json`` beside the library's manifest
    (models/fabric/, models/robot/ for the tasks' own libraries)."""
    return library.manifest.parent / SELECTOR_MODEL_NAME


def load_selection(selector: str, library: str, selector_model: str, task: Task) -> Selection:
    """The library ``library`` names and the selector model ``selector_model`` names (each a
    setting's value; ``auto`` the defaults), checked against ``task``, the library and
    ``selector``. Raises :class:`SelectionError` (one line, naming the argument)."""
    spec = selector.strip()
    kind, _, policy = spec.partition(":")
    if kind == FIXED:
        needs_model = False
    else:
        policy = ""           # the colon of module:Class
        try:
            needs_model = selector_class(spec).needs_model
        except RegistryError as exc:
            raise SelectionError(f"selector:={selector}: {exc.reason}") from None
    try:
        loaded = load_library(library, task)
    except HrcError as exc:
        text = str(exc)     # the library's own errors begin with the name they were given
        text = text[len(library) + 2:] if text.startswith(f"{library}: ") else text
        raise SelectionError(f"library:={library}: {text}") from None
    if policy and policy not in loaded.names():
        raise SelectionError(f"selector:={selector}: no policy {policy!r} in the library "
                             f"{shown_path(loaded.manifest)} (its policies: "
                             f"{', '.join(loaded.names())})")
    auto = selector_model.strip() in ("", settings.AUTO_WORD)
    path = auto_selector_model(loaded) if auto else user_path(selector_model.strip())
    if auto and not path.is_file():
        if needs_model:
            raise SelectionError(f"selector:={selector} needs a selector model, and the "
                                 f"library has none (looked for {shown_path(path)}): `make "
                                 "train-selector` writes it, or give selector_model:=FILE")
        return Selection(selector, loaded, None)
    try:
        model = load_selector_model(path, task, loaded.names())
    except HrcError as exc:
        if auto and not needs_model:
            return Selection(selector, loaded, None)   # not needed: another library's, unused
        raise SelectionError(f"selector_model:={selector_model}: {' '.join(str(exc).split())}"
                             ) from None
    return Selection(selector, loaded, model)


def new_selector(selection: Selection, seed: int, sequence: int, forgetting: float
                 ) -> Selector:
    """A fresh selector for one sequence: its choices drawn from the stream of (``seed``,
    ``sequence``, "selector") (:mod:`ros_hrc.streams`; the robot process numbers a sequence
    by the episode of its first task), so one sequence's choices repeat under its seed."""
    try:
        return make_selector(selection.spec, selection.library.names(), selection.model,
                             stream_seed(seed, sequence, "selector"), forgetting)
    except ValueError as exc:
        raise SelectionError(f"selector:={selection.spec}: {exc}") from None
