"""Model files by extension: load, save, convert and compare.

``.pomdp`` is Cassandra's format (:mod:`ros_hrc.pomdp.cassandra`), ``.pomdpx`` is POMDPX
(:mod:`ros_hrc.pomdp.pomdpx`); the case of the extension does not matter (the seed writes
``humanModel.POMDPx``). Converting either way and back gives identical tables, bit for bit.
A model is written whole or not at all (:mod:`ros_hrc.pomdp.output`).
"""
from __future__ import annotations

import importlib
from pathlib import Path
from types import ModuleType
from typing import List, Optional

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import ModelFormatError
from ros_hrc.pomdp.model import Model

__all__ = ["FORMATS", "format_of", "load_model", "save_model", "convert", "differences"]

#: File extension -> (format name, the stem of its modules ``<stem>_reader``/``<stem>_writer``).
#: A reader or writer is imported when a file of its format is read or written: a command on
#: a small model spends more time importing than working.
FORMATS = {".pomdp": ("Cassandra", "cassandra"), ".pomdpx": ("POMDPX", "pomdpx")}


def _format(path) -> tuple:
    suffix = Path(str(path)).suffix.lower()
    if suffix not in FORMATS:
        raise ModelFormatError(str(path), None,
                               f"unknown model format {suffix or '(no extension)'!r}: "
                               "expected .pomdp (Cassandra) or .pomdpx (POMDPX)")
    return FORMATS[suffix]


def _module(path, role: str) -> ModuleType:
    """The format's ``reader`` or ``writer`` module for ``path``'s extension."""
    return importlib.import_module(f"ros_hrc.pomdp.{_format(path)[1]}_{role}")


def format_of(path) -> str:
    """``"Cassandra"`` or ``"POMDPX"`` from the file's extension; ModelFormatError otherwise."""
    return _format(path)[0]


def load_model(path, memory_limit: Optional[int] = None) -> Model:
    """Read a model file, choosing the parser by extension (.pomdp or .pomdpx); with
    ``memory_limit`` (bytes), MemoryLimitError for a file too large to read within it."""
    return _module(path, "reader").load(path, memory_limit=memory_limit)


def save_model(model: Model, path) -> None:
    """Write ``model`` in the format the extension of ``path`` names, whole or not at all."""
    _module(path, "writer").save(model, path)


def convert(source, target, memory_limit: Optional[int] = None) -> Model:
    """Read ``source`` and write it to ``target`` in the format of ``target``'s extension."""
    _format(target)                    # refuse a bad target before reading anything
    model = load_model(source, memory_limit)
    save_model(model, target)
    return model


def differences(a: Model, b: Model) -> List[str]:
    """What differs between two models' names, discount, flags and tables (exactly); [] if none."""
    out: List[str] = []
    for label in ("states", "actions", "observations"):
        if list(getattr(a, label)) != list(getattr(b, label)):
            out.append(f"{label} differ: {getattr(a, label)} vs {getattr(b, label)}")
    if out:
        return out
    for label in ("discount", "fully_observable", "minimise"):
        if getattr(a, label) != getattr(b, label):
            out.append(f"{label} differs: {getattr(a, label)} vs {getattr(b, label)}")
    if not np.array_equal(np.asarray(a.initial_belief), np.asarray(b.initial_belief)):
        out.append("initial beliefs differ")
    for label in ("T", "O", "R"):
        for i, action in enumerate(a.actions):
            x, y = sp.csr_matrix(getattr(a, label)[i]), sp.csr_matrix(getattr(b, label)[i])
            if x.shape != y.shape:
                out.append(f"{label}[{action}] shapes differ: {x.shape} vs {y.shape}")
                continue
            delta = abs(x - y)
            if delta.nnz and delta.max() != 0:
                out.append(f"{label}[{action}] differs (largest difference {delta.max():g})")
    return out
