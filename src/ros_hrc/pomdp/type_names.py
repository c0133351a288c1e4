"""The names of a composed model of types (:mod:`ros_hrc.pomdp.typed`): a state under a type,
``<state>__<type>``, split back, a type name checked, a belief over types as one line.

Apart from :mod:`ros_hrc.pomdp.typed` because these need neither numpy's tables nor SciPy: the
step's display and the nodes that show a belief over types import only this (SciPy alone
costs each such process about 0.3 s of CPU at start; docs/performance.md).
"""
from __future__ import annotations

import re
from typing import Optional, Sequence, Tuple

from ros_hrc.errors import ModelError

#: Between a state's and its type's name in a composed model's state names (``S3__tired``).
#: Cassandra's grammar allows only letters, digits, ``_`` and ``-`` in a name (SARSOP refuses
#: ``S3@tired``), so the separator is made of those; a single ``-`` or ``_`` would not do,
#: since ordinary names hold them (Tiger's ``tiger-left``, a type ``expert_tired``) and a model
#: of no type would then read as one. A name splits at its last ``__``.
TYPE_SEPARATOR = "__"

#: What a type name may be: words of letters and digits joined by single ``_`` (a human
#: model's file stem), so that ``<state>__<type>`` is a name every model file format allows and
#: splits back unchanged.
TYPE_NAME = re.compile(r"[A-Za-z0-9]+(?:_[A-Za-z0-9]+)*")


def typed_state(state: str, type_name: str) -> str:
    """The composed model's name of ``state`` under ``type_name``."""
    return f"{state}{TYPE_SEPARATOR}{type_name}"


def split_state(name: str) -> Optional[Tuple[str, str]]:
    """(state, type) of a composed state's name, or None for a name of no type."""
    state, sep, type_name = name.rpartition(TYPE_SEPARATOR)
    if not sep or not state or not type_name:
        return None
    return state, type_name


def ranked_types(names: Sequence[str], belief: Sequence[float],
                 limit: Optional[int] = None) -> str:
    """A belief over types as one line, the most likely first: ``tired 0.62, beginner 0.21``;
    with ``limit``, the first ``limit`` and `` ...`` when more were left out."""
    ranked = sorted(zip(names, belief), key=lambda item: -item[1])
    shown = ", ".join(f"{name} {p:.2f}" for name, p in ranked[:limit])
    return shown + (" ..." if limit is not None and len(ranked) > limit else "")


def check_type_name(name: str) -> str:
    """``name``, or ModelError when it cannot name a type in a composed model's state names."""
    if not TYPE_NAME.fullmatch(name):
        raise ModelError(f"type name {name!r} must be letters and digits joined by single '_' (it ends a "
                         f"composed state's name, <state>{TYPE_SEPARATOR}<type>, in model files)")
    return name
