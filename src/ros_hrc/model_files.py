"""Where the package's model files are, and how a launch argument names one.

A model is named either by a path to a file or by a scenario name such as ``tired``, looked up
as ``models/<kind>/<name>.pomdpx`` (then ``.pomdp``) in the package.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import List, Optional

#: models/ of the package (the source tree; the devel space uses it in place).
MODELS_DIR = Path(__file__).resolve().parents[2] / "models"


def user_path(text: str) -> Path:
    """A path as the user typed it, made absolute against the directory the command was run
    from (``~`` expanded). The one rule for every file argument: entry points apply it once
    and pass only absolute paths on, because the processes they start run elsewhere
    (roslaunch starts nodes in ``$ROS_HOME``). Symbolic links are kept as typed."""
    return Path(os.path.abspath(os.path.expanduser(str(text))))


def names_a_file(name_or_path: str) -> bool:
    """Whether a model argument is a path (it has a directory part, starts with ``~`` or ends
    in ``.pomdp``/``.pomdpx``) rather than a scenario name looked up in the package."""
    typed = Path(str(name_or_path))
    return (typed.suffix in (".pomdp", ".pomdpx") or typed.parent != Path(".")
            or str(name_or_path).startswith("~"))


def resolve_model(name_or_path: str, kind: str, folder: Optional[Path] = None) -> Path:
    """The absolute model file for a scenario name or a path (see :func:`user_path`); a name
    is looked up in ``folder`` (default ``models/<kind>``: the seed task's; a task names its
    own, :attr:`ros_hrc.tasks.definition.Task.model_dirs`). FileNotFoundError lists what
    exists."""
    candidate = user_path(name_or_path)
    if names_a_file(name_or_path):
        if candidate.is_file():
            return candidate
        raise FileNotFoundError(f"no model file {name_or_path} (looked for {candidate})")
    folder = Path(folder) if folder is not None else MODELS_DIR / kind
    for suffix in (".pomdpx", ".pomdp"):
        path = folder / f"{name_or_path}{suffix}"
        if path.is_file():
            return path
    known = model_names(folder)
    raise FileNotFoundError(f"no {kind} model named {name_or_path!r} in {folder}; "
                            f"known: {', '.join(known) or 'none'}")


def model_names(folder: Path) -> List[str]:
    """The scenario names a model folder holds: the stems of its .pomdp and .pomdpx files,
    sorted (a name with both files is listed once)."""
    return sorted({path.stem for path in Path(folder).glob("*.pomdp*")
                   if path.suffix in (".pomdp", ".pomdpx")})
