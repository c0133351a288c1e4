"""Where the package's model files are, and how a launch argument names one.

A model is named either by a path to a file or by a scenario name such as ``tired``, looked up
as ``models/<kind>/<name>.pomdpx`` (then ``.pomdp``) in the package.
"""
from __future__ import annotations

from pathlib import Path

#: models/ of the package (the source tree; the devel space uses it in place).
MODELS_DIR = Path(__file__).resolve().parents[2] / "models"


def resolve_model(name_or_path: str, kind: str) -> Path:
    """The model file for a scenario name or a path; FileNotFoundError lists what exists."""
    candidate = Path(name_or_path).expanduser()
    if candidate.suffix in (".pomdp", ".pomdpx") or candidate.parent != Path("."):
        if candidate.is_file():
            return candidate
        raise FileNotFoundError(f"no model file {candidate}")
    folder = MODELS_DIR / kind
    for suffix in (".pomdpx", ".pomdp"):
        path = folder / f"{name_or_path}{suffix}"
        if path.is_file():
            return path
    known = sorted({p.stem for p in folder.glob("*.pomdp*")})
    raise FileNotFoundError(f"no {kind} model named {name_or_path!r} in {folder}; "
                            f"known: {', '.join(known) or 'none'}")
