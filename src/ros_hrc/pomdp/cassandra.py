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
  ``R(s,a,s') = sum_o O(o|s',a) R(s,a,s',o)`` (the model has no observation axis for rewards).
* ``R[a]`` keeps every entry the file gives; above
  :data:`~ros_hrc.pomdp.fileformat.FULL_REWARD_STATES` states it is kept only where
  ``T(s'|s,a) > 0`` (elsewhere it can never be earned), so a wildcard reward on a large model
  stays as sparse as ``T``.
* When the observations are the states (same names, same order) and every ``O[a]`` is the
  identity, the model is an MDP: ``fully_observable`` is set.

Checks: no negative probability, every row of ``T``, ``O`` and the start vector sums to one
within :data:`~ros_hrc.pomdp.model.PROBABILITY_TOLERANCE` (1e-4, for tables printed with 3-6
digits), discount in [0, 1), known names, the right count of numbers. Each failure raises
:class:`~ros_hrc.errors.ModelFormatError` naming the file and the line.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import ModelError, ModelFormatError
from ros_hrc.pomdp.fileformat import (FULL_REWARD_STATES, PROBABILITY_TOLERANCE,
                                      check_writable_names, default_names,
                                      format_number, is_identity, name_lookup, resolve_token)
from ros_hrc.pomdp.model import Model

__all__ = ["load", "loads", "dump", "save"]

_KEYWORDS = frozenset({"discount", "values", "states", "actions", "observations", "start",
                       "T", "O", "R"})
_KINDS = {"states": "state", "actions": "action", "observations": "observation"}
#: Observation-dependent rewards are folded through a dense (S, S', O) array per action.
_FOLD_LIMIT = 20_000_000
#: Matrices up to this size are written as matrices (readable); larger ones entry by entry.
_MATRIX_LIMIT = 32


def load(path) -> Model:
    """Read a Cassandra ``.pomdp`` file into a :class:`Model`."""
    path = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise ModelFormatError(path, None, f"cannot read the file: {exc.strerror or exc}") from None
    return loads(text, source=path)


def loads(text: str, source: str = "<string>") -> Model:
    """Parse Cassandra ``.pomdp`` text; ``source`` names it in error messages."""
    return _Reader(text, source).read()


def save(model: Model, path) -> None:
    """Write ``model`` to ``path`` in Cassandra format."""
    Path(path).write_text(dump(model), encoding="utf-8")


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
        return sp.csr_matrix(np.ones((R, C)))          # uniform, nonzero const

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
    def __init__(self, text: str, source: str) -> None:
        self.source = source
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
            count = int(st.data[0])
            if count < 1:
                self.fail(st.line, f"'{kind}:' count must be at least 1, found {count}")
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
            self.fail(st.line, f"unknown {_KINDS[kind]} {token!r} in '{st.header}'")
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
        self.rewards.append(_Reward(seq, action, start, end, obs, kind, payload))

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
        if len(data) == 1 and data[0].isdigit() and int(data[0]) < S:
            b = np.zeros(S)                      # a lone index names a state
            b[int(data[0])] = 1.0
            return b
        self.fail(st.line, f"'start:' expects {S} probabilities, 'uniform' or a state; "
                           f"found {len(data)} item(s)")

    def _fold_rewards(self, T: List[sp.csr_matrix], O: List[sp.csr_matrix]) -> List[sp.csr_matrix]:
        S, A, Z = (len(self.names[k]) for k in ("states", "actions", "observations"))
        if not any(r.depends_on_observation for r in self.rewards):
            layers = [_Layers(S, S) for _ in range(A)]
            for r in self.rewards:
                for a in self._each("actions", r.action):
                    if r.kind == "value":
                        layers[a].set_cell(r.seq, r.start, r.end, r.payload)
                    elif r.kind == "row":
                        layers[a].set_cell(r.seq, r.start, r.end, float(r.payload[0]))
                    else:
                        layers[a].set_row(r.seq, r.start, "vec", r.payload[:, 0].copy())
            full = S <= FULL_REWARD_STATES
            return [layers[a].materialise(None if full else T[a]) for a in range(A)]
        if S * S * Z > _FOLD_LIMIT:
            self.fail(None, f"observation-dependent rewards over {S} x {S} x {Z} cells are too "
                            "large to fold into R(s, a, s')")
        out = []
        for a in range(A):
            grid = np.zeros((S, S, Z))
            for r in self.rewards:
                if r.action is not None and r.action != a:
                    continue
                s = slice(None) if r.start is None else r.start
                s2 = slice(None) if r.end is None else r.end
                o = slice(None) if r.obs is None else r.obs
                if r.kind == "matrix":
                    grid[s, :, :] = r.payload
                else:
                    grid[s, s2, o] = r.payload
            folded = np.einsum("ijo,jo->ij", grid, O[a].toarray())
            if S <= FULL_REWARD_STATES:
                out.append(sp.csr_matrix(folded))
                continue
            rows = np.repeat(np.arange(S), np.diff(T[a].indptr))
            vals = folded[rows, T[a].indices]
            m = sp.csr_matrix((vals, T[a].indices.copy(), T[a].indptr.copy()), shape=(S, S))
            m.eliminate_zeros()
            out.append(m)
        return out

    def _build(self) -> Model:
        states, actions, observations = (self.names[k]
                                         for k in ("states", "actions", "observations"))
        self._tables()
        T, O = [], []
        for a in range(len(actions)):
            t = self.T[a].materialise()
            self._check_rows("T", a, self.T[a], t)
            T.append(t)
        for a in range(len(actions)):
            o = self.O[a].materialise()
            self._check_rows("O", a, self.O[a], o)
            O.append(o)
        R = self._fold_rewards(T, O)
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
