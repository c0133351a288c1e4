"""Writing Cassandra's ``.pomdp`` text format (:mod:`ros_hrc.pomdp.cassandra`): :func:`dump` /
:func:`save`.

Numbers are written as the shortest text that reads back exactly, so
:func:`ros_hrc.pomdp.cassandra_reader.loads` gives identical tables. Small tables are written
as matrices, larger ones entry by entry; rewards as ``R: a : s : s' : *`` for each non-zero;
a ``values: cost`` model's rewards as costs again.
"""
from __future__ import annotations

from typing import List, Sequence

import numpy as np
import scipy.sparse as sp

from ros_hrc.pomdp.fileformat import (CASSANDRA_NAME, CASSANDRA_NAME_RULE,
                                      check_writable_model_names, format_number,
                                      stored_entries, written_as_matrix)
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.output import write_text_atomically

__all__ = ["dump", "save"]


def save(model: Model, path) -> None:
    """Write ``model`` to ``path`` in Cassandra format (the whole file or nothing)."""
    write_text_atomically(path, dump(model))


def _wrap(words: Sequence[str], per_line: int = 10) -> List[str]:
    return [" ".join(words[i:i + per_line]) for i in range(0, len(words), per_line)] or [""]


def _start_lines(model: Model) -> List[str]:
    b = np.asarray(model.initial_belief, dtype=float)
    support = np.flatnonzero(b)
    if support.size and np.all(b[support] == 1.0 / support.size):
        if support.size == b.size:
            return ["start: uniform"]
        return ["start include: " + " ".join(model.states[i] for i in support)]
    return ["start:"] + _wrap([format_number(x) for x in b])


def _table_lines(key: str, action: str, matrix: sp.csr_matrix, rows: Sequence[str],
                 cols: Sequence[str]) -> List[str]:
    if written_as_matrix(matrix):
        dense = matrix.toarray()
        return [f"{key}: {action}"] + [" ".join(format_number(x) for x in row) for row in dense]
    return [f"{key}: {action} : {rows[r]} : {cols[c]} {format_number(value)}"
            for r, c, value in stored_entries(matrix)]


def dump(model: Model) -> str:
    """The model as Cassandra ``.pomdp`` text; ``loads`` reads it back to identical tables."""
    check_writable_model_names(model, CASSANDRA_NAME, CASSANDRA_NAME_RULE)
    lines = [f"# {model.name or 'model'}: written by ros_hrc (Cassandra .pomdp format)",
             f"# {model.n_states} states, {model.n_actions} actions, "
             f"{model.n_observations} observations", "",
             f"discount: {format_number(model.discount)}",
             f"values: {'cost' if model.minimise else 'reward'}"]
    for key, names in (("states", model.states), ("actions", model.actions),
                       ("observations", model.observations)):
        wrapped = _wrap(list(names))
        lines.append(f"{key}: {wrapped[0]}")
        lines.extend("    " + w for w in wrapped[1:])
    lines.append("")
    lines.extend(_start_lines(model))
    for key, tables, cols in (("T", model.T, model.states), ("O", model.O, model.observations)):
        lines.append("")
        for a, name in enumerate(model.actions):
            lines.extend(_table_lines(key, name, tables[a], model.states, cols))
    lines.append("")
    sign = -1.0 if model.minimise else 1.0
    for a, name in enumerate(model.actions):
        for s, s2, value in stored_entries(model.R[a]):
            if value != 0:
                lines.append(f"R: {name} : {model.states[s]} : {model.states[s2]} : * "
                             f"{format_number(sign * value)}")
    return "\n".join(lines) + "\n"
