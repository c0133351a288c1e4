"""Where the package's model files are, how a launch argument names one, and where ROS keeps
this user's files (``$ROS_HOME``).

A model is named either by a path to a file or by a scenario name such as ``tired``, looked up
as ``models/<kind>/<name>.pomdpx`` (then ``.pomdp``) in the package.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import List, Mapping, Optional, Sequence

from ros_hrc.errors import did_you_mean

#: models/ of the package (the source tree; the devel space uses it in place).
MODELS_DIR = Path(__file__).resolve().parents[2] / "models"


def ros_home(environ: Optional[Mapping[str, str]] = None) -> Path:
    """The directory ROS keeps per-user state in: ``$ROS_HOME``, or ``~/.ros`` without it (as
    rospkg's ``get_ros_home``, which these ROS-free rooms cannot import)."""
    environ = os.environ if environ is None else environ
    return Path(environ.get("ROS_HOME") or os.path.join(os.path.expanduser("~"), ".ros"))


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


def resolve_model(name_or_path: str, kind: str,
                  folder: "Path | Sequence[Path] | None" = None) -> Path:
    """The absolute model file for a scenario name or a path (see :func:`user_path`); a name
    is looked up in ``folder`` (default ``models/<kind>``: the seed task's; a task names its
    own, :attr:`ros_hrc.tasks.definition.Task.model_dirs`), or in several folders in turn, the
    first that holds it winning. FileNotFoundError lists what exists, in one line."""
    candidate = user_path(name_or_path)
    if names_a_file(name_or_path):
        if candidate.is_file():
            return candidate
        raise FileNotFoundError(f"no model file {name_or_path} (looked for {candidate})")
    if folder is None:
        folders = [MODELS_DIR / kind]
    elif isinstance(folder, (str, os.PathLike)):
        folders = [Path(folder)]
    else:
        folders = [Path(f) for f in folder]
    for place in folders:
        for suffix in (".pomdpx", ".pomdp"):
            path = place / f"{name_or_path}{suffix}"
            if path.is_file():
                return path
    known = sorted({name for place in folders for name in model_names(place)})
    where = ", ".join(shown_path(place) for place in folders) if len(folders) > 1 \
        else str(folders[0])
    hint = did_you_mean(name_or_path, known)
    raise FileNotFoundError(f"no {kind + ' ' if kind else ''}model named {name_or_path!r} in "
                            f"{where}; {hint + ' ' if hint else ''}"
                            f"known: {', '.join(known) or 'none'}")


def shown_path(path) -> str:
    """A file or folder as the messages show it: relative to the package for its own models."""
    path = Path(str(path))
    try:
        return str(path.resolve().relative_to(MODELS_DIR.parent))
    except ValueError:
        return str(path)


def model_names(folder: Path) -> List[str]:
    """The scenario names a model folder holds: the stems of its .pomdp and .pomdpx files,
    sorted (a name with both files is listed once)."""
    return sorted({path.stem for path in Path(folder).glob("*.pomdp*")
                   if path.suffix in (".pomdp", ".pomdpx")})
