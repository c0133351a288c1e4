"""Cassandra's ``.pomdp`` text format (pomdp.org, pomdp-solve, SARSOP ``examples/POMDP``).

Reading: :func:`load` / :func:`loads`. Writing: :func:`dump` / :func:`save`.

What is read
------------
::

    discount: 0.95                      in [0, 1)
    values: reward | cost
    states: 3 | name name ...           a count N names them s0..s(N-1); actions a0..,
    actions: ... observations: ...      observations o0.. (as POMDPX NumValues)
    start: p p ... | uniform | <state>
    start include: <states>             uniform over the listed states
    start exclude: <states>             uniform over the other states
    T: <a> : <s> : <s'> p    T: <a> : <s>  row | uniform    T: <a>  matrix | identity | uniform
    O: <a> : <s'> : <o> p    O: <a> : <s'> row | uniform    O: <a>  matrix | uniform | identity
    R: <a> : <s> : <s'> : <o> v    R: <a> : <s> : <s'>  row over o    R: <a> : <s>  matrix s' x o

* ``*`` is a wildcard in every position; a state, action or observation is a name or a
  0-based index, and a name wins over an index (so ``states: 1 0`` reads as written).
* Later entries override earlier ones, cell by cell. ``#`` starts a comment; numbers may run
  across lines. Without ``start`` the initial belief is uniform (as pomdp-solve does).
* ``O: <a> identity`` is accepted when there are as many observations as states.
* ``values: cost``: the file's numbers are costs. ``R`` holds rewards = -cost and
  ``Model.minimise`` is set, so solvers maximise ``R`` as always and a value is reported as a
  cost by negating it. :func:`dump` writes such a model back as costs.
* Rewards that depend on the observation are folded into their expectation,
  ``R(s,a,s') = sum_o O(o|s',a) R(s,a,s',o)`` (the model has no observation axis for rewards),
  one observation at a time on R's sparse pattern (observations no statement singles out are
  folded together), never through an S x S x O array.
* A leading UTF-8 byte-order mark is ignored; UTF-16 and UTF-32 files are refused.
* ``R[a]`` keeps every entry the file gives; above
  :data:`~ros_hrc.pomdp.fileformat.FULL_REWARD_STATES` states it is kept only where
  ``T(s'|s,a) > 0`` (elsewhere it can never be earned), so a wildcard reward on a large model
  stays as sparse as ``T``.
* When the observations are the states (same names, same order) and every ``O[a]`` is the
  identity, the model is an MDP: ``fully_observable`` is set.

Checks: no negative probability, every row of ``T``, ``O`` and the start vector sums to one
within :data:`~ros_hrc.pomdp.model.PROBABILITY_TOLERANCE` (1e-4, for tables printed with 3-6
digits), discount in [0, 1), known names, the right count of numbers, every number finite
(``inf``, ``nan``, ``1e999`` are refused) and every reward within
|R| / (1 - discount) <= :data:`~ros_hrc.pomdp.model.MAX_VALUE`. Each failure raises
:class:`~ros_hrc.errors.ModelFormatError` naming the file and the line.

Memory: with ``memory_limit`` (bytes) the reader refuses, with
:class:`~ros_hrc.pomdp.memory.MemoryLimitError`, a file whose tokens, names or tables would
need more, estimated before they are made (a 50,000-state ``T: * uniform`` is 2.5e9 non-zeros).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import ModelError, ModelFormatError
from ros_hrc.pomdp import memory
from ros_hrc.pomdp.fileformat import (FULL_REWARD_STATES, PROBABILITY_TOLERANCE,
                                      check_set_size, check_writable_names, decode_text,
                                      default_names, format_number, is_identity, name_lookup,
                                      read_file, resolve_token, strip_bom, MAX_DIGITS,
                                      is_number_text, shown_token)
from ros_hrc.pomdp.model import Model, reward_bound_problem
from ros_hrc.pomdp.output import write_text_atomically

__all__ = ["load", "loads", "dump", "save"]

_KEYWORDS = frozenset({"discount", "values", "states", "actions", "observations", "start",
                       "T", "O", "R"})
_KINDS = {"states": "state", "actions": "action", "observations": "observation"}
#: Matrices up to this size are written as matrices (readable); larger ones entry by entry.
_MATRIX_LIMIT = 32


def load(path, memory_limit: Optional[int] = None) -> Model:
    """Read a Cassandra ``.pomdp`` file into a :class:`Model` (``memory_limit``: bytes, see
    the module's docstring; None: no check)."""
    path = str(path)
    text = decode_text(read_file(path, memory_limit), path)
    return _Reader(text, path, memory_limit).read()


def loads(text: str, source: str = "<string>", memory_limit: Optional[int] = None) -> Model:
    """Parse Cassandra ``.pomdp`` text; ``source`` names it in error messages."""
    return _Reader(strip_bom(text), source, memory_limit).read()


def save(model: Model, path) -> None:
    """Write ``model`` to ``path`` in Cassandra format (the whole file or nothing)."""
    write_text_atomically(path, dump(model))


# --------------------------------------------------------------------------------------------
# Tokens and statements
# --------------------------------------------------------------------------------------------
@dataclass
class _Statement:
    keyword: str
    line: int
    fields: List[str] = field(default_factory=list)   # T/O/R: action, states, observation
    data: List[str] = field(default_factory=list)
    data_lines: List[int] = field(default_factory=list)
    mode: str = ""                                     # start: "", "include" or "exclude"

    @property
    def header(self) -> str:
        if self.keyword in ("T", "O", "R"):
            return f"{self.keyword}: " + " : ".join(self.fields)
        return f"start {self.mode}:" if self.mode else f"{self.keyword}:"


def _tokenise(text: str) -> Tuple[List[str], List[int]]:
    tokens: List[str] = []
    lines: List[int] = []
    for number, line in enumerate(text.splitlines(), 1):
        if "#" in line:
            line = line.split("#", 1)[0]
        words = line.replace(":", " : ").split()
        if words:
            tokens.extend(words)
            lines.extend([number] * len(words))
    return tokens, lines


def _statements(tokens: List[str], lines: List[int], fail) -> List[_Statement]:
    n = len(tokens)
    # Where a statement may begin: a keyword followed by ':' (or 'start include|exclude').
    # A header field that happens to look like one is skipped below, as fields are read in order.
    starts = [j for j in range(n - 1) if tokens[j] in _KEYWORDS and
              (tokens[j + 1] == ":" or
               (tokens[j] == "start" and tokens[j + 1] in ("include", "exclude")))]
    starts.append(n)
    out: List[_Statement] = []
    i = 0
    k = 0                                   # index into starts
    while i < n:
        if starts[k] != i:
            fail(lines[i], f"expected a statement (discount, values, states, actions, "
                           f"observations, start, T, O or R), found {tokens[i]!r}")
        st = _Statement(tokens[i], lines[i])
        if st.keyword == "start" and tokens[i + 1] in ("include", "exclude"):
            st.mode = tokens[i + 1]
            i += 2
            if i >= n or tokens[i] != ":":
                fail(st.line, f"expected ':' after 'start {st.mode}'")
            i += 1
        else:
            i += 2
        if st.keyword in ("T", "O", "R"):
            # Header fields are read one by one, so a name that is also a keyword still works.
            most = 4 if st.keyword == "R" else 3
            while True:
                if i >= n or tokens[i] == ":":
                    fail(st.line, f"{st.header}: a field is missing")
                st.fields.append(tokens[i])
                i += 1
                if len(st.fields) == most or i >= n or tokens[i] != ":":
                    break
                i += 1
        while starts[k] < i:
            k += 1
        j = starts[k]
        data = tokens[i:j]
        if ":" in data:
            fail(lines[i + data.index(":")], f"unexpected ':' in '{st.header}' (too many fields?)")
        st.data, st.data_lines = data, lines[i:j]
        out.append(st)
        i = j
    return out


# --------------------------------------------------------------------------------------------
# One action's table, written by statements in order
# --------------------------------------------------------------------------------------------
class _Layers:
    """The statements that wrote one action's table (T, O, or R without observations).

    Kept as layers and resolved at the end, so a wildcard or ``identity`` on a large model
    never expands into a dense array: the newest of (whole table or row, column, cell) wins.
    ``seq`` is the statement's position in the file.
    """

    def __init__(self, n_rows: int, n_cols: int) -> None:
        self.n_rows, self.n_cols = n_rows, n_cols
        self.whole: Optional[tuple] = None            # (seq, kind, payload) for every row
        self.row_whole: Dict[int, tuple] = {}          # row -> (seq, kind, payload)
        self.cells: Dict[int, Dict[int, tuple]] = {}   # row -> col -> (seq, value)
        self.col_cells: Dict[int, tuple] = {}          # col -> (seq, value) in every row

    # kinds: whole: dense | identity | uniform | const | rows;  row: vec | uniform | const
    def set_all(self, seq: int, kind: str, payload) -> None:
        self.whole = (seq, kind, payload)
        self.row_whole.clear()
        self.cells.clear()
        self.col_cells.clear()

    def set_row(self, seq: int, row: Optional[int], kind: str, payload) -> None:
        if row is None:
            self.set_all(seq, {"vec": "rows"}.get(kind, kind), payload)
        else:
            self.row_whole[row] = (seq, kind, payload)
            self.cells.pop(row, None)

    def set_cell(self, seq: int, row: Optional[int], col: Optional[int], value: float) -> None:
        if col is None:
            self.set_row(seq, row, "const", value)
        elif row is None:
            self.col_cells[col] = (seq, value)
        else:
            self.cells.setdefault(row, {})[col] = (seq, value)

    def row_seq(self, row: int) -> Optional[int]:
        """The newest statement that wrote to ``row`` (for error messages)."""
        seqs = []
        whole = self.row_whole.get(row, self.whole)
        if whole is not None:
            seqs.append(whole[0])
        seqs.extend(s for s, _ in self.cells.get(row, {}).values())
        seqs.extend(s for s, _ in self.col_cells.values())
        return max(seqs) if seqs else None

    # -- resolution -----------------------------------------------------------------------
    def _whole_pattern(self) -> sp.csr_matrix:
        R, C = self.n_rows, self.n_cols
        if self.whole is None:
            return sp.csr_matrix((R, C))
        _, kind, payload = self.whole
        if kind == "dense":
            return sp.csr_matrix((payload != 0).astype(float))
        if kind == "identity":
            return sp.identity(R, format="csr")
        if kind == "const" and payload == 0:
            return sp.csr_matrix((R, C))
        if kind == "rows":
            used = sp.csr_matrix((payload != 0).astype(float)[None, :])
            return sp.csr_matrix(np.ones((R, 1))) @ used
        # uniform, nonzero const: every cell, built as CSR directly (no dense R x C array)
        return sp.csr_matrix((np.ones(R * C), np.tile(np.arange(C), R),
                              np.arange(R + 1, dtype=np.int64) * C), shape=(R, C))

    def max_nonzeros(self) -> int:
        """An upper bound of the table's non-zeros from the statements alone, so its size can
        be checked before it is built."""
        R, C = self.n_rows, self.n_cols
        total = 0
        if self.whole is not None:
            _, kind, payload = self.whole
            if kind == "dense":
                total = int(np.count_nonzero(payload))
            else:
                if kind == "identity":
                    per_row = 1
                elif kind == "rows":
                    per_row = int(np.count_nonzero(payload))
                elif kind == "const" and payload == 0:
                    per_row = 0
                else:                                  # uniform, nonzero const
                    per_row = C
                total = per_row * (R - len(self.row_whole))
        for _, kind, payload in self.row_whole.values():
            if kind == "vec":
                total += int(np.count_nonzero(payload))
            elif not (kind == "const" and payload == 0):
                total += C
        total += len(self.col_cells) * R + sum(len(c) for c in self.cells.values())
        return min(total, R * C)

    def _cell_arrays(self) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Row, column, statement and value of every single-cell entry, as arrays."""
        rows: List[int] = []
        cols: List[int] = []
        seqs: List[int] = []
        vals: List[float] = []
        for r, cells in self.cells.items():
            for c, (seq, value) in cells.items():
                rows.append(r)
                cols.append(c)
                seqs.append(seq)
                vals.append(value)
        return (np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64),
                np.array(seqs, dtype=np.int64), np.array(vals, dtype=float))

    def pattern(self, cells) -> sp.csr_matrix:
        """Every cell that may be nonzero, as a CSR matrix of ones with sorted indices."""
        R, C = self.n_rows, self.n_cols
        P = self._whole_pattern()
        rows: List[np.ndarray] = [cells[0]]
        cols: List[np.ndarray] = [cells[1]]
        if self.row_whole:
            keep = np.ones(R)
            keep[list(self.row_whole)] = 0.0
            P = sp.diags(keep) @ P
            for r, (_, kind, payload) in self.row_whole.items():
                if kind == "vec":
                    c = np.flatnonzero(payload)
                elif kind == "const" and payload == 0:
                    c = np.empty(0, dtype=np.int64)
                else:
                    c = np.arange(C)
                rows.append(np.full(c.size, r))
                cols.append(c)
        if self.col_cells:
            c = np.fromiter(self.col_cells.keys(), dtype=np.int64, count=len(self.col_cells))
            rows.append(np.repeat(np.arange(R), c.size))
            cols.append(np.tile(c, R))
        r_all = np.concatenate(rows)
        if r_all.size:
            c_all = np.concatenate(cols)
            P = P + sp.csr_matrix((np.ones(r_all.size), (r_all, c_all)), shape=(R, C))
        P = sp.csr_matrix(P)
        P.eliminate_zeros()
        P.sum_duplicates()
        P.sort_indices()
        P.data[:] = 1.0
        return P

    def values_at(self, indptr: np.ndarray, cols: np.ndarray, cells) -> np.ndarray:
        """The table's values at the cells of a CSR structure (sorted column indices)."""
        R, C = self.n_rows, self.n_cols
        rows = np.repeat(np.arange(R), np.diff(indptr))
        vals = np.zeros(cols.size)
        seq_w = np.full(cols.size, -1)
        if self.whole is not None:
            seq, kind, payload = self.whole
            seq_w[:] = seq
            if kind == "dense":
                vals = payload[rows, cols].astype(float)
            elif kind == "identity":
                vals = (rows == cols).astype(float)
            elif kind == "uniform":
                vals[:] = 1.0 / C
            elif kind == "const":
                vals[:] = payload
            else:                                      # rows: one vector for every row
                vals = payload[cols].astype(float)
        for r, (seq, kind, payload) in self.row_whole.items():
            sl = slice(indptr[r], indptr[r + 1])
            seq_w[sl] = seq
            if kind == "vec":
                vals[sl] = payload[cols[sl]]
            elif kind == "uniform":
                vals[sl] = 1.0 / C
            else:
                vals[sl] = payload
        col_seq = np.full(C, -1)
        if self.col_cells:
            col_val = np.zeros(C)
            for c, (seq, value) in self.col_cells.items():
                col_seq[c], col_val[c] = seq, value
            newer = col_seq[cols] > seq_w
            vals[newer] = col_val[cols[newer]]
        cell_rows, cell_cols, cell_seqs, cell_vals = cells
        if cell_rows.size and cols.size:
            # A cell entry is newer than its row's whole-row entry (which clears it) and wins
            # unless a whole-column entry came later.
            keys = rows.astype(np.int64) * C + cols
            want = cell_rows * C + cell_cols
            pos = np.minimum(np.searchsorted(keys, want), keys.size - 1)
            ok = (keys[pos] == want) & (cell_seqs > col_seq[cell_cols])
            vals[pos[ok]] = cell_vals[ok]
        return vals

    def materialise(self, structure: Optional[sp.csr_matrix] = None) -> sp.csr_matrix:
        """The table as CSR: on its own nonzero pattern, or on ``structure``'s cells."""
        cells = self._cell_arrays()
        P = self.pattern(cells) if structure is None else structure
        vals = self.values_at(P.indptr, P.indices, cells)
        out = sp.csr_matrix((vals, P.indices.copy(), P.indptr.copy()),
                            shape=(self.n_rows, self.n_cols))
        out.eliminate_zeros()
        return out


@dataclass
class _Reward:
    seq: int
    action: Optional[int]
    start: Optional[int]
    end: Optional[int]
    obs: Optional[int]
    kind: str            # value | row (over o) | matrix (s' x o)
    payload: object
    line: int = 0

    def applies_to(self, action: int) -> bool:
        return self.action is None or self.action == action

    def write(self, layer: "_Layers", o: int = 0) -> None:
        """Put this statement's R(., ., ., o) into ``layer`` (one observation's S x S' table)."""
        if self.kind == "value":
            if self.obs is None or self.obs == o:
                layer.set_cell(self.seq, self.start, self.end, self.payload)
        elif self.kind == "row":
            layer.set_cell(self.seq, self.start, self.end, float(self.payload[o]))
        else:
            layer.set_row(self.seq, self.start, "vec", self.payload[:, o].copy())

    @property
    def depends_on_observation(self) -> bool:
        if self.kind == "value":
            return self.obs is not None
        if self.kind == "row":
            return bool(np.any(self.payload != self.payload[0]))
        return bool(np.any(self.payload != self.payload[:, :1]))


# --------------------------------------------------------------------------------------------
# The reader
# --------------------------------------------------------------------------------------------
class _Reader:
    def __init__(self, text: str, source: str, memory_limit: Optional[int] = None) -> None:
        self.source = source
        self.memory_limit = memory_limit
        self.text = text
        self.names: Dict[str, List[str]] = {}
        self.lookups: Dict[str, Dict[str, int]] = {}
        self.discount: Optional[float] = None
        self.values = "reward"
        self.values_seen = False
        self.start: Optional[_Statement] = None
        self.T: List[_Layers] = []
        self.O: List[_Layers] = []
        self.rewards: List[_Reward] = []
        self.seq_lines: List[int] = []

    def fail(self, line: Optional[int], what: str):
        raise ModelFormatError(self.source, str(line) if line else None, what)

    # -- driver -----------------------------------------------------------------------------
    def read(self) -> Model:
        tokens, lines = _tokenise(self.text)
        if not tokens:
            self.fail(None, "the file is empty")
        statements = _statements(tokens, lines, self.fail)
        self.seq_lines = [st.line for st in statements]
        for seq, st in enumerate(statements):
            handler = {"discount": self._discount, "values": self._values, "start": self._start,
                       "T": self._transition, "O": self._observation,
                       "R": self._reward}.get(st.keyword)
            if handler is None:
                self._declare(st)
            else:
                handler(st, seq)
        for kind in ("states", "actions", "observations"):
            if kind not in self.names:
                self.fail(None, f"no '{kind}:' line")
        if self.discount is None:
            self.fail(None, "no 'discount:' line")
        return self._build()

    # -- preamble ---------------------------------------------------------------------------
    def _declare(self, st: _Statement) -> None:
        kind = st.keyword
        if kind in self.names:
            self.fail(st.line, f"'{kind}:' is given twice")
        if not st.data:
            self.fail(st.line, f"'{kind}:' needs a count or a list of names")
        if len(st.data) == 1 and st.data[0].isdigit():
            if not is_number_text(st.data[0]):
                self.fail(st.line, f"'{kind}:' count {shown_token(st.data[0])} is not a "
                                   f"count (decimal digits, at most {MAX_DIGITS})")
            count = int(st.data[0])
            if count < 1:
                self.fail(st.line, f"'{kind}:' count must be at least 1, found {count}")
            check_set_size(kind, count, self.memory_limit, self.source, str(st.line))
            names = default_names(kind[0], count)
        else:
            names = list(st.data)
            seen = set()
            for name, line in zip(names, st.data_lines):
                if name in seen:
                    self.fail(line, f"the {_KINDS[kind]} name {name!r} appears twice")
                if name == "*":
                    self.fail(line, f"'*' cannot be a {_KINDS[kind]} name")
                seen.add(name)
        self.names[kind] = names
        self.lookups[kind] = name_lookup(names)

    def _discount(self, st: _Statement, seq: int) -> None:
        if self.discount is not None:
            self.fail(st.line, "'discount:' is given twice")
        value = self._single(st)
        if not 0.0 <= value < 1.0:
            self.fail(st.line, f"discount {format_number(value)} is outside [0, 1)")
        self.discount = value

    def _values(self, st: _Statement, seq: int) -> None:
        if self.values_seen:
            self.fail(st.line, "'values:' is given twice")
        if st.data not in (["reward"], ["cost"]):
            self.fail(st.line, f"'values:' must be 'reward' or 'cost', found {' '.join(st.data)!r}")
        self.values, self.values_seen = st.data[0], True

    def _start(self, st: _Statement, seq: int) -> None:
        if self.start is not None:
            self.fail(st.line, f"a start belief is given twice (first on line {self.start.line})")
        self.start = st

    # -- numbers and names --------------------------------------------------------------------
    def _numbers(self, st: _Statement) -> np.ndarray:
        try:
            arr = np.array(st.data, dtype=float)
        except ValueError:
            for token, line in zip(st.data, st.data_lines):
                try:
                    float(token)
                except ValueError:
                    self.fail(line, f"{st.header} expected a number, found {token!r}")
            raise
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            self.fail(st.data_lines[bad[0]],
                      f"{st.header} has a non-finite number {st.data[bad[0]]!r}")
        return arr

    def _single(self, st: _Statement) -> float:
        if len(st.data) != 1:
            self.fail(st.line, f"{st.header} expects one number, found {len(st.data)}")
        try:
            value = float(st.data[0])
        except ValueError:
            self.fail(st.data_lines[0], f"{st.header} expected a number, found {st.data[0]!r}")
        if not math.isfinite(value):
            self.fail(st.data_lines[0], f"{st.header} has a non-finite number {st.data[0]!r}")
        return value

    def _probability(self, st: _Statement, p: float) -> None:
        if p < 0:
            self.fail(st.data_lines[0], f"{st.header} has a negative probability {p:g}")
        if p > 1.0 + PROBABILITY_TOLERANCE:
            self.fail(st.data_lines[0], f"{st.header} has a probability above 1 ({p:g})")

    def _probabilities(self, st: _Statement, arr: np.ndarray) -> None:
        bad = np.flatnonzero(arr < 0)
        if bad.size:
            line = st.data_lines[bad[0]] if st.data_lines else st.line
            self.fail(line, f"{st.header} has a negative probability {arr[bad[0]]:g}")
        bad = np.flatnonzero(arr > 1.0 + PROBABILITY_TOLERANCE)
        if bad.size:
            line = st.data_lines[bad[0]] if st.data_lines else st.line
            self.fail(line, f"{st.header} has a probability above 1 ({arr[bad[0]]:g})")

    def _need(self, st: _Statement, *kinds: str) -> None:
        for kind in kinds:
            if kind not in self.names:
                self.fail(st.line, f"'{st.keyword}:' comes before '{kind}:' is declared")

    def _select(self, st: _Statement, kind: str, token: str) -> Optional[int]:
        if token == "*":
            return None
        index = resolve_token(token, self.lookups[kind], len(self.names[kind]))
        if index is None:
            self.fail(st.line, f"unknown {_KINDS[kind]} {shown_token(token)!r} in "
                               f"'{shown_token(st.header, 80)}'")
        return index

    def _each(self, kind: str, index: Optional[int]) -> Sequence[int]:
        return range(len(self.names[kind])) if index is None else (index,)

    def _row(self, st: _Statement, width: int, probabilities: bool = True):
        if probabilities and st.data == ["uniform"]:
            return "uniform", None
        arr = self._numbers(st)
        if arr.size != width:
            self.fail(st.line, f"'{st.header}' needs {width} numbers (one row), found {arr.size}")
        if probabilities:
            self._probabilities(st, arr)
        return "vec", arr

    def _matrix(self, st: _Statement, rows: int, cols: int, identity: bool):
        if st.data == ["uniform"]:
            return "uniform", None
        if st.data == ["identity"]:
            if not identity:
                self.fail(st.line, f"'{st.header} identity' needs a square table "
                                   f"({rows} x {cols} is not)")
            return "identity", None
        arr = self._numbers(st)
        if arr.size != rows * cols:
            self.fail(st.line, f"'{st.header}' needs {rows * cols} numbers ({rows} x {cols}), "
                               f"found {arr.size}")
        self._probabilities(st, arr)
        return "dense", arr.reshape(rows, cols)

    # -- T, O, R ---------------------------------------------------------------------------
    def _tables(self) -> None:
        if not self.T:
            S, A, Z = (len(self.names[k]) for k in ("states", "actions", "observations"))
            self.T = [_Layers(S, S) for _ in range(A)]
            self.O = [_Layers(S, Z) for _ in range(A)]

    def _transition(self, st: _Statement, seq: int) -> None:
        self._need(st, "states", "actions", "observations")
        self._tables()
        S = len(self.names["states"])
        action = self._select(st, "actions", st.fields[0])
        if len(st.fields) == 3:
            s, s2 = (self._select(st, "states", f) for f in st.fields[1:])
            p = self._single(st)
            self._probability(st, p)
            for a in self._each("actions", action):
                self.T[a].set_cell(seq, s, s2, p)
        elif len(st.fields) == 2:
            s = self._select(st, "states", st.fields[1])
            kind, payload = self._row(st, S)
            for a in self._each("actions", action):
                self.T[a].set_row(seq, s, kind, payload)
        else:
            kind, payload = self._matrix(st, S, S, identity=True)
            for a in self._each("actions", action):
                self.T[a].set_all(seq, kind, payload)

    def _observation(self, st: _Statement, seq: int) -> None:
        self._need(st, "states", "actions", "observations")
        self._tables()
        S, Z = len(self.names["states"]), len(self.names["observations"])
        action = self._select(st, "actions", st.fields[0])
        if len(st.fields) == 3:
            s2 = self._select(st, "states", st.fields[1])
            o = self._select(st, "observations", st.fields[2])
            p = self._single(st)
            self._probability(st, p)
            for a in self._each("actions", action):
                self.O[a].set_cell(seq, s2, o, p)
        elif len(st.fields) == 2:
            s2 = self._select(st, "states", st.fields[1])
            kind, payload = self._row(st, Z)
            for a in self._each("actions", action):
                self.O[a].set_row(seq, s2, kind, payload)
        else:
            kind, payload = self._matrix(st, S, Z, identity=(S == Z))
            for a in self._each("actions", action):
                self.O[a].set_all(seq, kind, payload)

    def _reward(self, st: _Statement, seq: int) -> None:
        self._need(st, "states", "actions", "observations")
        S, Z = len(self.names["states"]), len(self.names["observations"])
        if len(st.fields) < 2:
            self.fail(st.line, f"'{st.header}' needs at least an action and a start state")
        action = self._select(st, "actions", st.fields[0])
        start = self._select(st, "states", st.fields[1])
        end = self._select(st, "states", st.fields[2]) if len(st.fields) > 2 else None
        obs = self._select(st, "observations", st.fields[3]) if len(st.fields) > 3 else None
        if len(st.fields) == 4:
            kind, payload = "value", self._single(st)
        elif len(st.fields) == 3:
            kind, payload = "row", self._row(st, Z, probabilities=False)[1]
        else:
            arr = self._numbers(st)
            if arr.size != S * Z:
                self.fail(st.line, f"'{st.header}' needs {S * Z} numbers ({S} end states x "
                                   f"{Z} observations), found {arr.size}")
            kind, payload = "matrix", arr.reshape(S, Z)
        self.rewards.append(_Reward(seq, action, start, end, obs, kind, payload, st.line))

    # -- assembling the model ---------------------------------------------------------------
    def _check_rows(self, label: str, a: int, layers: _Layers, table: sp.csr_matrix) -> None:
        sums = np.asarray(table.sum(axis=1)).ravel()
        bad = np.flatnonzero(np.abs(sums - 1.0) > PROBABILITY_TOLERANCE)
        if not bad.size:
            return
        r = int(bad[0])
        seq = layers.row_seq(r)
        action, state = self.names["actions"][a], self.names["states"][r]
        if seq is None:
            self.fail(None, f"{label}: {action} : {state} is never given (its row sums to 0)")
        self.fail(self.seq_lines[seq],
                  f"{label}: {action} : {state} row sums to {sums[r]:.6g}, not 1 "
                  f"(tolerance {PROBABILITY_TOLERANCE:g}; {bad.size} such row(s))")

    def _initial_belief(self) -> np.ndarray:
        S = len(self.names["states"])
        st = self.start
        if st is None:
            return np.full(S, 1.0 / S)
        if st.mode:
            if not st.data:
                self.fail(st.line, f"'start {st.mode}:' needs at least one state")
            mask = np.zeros(S, dtype=bool)
            for token in st.data:
                index = self._select(st, "states", token)
                if index is None:
                    self.fail(st.line, f"'*' is not allowed in 'start {st.mode}:'")
                mask[index] = True
            if st.mode == "exclude":
                mask = ~mask
            if not mask.any():
                self.fail(st.line, "'start exclude:' excludes every state")
            return mask / mask.sum()
        data = st.data
        lookup = self.lookups["states"]
        if data == ["uniform"]:
            return np.full(S, 1.0 / S)
        if len(data) == 1 and data[0] in lookup:
            b = np.zeros(S)
            b[lookup[data[0]]] = 1.0
            return b
        if len(data) == S:
            b = self._numbers(st)
            self._probabilities(st, b)
            if abs(b.sum() - 1.0) > PROBABILITY_TOLERANCE:
                self.fail(st.line, f"start probabilities sum to {b.sum():.6g}, not 1 "
                                   f"(tolerance {PROBABILITY_TOLERANCE:g})")
            return b
        if len(data) == 1 and is_number_text(data[0]) and int(data[0]) < S:
            b = np.zeros(S)                      # a lone index names a state
            b[int(data[0])] = 1.0
            return b
        self.fail(st.line, f"'start:' expects {S} probabilities, 'uniform' or a state; "
                           f"found {len(data)} item(s)")

    def _reward_layers(self) -> List[List[Tuple[List[int], _Layers]]]:
        """Per action, R(s, a, s', o) as layers: (observations, their common S x S' table).

        Without observation-dependent rewards one layer holds every observation. Otherwise each
        observation a statement singles out gets its own layer and the rest share one, so the
        fold costs a table per distinct observation, never an S x S' x O array.
        """
        S, A, Z = (len(self.names[k]) for k in ("states", "actions", "observations"))
        out = []
        for a in range(A):
            mine = [r for r in self.rewards if r.applies_to(a)]
            if not any(r.depends_on_observation for r in mine):
                layer = _Layers(S, S)
                for r in mine:
                    r.write(layer)
                out.append([(list(range(Z)), layer)])
                continue
            if any(r.kind != "value" and r.depends_on_observation for r in mine):
                named = set(range(Z))                 # a row or matrix over o: all differ
            else:
                named = {r.obs for r in mine if r.obs is not None}
            groups = [[o] for o in sorted(named)]
            rest = [o for o in range(Z) if o not in named]
            if rest:
                groups.append(rest)
            layers = []
            for group in groups:
                layer = _Layers(S, S)
                for r in mine:
                    r.write(layer, group[0])
                layers.append((group, layer))
            out.append(layers)
        return out

    def _fold_rewards(self, T: List[sp.csr_matrix], O: List[sp.csr_matrix],
                      layers: List[List[Tuple[List[int], _Layers]]]) -> List[sp.csr_matrix]:
        """R(s, a, s') = Σ_o O(o|s',a) R(s, a, s', o), on the cells the file wrote (small
        models) or where T(s'|s,a) > 0 (above FULL_REWARD_STATES states)."""
        S = len(self.names["states"])
        full = S <= FULL_REWARD_STATES
        out = []
        for a, action_layers in enumerate(layers):
            if len(action_layers) == 1:
                # No observation-dependent reward: the table itself (as it always was read).
                out.append(action_layers[0][1].materialise(None if full else T[a]))
                continue
            cells = [layer._cell_arrays() for _, layer in action_layers]
            if full:
                structure = sum((layer.pattern(c) for (_, layer), c in
                                 zip(action_layers, cells)), sp.csr_matrix((S, S)))
                structure = sp.csr_matrix(structure)
                structure.sort_indices()
            else:
                structure = T[a]
            vals = np.zeros(structure.nnz)
            for (group, layer), c in zip(action_layers, cells):
                weight = np.asarray(O[a][:, group].sum(axis=1)).ravel()    # Σ_o∈group O(o|s')
                vals += weight[structure.indices] * layer.values_at(structure.indptr,
                                                                    structure.indices, c)
            m = sp.csr_matrix((vals, structure.indices.copy(), structure.indptr.copy()),
                              shape=(S, S))
            m.eliminate_zeros()
            out.append(m)
        return out

    def _check_rewards(self) -> None:
        """Every reward finite (the parser refused non-finite numbers) and small enough that
        no value overflows: |R| / (1 - discount) <= MAX_VALUE."""
        for r in self.rewards:
            largest = float(np.max(np.abs(r.payload))) if r.kind != "value" else abs(r.payload)
            problem = reward_bound_problem(largest, self.discount)
            if problem:
                self.fail(r.line, problem)

    def _check_memory(self, layers: List[List[Tuple[List[int], _Layers]]]) -> None:
        """Refuse, before building them, tables that would not fit in the memory limit."""
        if self.memory_limit is None:
            return
        S, A = len(self.names["states"]), len(self.names["actions"])
        t_nnz = [t.max_nonzeros() for t in self.T]
        o_nnz = [o.max_nonzeros() for o in self.O]
        if S <= FULL_REWARD_STATES:
            r_nnz = [min(S * S, sum(layer.max_nonzeros() for _, layer in action_layers))
                     for action_layers in layers]
        else:
            r_nnz = t_nnz
        needed = memory.tables_bytes(t_nnz + o_nnz + r_nnz, S) + memory.model_overhead(S, A)
        memory.require(needed, self.memory_limit, self.source,
                       f"building T, O and R ({sum(t_nnz)}, {sum(o_nnz)} and {sum(r_nnz)} "
                       "non-zeros at most)")

    def _build(self) -> Model:
        states, actions, observations = (self.names[k]
                                         for k in ("states", "actions", "observations"))
        self._tables()
        self._check_rewards()
        reward_layers = self._reward_layers()
        self._check_memory(reward_layers)
        T, O = [], []
        for a in range(len(actions)):
            t = self.T[a].materialise()
            self._check_rows("T", a, self.T[a], t)
            T.append(t)
        for a in range(len(actions)):
            o = self.O[a].materialise()
            self._check_rows("O", a, self.O[a], o)
            O.append(o)
        R = self._fold_rewards(T, O, reward_layers)
        if self.values == "cost":
            R = [-r for r in R]
        fully = observations == states and all(is_identity(o) for o in O)
        name = Path(self.source).stem if self.source != "<string>" else "model"
        model = Model(states=list(states), actions=list(actions), observations=list(observations),
                      discount=float(self.discount), initial_belief=self._initial_belief(),
                      T=T, O=O, R=R, fully_observable=fully, minimise=self.values == "cost",
                      name=name, source=self.source, meta={"format": "cassandra"})
        try:
            model.validate()
        except ModelError as exc:
            raise ModelFormatError(self.source, None, str(exc)) from None
        return model


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------
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
    n, m = matrix.shape
    if n <= _MATRIX_LIMIT and m <= _MATRIX_LIMIT:
        dense = matrix.toarray()
        return [f"{key}: {action}"] + [" ".join(format_number(x) for x in row) for row in dense]
    out = []
    coo = matrix.tocsr()
    coo.sort_indices()
    for r in range(n):
        for k in range(coo.indptr[r], coo.indptr[r + 1]):
            out.append(f"{key}: {action} : {rows[r]} : {cols[coo.indices[k]]} "
                       f"{format_number(coo.data[k])}")
    return out


def dump(model: Model) -> str:
    """The model as Cassandra ``.pomdp`` text; :func:`loads` reads it back to identical tables."""
    source = model.source or model.name or "<model>"
    for kind, names in (("state", model.states), ("action", model.actions),
                        ("observation", model.observations)):
        check_writable_names(kind, names, ":#", source)
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
        r = sp.csr_matrix(model.R[a])
        r.sort_indices()
        for s in range(model.n_states):
            for k in range(r.indptr[s], r.indptr[s + 1]):
                if r.data[k] != 0:
                    lines.append(f"R: {name} : {model.states[s]} : "
                                 f"{model.states[r.indices[k]]} : * "
                                 f"{format_number(sign * r.data[k])}")
    return "\n".join(lines) + "\n"
