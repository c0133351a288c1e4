"""Reading Cassandra's ``.pomdp`` text format (:mod:`ros_hrc.pomdp.cassandra`): :func:`load` /
:func:`loads`. The text is cut into statements (:mod:`ros_hrc.pomdp.cassandra_statements`);
each action's T, O and R are written by them in order (:mod:`ros_hrc.pomdp.cassandra_tables`)
and resolved at the end.

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
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import ModelFormatError
from ros_hrc.pomdp import memory
from ros_hrc.pomdp.cassandra_statements import Statement, parse_statements, tokenise
from ros_hrc.pomdp.cassandra_tables import Layers, RewardStatement
from ros_hrc.pomdp.fileformat import (FULL_REWARD_STATES, MAX_DIGITS, PROBABILITY_TOLERANCE,
                                      STRING_SOURCE, check_set_size, decode_text,
                                      default_names, discount_problem, first_non_number,
                                      is_identity, is_number_text, model_name, name_lookup,
                                      read_file, resolve_token, shown_token, strip_bom,
                                      validated)
from ros_hrc.pomdp.model import (Model, reward_bound_problem, rows_not_summing_to_one,
                                 sum_problem)

__all__ = ["load", "loads"]

_KINDS = {"states": "state", "actions": "action", "observations": "observation"}


def load(path, memory_limit: Optional[int] = None) -> Model:
    """Read a Cassandra ``.pomdp`` file into a :class:`Model` (``memory_limit``: bytes, see
    the module's docstring; None: no check)."""
    path = str(path)
    text = decode_text(read_file(path, memory_limit), path)
    return _Reader(text, path, memory_limit).read()


def loads(text: str, source: str = STRING_SOURCE, memory_limit: Optional[int] = None) -> Model:
    """Parse Cassandra ``.pomdp`` text; ``source`` names it in error messages."""
    return _Reader(strip_bom(text), source, memory_limit).read()


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
        self.start: Optional[Statement] = None
        self.T: List[Layers] = []
        self.O: List[Layers] = []
        self.rewards: List[RewardStatement] = []
        self.seq_lines: List[int] = []

    def fail(self, line: Optional[int], what: str):
        raise ModelFormatError(self.source, str(line) if line else None, what)

    # -- driver -----------------------------------------------------------------------------
    def read(self) -> Model:
        tokens, lines = tokenise(self.text)
        if not tokens:
            self.fail(None, "the file is empty")
        statements = parse_statements(tokens, lines, self.fail)
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
    def _declare(self, st: Statement) -> None:
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

    def _discount(self, st: Statement, seq: int) -> None:
        if self.discount is not None:
            self.fail(st.line, "'discount:' is given twice")
        value = self._single(st)
        problem = discount_problem(value)
        if problem:
            self.fail(st.line, problem)
        self.discount = value

    def _values(self, st: Statement, seq: int) -> None:
        if self.values_seen:
            self.fail(st.line, "'values:' is given twice")
        if st.data not in (["reward"], ["cost"]):
            self.fail(st.line, f"'values:' must be 'reward' or 'cost', found {' '.join(st.data)!r}")
        self.values, self.values_seen = st.data[0], True

    def _start(self, st: Statement, seq: int) -> None:
        if self.start is not None:
            self.fail(st.line, f"a start belief is given twice (first on line {self.start.line})")
        self.start = st

    # -- numbers and names --------------------------------------------------------------------
    def _numbers(self, st: Statement) -> np.ndarray:
        try:
            arr = np.array(st.data, dtype=float)
        except ValueError:
            k = first_non_number(st.data)
            if k is None:
                raise
            self.fail(st.data_lines[k], f"{st.header} expected a number, found {st.data[k]!r}")
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            self.fail(st.data_lines[bad[0]],
                      f"{st.header} has a non-finite number {st.data[bad[0]]!r}")
        return arr

    def _single(self, st: Statement) -> float:
        if len(st.data) != 1:
            self.fail(st.line, f"{st.header} expects one number, found {len(st.data)}")
        try:
            value = float(st.data[0])
        except ValueError:
            self.fail(st.data_lines[0], f"{st.header} expected a number, found {st.data[0]!r}")
        if not math.isfinite(value):
            self.fail(st.data_lines[0], f"{st.header} has a non-finite number {st.data[0]!r}")
        return value

    def _probability(self, st: Statement, p: float) -> None:
        if p < 0:
            self.fail(st.data_lines[0], f"{st.header} has a negative probability {p:g}")
        if p > 1.0 + PROBABILITY_TOLERANCE:
            self.fail(st.data_lines[0], f"{st.header} has a probability above 1 ({p:g})")

    def _probabilities(self, st: Statement, arr: np.ndarray) -> None:
        bad = np.flatnonzero(arr < 0)
        if bad.size:
            line = st.data_lines[bad[0]] if st.data_lines else st.line
            self.fail(line, f"{st.header} has a negative probability {arr[bad[0]]:g}")
        bad = np.flatnonzero(arr > 1.0 + PROBABILITY_TOLERANCE)
        if bad.size:
            line = st.data_lines[bad[0]] if st.data_lines else st.line
            self.fail(line, f"{st.header} has a probability above 1 ({arr[bad[0]]:g})")

    def _need(self, st: Statement, *kinds: str) -> None:
        for kind in kinds:
            if kind not in self.names:
                self.fail(st.line, f"'{st.keyword}:' comes before '{kind}:' is declared")

    def _select(self, st: Statement, kind: str, token: str) -> Optional[int]:
        if token == "*":
            return None
        index = resolve_token(token, self.lookups[kind], len(self.names[kind]))
        if index is None:
            self.fail(st.line, f"unknown {_KINDS[kind]} {shown_token(token)!r} in "
                               f"'{shown_token(st.header, 80)}'")
        return index

    def _each(self, kind: str, index: Optional[int]) -> Sequence[int]:
        return range(len(self.names[kind])) if index is None else (index,)

    def _row(self, st: Statement, width: int, probabilities: bool = True):
        if probabilities and st.data == ["uniform"]:
            return "uniform", None
        arr = self._numbers(st)
        if arr.size != width:
            self.fail(st.line, f"'{st.header}' needs {width} numbers (one row), found {arr.size}")
        if probabilities:
            self._probabilities(st, arr)
        return "vec", arr

    def _matrix(self, st: Statement, rows: int, cols: int, identity: bool):
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
            self.T = [Layers(S, S) for _ in range(A)]
            self.O = [Layers(S, Z) for _ in range(A)]

    def _transition(self, st: Statement, seq: int) -> None:
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

    def _observation(self, st: Statement, seq: int) -> None:
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

    def _reward(self, st: Statement, seq: int) -> None:
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
        self.rewards.append(RewardStatement(seq, action, start, end, obs, kind, payload, st.line))

    # -- assembling the model ---------------------------------------------------------------
    def _check_rows(self, label: str, a: int, layers: Layers, table: sp.csr_matrix) -> None:
        sums = np.asarray(table.sum(axis=1)).ravel()
        bad = rows_not_summing_to_one(sums)
        if not bad.size:
            return
        r = int(bad[0])
        seq = layers.row_seq(r)
        action, state = self.names["actions"][a], self.names["states"][r]
        if seq is None:
            self.fail(None, f"{label}: {action} : {state} is never given (its row sums to 0)")
        self.fail(self.seq_lines[seq],
                  f"{label}: {action} : {state} row {sum_problem(sums[r], bad.size)}")

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

    def _reward_layers(self) -> List[List[Tuple[List[int], Layers]]]:
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
                layer = Layers(S, S)
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
                layer = Layers(S, S)
                for r in mine:
                    r.write(layer, group[0])
                layers.append((group, layer))
            out.append(layers)
        return out

    def _fold_rewards(self, T: List[sp.csr_matrix], O: List[sp.csr_matrix],
                      layers: List[List[Tuple[List[int], Layers]]]) -> List[sp.csr_matrix]:
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
            cells = [layer.cell_arrays() for _, layer in action_layers]
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

    def _check_memory(self, layers: List[List[Tuple[List[int], Layers]]]) -> None:
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
        model = Model(states=list(states), actions=list(actions), observations=list(observations),
                      discount=float(self.discount), initial_belief=self._initial_belief(),
                      T=T, O=O, R=R, fully_observable=fully, minimise=self.values == "cost",
                      name=model_name(self.source), source=self.source,
                      meta={"format": "cassandra"})
        return validated(model, self.source)

