"""The files a cell takes to a cluster's node (``--cluster``; docs/cluster.md).

A node needs the package, not the driver's paths: every file a cell names on the driver
travels with it, and the node writes them into the cell's own directory and points the cell
at its copies. They are

- the robot model and the human model (the cell's ``robot_model`` and ``human_model_file``);
- of a sequence cell, the files its launch arguments name (:data:`FILE_ARGUMENTS`): the
  selector model, a schedule file, and a policy library: its manifest with every file its
  policies name, in the same layout relative to one another, so that the manifest's
  relative paths find them on the node as on the driver.

An argument whose value is no file of the driver's (``auto``, ``fabric``, an inline schedule)
goes as it is: the node's install answers it. Pure: no Ray, no ROS; the driver calls
:func:`cell_files` and the node :func:`place_cell_files`.
"""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Dict, List, Tuple

from ros_hrc import settings
from ros_hrc.experiment.stack import CellSpec

__all__ = ["FILE_ARGUMENTS", "ShippedFiles", "cell_files", "place_cell_files"]

#: The cell's fields that name a model file.
MODEL_FIELDS = ("robot_model", "human_model_file")
#: The launch arguments of a sequence cell that may name a file of the driver's.
FILE_ARGUMENTS = ("selector_model", "schedule", "library")
#: Keys of the files that a launch argument names (its value is rewritten on the node) and
#: of the files a library's policies name (written only: the manifest finds them).
_ARGUMENT = "argument:"
_LIBRARY_MEMBER = "library-member:"

#: What travels: key -> (path relative to the cell's model folder, contents).
ShippedFiles = Dict[str, Tuple[str, bytes]]


def cell_files(cell: CellSpec, cache: Dict[Tuple[str, str], ShippedFiles]) -> ShippedFiles:
    """The files ``cell`` names on this machine, keyed as :func:`place_cell_files` reads them.
    ``cache`` (what was read before, by the kind and path) spares reading a file again for
    the next cell that names it."""
    files: ShippedFiles = {}
    for field_name in MODEL_FIELDS:
        path = getattr(cell, field_name)
        if path:
            files.update(_cached(cache, field_name, path,
                                 lambda p=path, f=field_name: {f: _read(Path(p), Path(p).name)}))
    for word in cell.extra_args:
        name, sep, value = word.partition(":=")
        # The driver made every file it was given absolute; a word such as ``fabric`` or
        # ``auto`` is no file even when one of that name lies where the driver runs.
        if not sep or name not in FILE_ARGUMENTS or not (os.path.isabs(value)
                                                         and os.path.isfile(value)):
            continue
        if name == "library":
            files.update(_cached(cache, name, value,
                                 lambda v=value: _library_files(Path(v), cell.task)))
        else:
            files.update(_cached(cache, name, value, lambda n=name, v=value: {
                f"{_ARGUMENT}{n}": _read(Path(v), f"{n}/{Path(v).name}")}))
    return files


def place_cell_files(spec: CellSpec, files: ShippedFiles, models: Path) -> CellSpec:
    """On the node: write ``files`` under ``models`` (made if missing) and return ``spec``
    pointing at the copies (its model fields, and the launch arguments that named a file)."""
    fields: Dict[str, str] = {}
    arguments: Dict[str, str] = {}
    for key, (relative, data) in files.items():
        path = models / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        if key in MODEL_FIELDS:
            fields[key] = str(path)
        elif key.startswith(_ARGUMENT):
            arguments[key[len(_ARGUMENT):]] = str(path)
    extra_args: List[str] = []
    for word in spec.extra_args:
        name, sep, _ = word.partition(":=")
        extra_args.append(f"{name}:={arguments[name]}" if sep and name in arguments else word)
    return dataclasses.replace(spec, extra_args=extra_args, **fields)


def _library_files(manifest: Path, task: str) -> ShippedFiles:
    """A library's manifest and the files its policies name, relative to the folder that
    holds them all (under ``library/``)."""
    # Imported here: the library loads the robot models, which only a sequence cell needs.
    from ros_hrc.agents.library import load_library

    library = load_library(manifest, task)
    # Every setting of a policy that names a file: its robot model and any file option.
    members = sorted({Path(value) for policy in library.policies
                      for key, value in policy.settings().items()
                      if settings.SETTINGS[key].kind in ("model", "file") and value}
                     - {library.manifest})
    root = Path(os.path.commonpath([library.manifest.parent] + [m.parent for m in members]))
    files = {f"{_ARGUMENT}library": _read(library.manifest, _under_library(library.manifest,
                                                                            root))}
    for member in members:
        files[f"{_LIBRARY_MEMBER}{member}"] = _read(member, _under_library(member, root))
    return files


def _under_library(path: Path, root: Path) -> str:
    return str(Path("library") / path.relative_to(root))


def _read(path: Path, relative: str) -> Tuple[str, bytes]:
    return relative, path.read_bytes()


def _cached(cache: Dict[Tuple[str, str], ShippedFiles], kind: str, path: str,
            read) -> ShippedFiles:
    if (kind, path) not in cache:
        cache[(kind, path)] = read()
    return cache[(kind, path)]
