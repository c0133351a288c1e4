"""POMDPX (SARSOP ``doc/POMDPX``, version 1.0): read and write.

Reading: :func:`load` / :func:`loads`. Writing: :func:`dump` / :func:`save`.

The XML is parsed with :mod:`defusedxml`: a document that declares entities (the "billion
laughs") or refers to external ones is refused, never expanded.

What is read
------------
* ``<StateVar vnamePrev vnameCurr fullyObs>``, ``<ObsVar vname>``, one ``<ActionVar vname>``,
  ``<RewardVar vname>``; values as ``<ValueEnum>`` or ``<NumValues>`` (n values named
  ``s0..``, ``o0..``, ``a0..`` for state, observation and action variables).
* ``<InitialStateBelief>``, ``<StateTransitionFunction>`` and ``<ObsFunction>`` as ``<CondProb>``
  (``<Var>``, ``<Parent>`` list or ``null``, ``<Parameter type="TBL">``), ``<RewardFunction>``
  as one or more ``<Func>`` whose values are summed.
* ``<Entry><Instance>`` lists a value (name or 0-based index), ``*`` (every value, the same
  numbers) or ``-`` (every value, numbers enumerated row-major over the ``-`` positions) for
  each parent and then the variable. ``<ProbTable>`` holds numbers, ``identity`` (two ``-``
  positions of one size) or ``uniform``; ``<ValueTable>`` holds numbers. Later entries
  override earlier ones.
* Rewards may depend on the action and on previous *and* next state variables
  (the seed's human model rewards ``R(action, state_1)``), and on observation variables: the
  flat ``R(s, a, s')`` is then the expectation over the observation given (a, s'),
  Σ_o O(o | s', a) R(a, s, s', o), as SARSOP reads it.
* Malformed XML is reported at expat's line, in words where expat only says "invalid
  token": a comment opened inside another one, ``--`` inside a comment. A word of a table that
  is not a number is reported at its own line (a table may span many).

How a factored file becomes one flat model
------------------------------------------
* States are the product of the state variables in declaration order, the first variable
  most significant; a joint state is named by its values joined with ``_`` (one variable: its
  own value names). ``T[a]`` is built per action as a row-wise Kronecker product of the
  per-variable conditional tables, in sparse form: never a dense S x S array, so SARSOP's
  RockSample_7_8 (50 x 2^8 = 12,800 joint states; SARSOP counts 12,545 after merging the
  terminal states) reads in about a second.
* Observability: when every state variable is ``fullyObs``, the model is an MDP:
  ``fully_observable`` is set, the observations are the states and ``O`` is the identity
  (an ``<ObsFunction>`` is then ignored). With mixed observability the fully observable
  variables become part of the observation: the observation is the product of the fully
  observable state variables' next values and the observation variables, in declaration
  order, named as joint states are. A model with neither has the single observation ``none``.
  Either way ``observed_key`` numbers the fully observable variables' joint value of each
  state (an MDP: the state itself), so that a run and the solvers know it from the start, as
  SARSOP does; it is None when no state variable is ``fullyObs``.
* ``R[a]`` keeps every (s, s') up to
  :data:`~ros_hrc.pomdp.fileformat.FULL_REWARD_STATES` states, and only the cells where
  ``T(s'|s,a) > 0`` above it.
* Checks: every conditional table sums to one over its variable for every parent value
  (within :data:`~ros_hrc.pomdp.model.PROBABILITY_TOLERANCE`), no negative probability,
  discount in [0, 1), known names, the right count of numbers, every number finite (``inf``,
  ``nan``, ``1e999`` are refused), every reward -- each ``<Func>``'s and their sum -- within
  |R| / (1 - discount) <= :data:`~ros_hrc.pomdp.model.MAX_VALUE`. A failure raises
  :class:`~ros_hrc.errors.ModelFormatError` with the file and the line of the element.
* A leading byte-order mark is accepted (expat reads it as the XML standard says), from
  bytes or from text.
* Memory: with ``memory_limit`` (bytes) the reader refuses, with
  :class:`~ros_hrc.pomdp.memory.MemoryLimitError`, a file, a variable's value count, the
  conditional tables or the flat T, O and R whose size would exceed it, estimated (the flat
  tables' non-zeros exactly, from the factors' rows) before they are made.

Writing
-------
:func:`dump` writes a flat model: one state variable (``state_0``/``state_1``), one action
variable, one observation variable (none for an MDP, whose state variable is ``fullyObs``),
one reward function over (action, state_0, state_1). Names come from the model's own POMDPX
variables when it was read from a one-variable file. A ``values: cost`` model is marked
``[values: cost]`` in the ``<Description>`` (rewards are still written as rewards = -cost) so
the flag survives a round trip. A model with mixed observability is written as a POMDP whose
observation still carries the fully observed values after each step, but its ``observed_key``
is not kept: read back, the start is no longer conditioned on them.
"""
from __future__ import annotations

import itertools
import re
from dataclasses import dataclass, field
from functools import reduce
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple, Union
from xml.sax.saxutils import escape, quoteattr

import numpy as np
import scipy.sparse as sp
from defusedxml import DefusedXmlException
from defusedxml.ElementTree import DefusedXMLParser, ParseError

from ros_hrc.errors import ModelError, ModelFormatError
from ros_hrc.pomdp import memory
from ros_hrc.pomdp.fileformat import (FULL_REWARD_STATES, PROBABILITY_TOLERANCE,
                                      check_set_size, check_writable_names, default_names,
                                      format_number, is_identity, joint_names, name_lookup,
                                      read_file, resolve_token, strip_bom, MAX_DIGITS,
                                      is_number_text, shown_token)
from ros_hrc.pomdp.model import Model, reward_bound_problem
from ros_hrc.pomdp.output import write_text_atomically

__all__ = ["load", "loads", "dump", "save", "rowwise_kron"]

#: Conditional tables up to this many cells are dense arrays; larger ones are kept sparse.
_DENSE_CELLS = 5_000_000
#: One <Entry> may not expand to more cells than this (a '*' over a huge flat variable).
_ENTRY_CELLS = 20_000_000
_MAX_STATES = 2_000_000
_COST_MARK = "[values: cost]"
_DEFAULT_NAMES = {"state_prev": "state_0", "state_curr": "state_1", "action": "action_agent",
                  "observation": "obs_agent", "reward": "reward_agent"}


def load(path, memory_limit: Optional[int] = None) -> Model:
    """Read a POMDPX file into a :class:`Model` (``memory_limit``: bytes, see the module's
    docstring; None: no check)."""
    path = str(path)
    data = read_file(path, memory_limit)
    return _Reader(_parse_xml(data, path), path, memory_limit).read()


def loads(text: Union[str, bytes], source: str = "<string>",
          memory_limit: Optional[int] = None) -> Model:
    """Parse POMDPX text; ``source`` names it in error messages."""
    if isinstance(text, str):
        text = strip_bom(text)
    return _Reader(_parse_xml(text, source), source, memory_limit).read()


def save(model: Model, path) -> None:
    """Write ``model`` to ``path`` as POMDPX (the whole file or nothing)."""
    write_text_atomically(path, dump(model))


# --------------------------------------------------------------------------------------------
# XML with line numbers, parsed safely
# --------------------------------------------------------------------------------------------
class _LineNumberingParser(DefusedXMLParser):
    """defusedxml's parser, recording each element's line (``elem.line``) for messages."""

    def _start(self, *args):
        elem = super()._start(*args)
        elem.line = self.parser.CurrentLineNumber
        return elem


def _parse_xml(text: Union[str, bytes], source: str):
    parser = _LineNumberingParser()
    try:
        parser.feed(text)
        return parser.close()
    except DefusedXmlException as exc:
        line = parser.parser.CurrentLineNumber
        raise ModelFormatError(source, str(line), f"unsafe XML refused ({type(exc).__name__}): "
                                                  "entity declarations and external references "
                                                  "are not allowed") from None
    except ParseError as exc:
        position = getattr(exc, "position", None)
        line = position[0] if position else None
        what = re.sub(r": line \d+, column \d+$", "", str(exc))
        hint = _xml_error_hint(text, *position) if position else None
        raise ModelFormatError(source, str(line) if line else None,
                               f"malformed XML: {hint or what}") from None


def _xml_error_hint(text: Union[str, bytes], line: int, column: int) -> Optional[str]:
    """What is wrong at expat's error position, in words, for the mistakes expat only calls an
    "invalid token": a comment opened inside another one (XML comments do not nest; SARSOP's
    reader accepts them) and ``--`` inside a comment. None when it is something else."""
    if isinstance(text, bytes):
        text = text.decode("utf-8", errors="replace")
    lines = text.split("\n")
    if not 1 <= line <= len(lines):
        return None
    offset = sum(len(l) + 1 for l in lines[:line - 1]) + column
    # expat stops right after the "--" it refuses.
    if text[max(0, offset - 2):offset] != "--":
        return None
    opened = text.rfind("<!--", 0, offset - 2)
    if opened < 0 or text.find("-->", opened + 4, offset - 2) >= 0:
        return None                 # not inside a comment
    opened_line = text.count("\n", 0, opened) + 1
    if text[max(0, offset - 4):offset] == "<!--":
        return (f"a comment is opened inside another comment (the one opened on line "
                f"{opened_line}): XML comments do not nest; close the first with '-->' "
                f"before opening another")
    return (f"'--' inside a comment (opened on line {opened_line}): XML does not allow two "
            f"hyphens in a row within a comment")


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _kids(elem, tag: Optional[str] = None) -> list:
    return [c for c in elem if isinstance(c.tag, str) and (tag is None or _local(c.tag) == tag)]


# --------------------------------------------------------------------------------------------
# Variables and conditional tables
# --------------------------------------------------------------------------------------------
@dataclass
class _Var:
    name: str
    role: str                 # prev | curr | obs | action | reward
    index: int                # which state / observation variable
    values: List[str]
    lookup: Dict[str, int] = field(default_factory=dict)

    @property
    def size(self) -> int:
        return len(self.values)


class _DenseTable:
    """A conditional table as a numpy array (axes: parents, then the variable)."""

    def __init__(self, shape: Tuple[int, ...]) -> None:
        self.shape = shape
        self.data = np.zeros(shape)
        self._csr: Optional[sp.csr_matrix] = None

    def assign(self, selection: List[Optional[int]], values: np.ndarray) -> None:
        index = tuple(slice(None) if s is None else s for s in selection)
        self.data[index] = values
        self._csr = None

    def finish(self) -> None:
        pass

    def last_axis_sums(self) -> np.ndarray:
        return self.data.reshape(-1, self.shape[-1]).sum(axis=1)

    def negatives(self) -> np.ndarray:
        return np.flatnonzero(self.data.ravel() < 0)

    def rows(self, configs: np.ndarray) -> sp.csr_matrix:
        # Rows picked from the table as CSR: picked from the dense table they would make an
        # (S, values) array, 100 MB for 50,000 states of a 250-valued variable.
        if self._csr is None:
            self._csr = sp.csr_matrix(self.data.reshape(-1, self.shape[-1]))
        return self._csr[configs]

    def row_nonzeros(self) -> np.ndarray:
        """Non-zeros of each parent configuration's row."""
        return np.count_nonzero(self.data.reshape(-1, self.shape[-1]), axis=1)

    def gather(self, flat: np.ndarray) -> np.ndarray:
        return self.data.ravel()[flat]


class _SparseTable:
    """A conditional table too large to be dense: the cells entries wrote, last write wins."""

    def __init__(self, shape: Tuple[int, ...]) -> None:
        self.shape = shape
        self.strides = np.array([int(np.prod(shape[k + 1:])) for k in range(len(shape))],
                                dtype=np.int64)
        self.parts: List[Tuple[np.ndarray, np.ndarray]] = []
        self.flat = np.empty(0, dtype=np.int64)
        self.vals = np.empty(0)

    def assign(self, selection: List[Optional[int]], values: np.ndarray) -> None:
        free = [k for k, s in enumerate(selection) if s is None]
        flat = np.int64(sum(int(s) * int(self.strides[k]) for k, s in enumerate(selection)
                            if s is not None))
        grids = np.zeros([self.shape[k] for k in free], dtype=np.int64) + flat
        for pos, k in enumerate(free):
            shape = [1] * len(free)
            shape[pos] = self.shape[k]
            axis = np.arange(self.shape[k], dtype=np.int64) * self.strides[k]
            grids = grids + axis.reshape(shape)
        values = np.broadcast_to(values, grids.shape)
        self.parts.append((grids.ravel(), np.array(values, dtype=float).ravel()))

    def finish(self) -> None:
        if not self.parts:
            return
        flat = np.concatenate([p[0] for p in self.parts])[::-1]
        vals = np.concatenate([p[1] for p in self.parts])[::-1]
        self.flat, first = np.unique(flat, return_index=True)   # first in reverse = last written
        self.vals = vals[first]
        self.parts = []

    def last_axis_sums(self) -> np.ndarray:
        n_cfg = int(np.prod(self.shape[:-1]))
        return np.bincount(self.flat // self.shape[-1], weights=self.vals, minlength=n_cfg)

    def negatives(self) -> np.ndarray:
        return self.flat[self.vals < 0]

    def row_nonzeros(self) -> np.ndarray:
        """Non-zeros of each parent configuration's row."""
        n_cfg = int(np.prod(self.shape[:-1]))
        return np.bincount(self.flat // self.shape[-1], weights=self.vals != 0,
                           minlength=n_cfg).astype(np.int64)

    def rows(self, configs: np.ndarray) -> sp.csr_matrix:
        n = self.shape[-1]
        starts = np.searchsorted(self.flat, configs.astype(np.int64) * n)
        ends = np.searchsorted(self.flat, (configs.astype(np.int64) + 1) * n)
        counts = ends - starts
        indptr = np.concatenate([[0], np.cumsum(counts)])
        offsets = np.arange(indptr[-1]) - np.repeat(indptr[:-1], counts)
        pos = np.repeat(starts, counts) + offsets
        return sp.csr_matrix((self.vals[pos], self.flat[pos] % n, indptr),
                             shape=(configs.size, n))

    def gather(self, flat: np.ndarray) -> np.ndarray:
        pos = np.searchsorted(self.flat, flat)
        pos = np.minimum(pos, max(self.flat.size - 1, 0))
        out = np.zeros(flat.size)
        if self.flat.size:
            hit = self.flat[pos] == flat
            out[hit] = self.vals[pos[hit]]
        return out


@dataclass
class _Factor:
    """One <CondProb> or <Func>: its variable, parents and table."""
    var: Optional[_Var]       # None for a reward <Func>
    parents: List[_Var]
    table: object
    line: Optional[int]
    label: str

    @property
    def axes(self) -> List[_Var]:
        return self.parents + ([self.var] if self.var is not None else [])


def rowwise_kron(A: sp.csr_matrix, B: sp.csr_matrix) -> sp.csr_matrix:
    """Row-wise Kronecker product: ``C[s, i * n + j] = A[s, i] * B[s, j]`` (sparse, no loops).

    For factored transitions: if row s of A is P(x'|s) and of B is P(y'|s), row s of C is the
    joint P(x', y'|s) with x the more significant variable.
    """
    A = sp.csr_matrix(A)
    B = sp.csr_matrix(B)
    A.eliminate_zeros()
    B.eliminate_zeros()
    A.sort_indices()
    B.sort_indices()
    S, n = A.shape[0], B.shape[1]
    na, nb = np.diff(A.indptr), np.diff(B.indptr)
    row_of_a = np.repeat(np.arange(S), na)
    reps = nb[row_of_a]
    a_pos = np.repeat(np.arange(A.nnz), reps)
    group_start = np.repeat(np.cumsum(reps) - reps, reps)
    b_pos = np.repeat(B.indptr[row_of_a], reps) + (np.arange(int(reps.sum())) - group_start)
    data = A.data[a_pos] * B.data[b_pos]
    cols = A.indices[a_pos].astype(np.int64) * n + B.indices[b_pos]
    indptr = np.concatenate([[0], np.cumsum(na * nb)])
    out = sp.csr_matrix((data, cols, indptr), shape=(S, A.shape[1] * n))
    out.eliminate_zeros()
    return out


# --------------------------------------------------------------------------------------------
# The reader
# --------------------------------------------------------------------------------------------
class _Reader:
    def __init__(self, root, source: str, memory_limit: Optional[int] = None) -> None:
        self.root = root
        self.source = source
        self.memory_limit = memory_limit
        self.discount = 0.0
        self.table_bytes = 0            # what the conditional tables read so far hold
        self.vars: Dict[str, _Var] = {}
        self.state_vars: List[Tuple[_Var, _Var, bool]] = []     # (prev, curr, fully observed)
        self.obs_vars: List[_Var] = []
        self.action: Optional[_Var] = None
        self.reward_vars: List[_Var] = []

    def fail(self, elem, what: str):
        line = getattr(elem, "line", None) if elem is not None else None
        where = str(line) if line else (f"<{_local(elem.tag)}>" if elem is not None else None)
        raise ModelFormatError(self.source, where, what)

    def fail_at_word(self, elem, k: int, what: str):
        """Fail naming the line of the ``k``-th word of ``elem``'s text (a table's numbers
        may span many lines below its tag)."""
        line = getattr(elem, "line", None)
        text = elem.text or ""
        if line:
            words = re.finditer(r"\S+", text)
            start = next((m.start() for i, m in enumerate(words) if i == k), 0)
            line += text.count("\n", 0, start)
            raise ModelFormatError(self.source, str(line), what)
        self.fail(elem, what)

    def _one(self, parent, tag: str, required: bool = True):
        found = _kids(parent, tag)
        if len(found) > 1:
            self.fail(found[1], f"<{_local(parent.tag)}> has more than one <{tag}>")
        if not found:
            if required:
                self.fail(parent, f"<{_local(parent.tag)}> has no <{tag}>")
            return None
        return found[0]

    # -- driver -----------------------------------------------------------------------------
    def read(self) -> Model:
        root = self.root
        if _local(root.tag) != "pomdpx":
            self.fail(root, f"the root element is <{_local(root.tag)}>, not <pomdpx>")
        known = {"Description", "Discount", "Variable", "InitialStateBelief",
                 "StateTransitionFunction", "ObsFunction", "RewardFunction"}
        for child in _kids(root):
            if _local(child.tag) not in known:
                self.fail(child, f"unknown element <{_local(child.tag)}> in <pomdpx>")
        discount = self.discount = self._discount()
        self._variables(self._one(root, "Variable"))
        description = self._one(root, "Description", required=False)
        minimise = description is not None and _COST_MARK in (description.text or "")

        init = self._factors(self._one(root, "InitialStateBelief"), "CondProb", "initial")
        trans = self._factors(self._one(root, "StateTransitionFunction"), "CondProb", "transition")
        fully = all(fo for _, _, fo in self.state_vars)
        obs_elem = self._one(root, "ObsFunction", required=False)
        obs: List[_Factor] = []
        if self.obs_vars and not fully:
            if obs_elem is None:
                self.fail(root, "<pomdpx> has observation variables but no <ObsFunction>")
            obs = self._factors(obs_elem, "CondProb", "observation")
        reward_elem = self._one(root, "RewardFunction", required=False)
        rewards = self._factors(reward_elem, "Func", "reward") if reward_elem is not None else []
        return self._build(discount, minimise, fully, init, trans, obs, rewards)

    def _discount(self) -> float:
        elem = self._one(self.root, "Discount")
        try:
            value = float((elem.text or "").strip())
        except ValueError:
            self.fail(elem, f"<Discount> is not a number: {(elem.text or '').strip()!r}")
        if not 0.0 <= value < 1.0:
            self.fail(elem, f"discount {format_number(value)} is outside [0, 1)")
        return value

    # -- <Variable> --------------------------------------------------------------------------
    def _values(self, elem, prefix: str) -> List[str]:
        enum = self._one(elem, "ValueEnum", required=False)
        num = self._one(elem, "NumValues", required=False)
        if (enum is None) == (num is None):
            self.fail(elem, f"<{_local(elem.tag)}> needs exactly one of <ValueEnum> or <NumValues>")
        if enum is not None:
            values = (enum.text or "").split()
            if not values:
                self.fail(enum, "<ValueEnum> is empty")
            seen = set()
            for v in values:
                if v in seen:
                    self.fail(enum, f"the value {v!r} appears twice in <ValueEnum>")
                if v in ("*", "-"):
                    self.fail(enum, f"{v!r} cannot be a value name")
                seen.add(v)
            return values
        text = (num.text or "").strip()
        if not is_number_text(text) or int(text) < 1:
            self.fail(num, f"<NumValues> must be a positive integer of at most {MAX_DIGITS} "
                           f"digits, found {shown_token(text)!r}")
        check_set_size("values", int(text), self.memory_limit, self.source,
                       str(getattr(num, "line", "")) or None)
        return default_names(prefix, int(text))

    def _attr(self, elem, name: str) -> str:
        value = elem.get(name)
        if not value:
            self.fail(elem, f"<{_local(elem.tag)}> has no {name}= attribute")
        return value

    def _add_var(self, elem, var: _Var) -> _Var:
        if var.name in self.vars:
            self.fail(elem, f"the variable name {var.name!r} is used twice")
        var.lookup = name_lookup(var.values)
        self.vars[var.name] = var
        return var

    def _variables(self, elem) -> None:
        for child in _kids(elem):
            tag = _local(child.tag)
            if tag == "StateVar":
                values = self._values(child, "s")
                flag = (child.get("fullyObs") or "false").strip().lower()
                if flag not in ("true", "false"):
                    self.fail(child, f"fullyObs must be 'true' or 'false', found {flag!r}")
                i = len(self.state_vars)
                prev = self._add_var(child, _Var(self._attr(child, "vnamePrev"), "prev", i, values))
                curr = self._add_var(child, _Var(self._attr(child, "vnameCurr"), "curr", i, values))
                self.state_vars.append((prev, curr, flag == "true"))
            elif tag == "ObsVar":
                var = _Var(self._attr(child, "vname"), "obs", len(self.obs_vars),
                           self._values(child, "o"))
                self.obs_vars.append(self._add_var(child, var))
            elif tag == "ActionVar":
                if self.action is not None:
                    self.fail(child, "only one <ActionVar> is supported")
                self.action = self._add_var(child, _Var(self._attr(child, "vname"), "action", 0,
                                                        self._values(child, "a")))
            elif tag == "RewardVar":
                self.reward_vars.append(self._add_var(child, _Var(self._attr(child, "vname"),
                                                                  "reward", 0, [])))
            else:
                self.fail(child, f"unknown element <{tag}> in <Variable>")
        if not self.state_vars:
            self.fail(elem, "<Variable> declares no <StateVar>")
        if self.action is None:
            self.fail(elem, "<Variable> declares no <ActionVar>")

    # -- functions ---------------------------------------------------------------------------
    _VAR_ROLES = {"initial": ("prev", "curr"), "transition": ("curr",), "observation": ("obs",),
                  "reward": ("reward",)}
    _PARENT_ROLES = {"initial": ("prev", "curr"), "transition": ("action", "prev"),
                     "observation": ("action", "curr"),
                     "reward": ("action", "prev", "curr", "obs")}

    def _factors(self, elem, tag: str, kind: str) -> List[_Factor]:
        out = []
        for child in _kids(elem):
            if _local(child.tag) != tag:
                self.fail(child, f"unexpected <{_local(child.tag)}> in <{_local(elem.tag)}> "
                                 f"(expected <{tag}>)")
            out.append(self._factor(child, kind))
        return out

    def _factor(self, elem, kind: str) -> _Factor:
        var_elem = self._one(elem, "Var")
        names = (var_elem.text or "").split()
        if len(names) != 1:
            self.fail(var_elem, f"<Var> must name exactly one variable, found {len(names)}")
        var = self.vars.get(names[0])
        if var is None:
            self.fail(var_elem, f"unknown variable {names[0]!r}")
        if var.role not in self._VAR_ROLES[kind]:
            self.fail(var_elem,
                      f"{var.name!r} ({var.role}) cannot be the <Var> of a {kind} function")
        parent_elem = self._one(elem, "Parent", required=kind != "initial")
        parent_names = (parent_elem.text or "").split() if parent_elem is not None else []
        if parent_names == ["null"]:
            parent_names = []
        parents = []
        for name in parent_names:
            p = self.vars.get(name)
            if p is None:
                self.fail(parent_elem, f"unknown parent variable {name!r}")
            if p.role not in self._PARENT_ROLES[kind] or p is var or \
                    (kind == "initial" and p.index == var.index):
                hint = (" (a next-state variable depending on another next-state variable is not "
                        "supported)" if kind == "transition" and p.role == "curr" else "")
                self.fail(parent_elem, f"{name!r} ({p.role}) cannot be a parent in a {kind} "
                                       f"function{hint}")
            if p in parents:
                self.fail(parent_elem, f"parent {name!r} is listed twice")
            parents.append(p)
        label = f"<{_local(elem.tag)}> for {var.name}"
        axes = parents + ([] if kind == "reward" else [var])
        shape = tuple(v.size for v in axes) or (1,)
        cells = int(np.prod(shape))
        if cells <= _DENSE_CELLS:
            self._table_memory(elem, 8 * cells)
        table = _DenseTable(shape) if cells <= _DENSE_CELLS else _SparseTable(shape)
        param = self._one(elem, "Parameter")
        ptype = (param.get("type") or "TBL").strip()
        if ptype != "TBL":
            self.fail(param, f"<Parameter type={ptype!r}> is not supported (only TBL)")
        value_tag = "ValueTable" if kind == "reward" else "ProbTable"
        for entry in _kids(param):
            if _local(entry.tag) != "Entry":
                self.fail(entry, f"unexpected <{_local(entry.tag)}> in <Parameter>")
            self._entry(entry, axes, table, value_tag, label, probabilities=kind != "reward")
        table.finish()
        factor = _Factor(None if kind == "reward" else var, parents, table,
                         getattr(elem, "line", None), label)
        if kind != "reward":
            self._check_normalised(elem, factor)
        return factor

    def _entry(self, entry, axes: List[_Var], table, value_tag: str, label: str,
               probabilities: bool) -> None:
        inst = self._one(entry, "Instance")
        tokens = (inst.text or "").split()
        if len(tokens) != max(len(axes), 1) or (not axes and tokens not in (["-"], ["*"])):
            order = " ".join(v.name for v in axes) or "(none: use '-')"
            self.fail(inst, f"<Instance>{' '.join(tokens)}</Instance> has {len(tokens)} item(s); "
                            f"{label} needs {max(len(axes), 1)} ({order})")
        selection: List[Optional[int]] = []
        dashes: List[int] = []
        shape: List[int] = []
        for k, token in enumerate(tokens if axes else []):
            v = axes[k]
            if token in ("*", "-"):
                selection.append(None)
                shape.append(v.size if token == "-" else 1)
                if token == "-":
                    dashes.append(v.size)
            else:
                index = resolve_token(token, v.lookup, v.size)
                if index is None:
                    self.fail(inst, f"{token!r} is not a value of {v.name} "
                                    f"({' '.join(v.values[:12])}{' ...' if v.size > 12 else ''})")
                selection.append(index)
        if not axes:
            selection = [None]
            shape = [1]
            dashes = [1]
        cells = int(np.prod([axes[k].size for k, s in enumerate(selection) if s is None])) \
            if axes else 1
        if cells > _ENTRY_CELLS:
            self.fail(inst, f"this entry covers {cells} cells, more than {_ENTRY_CELLS} allowed")
        if isinstance(table, _SparseTable):
            # index and value per cell, kept until finish(), which sorts a copy
            self._table_memory(inst, 48 * cells)
        vt = self._one(entry, value_tag)
        words = (vt.text or "").split()
        need = int(np.prod(dashes)) if dashes else 1
        if probabilities and words == ["identity"]:
            if len(dashes) != 2 or dashes[0] != dashes[1]:
                self.fail(vt, "'identity' needs exactly two '-' positions of the same size")
            values = np.eye(dashes[0])
        elif probabilities and words == ["uniform"]:
            values = np.full(need, 1.0 / axes[-1].size) if axes else np.ones(1)
        else:
            try:
                values = np.array(words, dtype=float)
            except ValueError:
                k = next(i for i, w in enumerate(words) if not _is_number(w))
                allowed = "numbers" if not probabilities else \
                    "numbers, or 'identity' or 'uniform' alone"
                self.fail_at_word(vt, k, f"<{value_tag}> expected numbers, found "
                                         f"{words[k]!r}, which is not a number (it holds "
                                         f"{allowed})")
            if values.size != need:
                self.fail(vt, f"<{value_tag}> has {values.size} number(s); "
                              f"<Instance>{' '.join(tokens)}</Instance> needs {need}")
            if not np.all(np.isfinite(values)):
                k = int(np.flatnonzero(~np.isfinite(values))[0])
                self.fail_at_word(vt, k, f"<{value_tag}> has a non-finite number {words[k]!r}")
            if not probabilities and values.size:
                problem = reward_bound_problem(float(np.abs(values).max()), self.discount)
                if problem:
                    self.fail(vt, problem)
            if probabilities:
                if np.any(values < 0):
                    self.fail(vt, f"negative probability {values[values < 0][0]:g} in {label}")
                if np.any(values > 1.0 + PROBABILITY_TOLERANCE):
                    self.fail(vt, f"probability above 1 ({values.max():g}) in {label}")
        table.assign(selection, np.reshape(values, shape))

    def _table_memory(self, elem, more: int) -> None:
        """Count ``more`` bytes of conditional tables; refuse past the memory limit."""
        self.table_bytes += more
        if self.memory_limit is not None and self.table_bytes > self.memory_limit:
            line = getattr(elem, "line", None)
            raise memory.MemoryLimitError(f"{self.source}:{line}" if line else self.source,
                                          "the conditional tables", self.table_bytes,
                                          self.memory_limit)

    def _check_normalised(self, elem, factor: _Factor) -> None:
        sums = factor.table.last_axis_sums()
        bad = np.flatnonzero(np.abs(sums - 1.0) > PROBABILITY_TOLERANCE)
        if not bad.size:
            return
        config = np.unravel_index(int(bad[0]), [p.size for p in factor.parents]) \
            if factor.parents else ()
        given = ", ".join(f"{p.name}={p.values[i]}" for p, i in zip(factor.parents, config))
        what = f"P({factor.var.name} | {given})" if given else f"P({factor.var.name})"
        self.fail(elem, f"{factor.label}: {what} sums to {sums[bad[0]]:.6g}, not 1 "
                        f"(tolerance {PROBABILITY_TOLERANCE:g}; {bad.size} such row(s))")

    # -- the flat model ----------------------------------------------------------------------
    def _build(self, discount: float, minimise: bool, fully: bool, init: List[_Factor],
               trans: List[_Factor], obs: List[_Factor], rewards: List[_Factor]) -> Model:
        sizes = [prev.size for prev, _, _ in self.state_vars]
        S = int(np.prod(sizes))
        if S > _MAX_STATES:
            self.fail(self.root, f"{S} joint states is more than {_MAX_STATES} supported")
        strides = [int(np.prod(sizes[i + 1:])) for i in range(len(sizes))]
        all_s = np.arange(S)
        digits = [(all_s // strides[i]) % sizes[i] for i in range(len(sizes))]
        A = self.action.size

        def by_var(factors: List[_Factor], what: str, role_of_var) -> List[_Factor]:
            found: Dict[int, _Factor] = {}
            for f in factors:
                if f.var.index in found:
                    self.fail(self.root, f"two {what} tables for {f.var.name} (lines "
                                         f"{found[f.var.index].line} and {f.line})")
                found[f.var.index] = f
            for i, (prev, curr, _) in enumerate(self.state_vars):
                if role_of_var == "state" and i not in found:
                    self.fail(self.root,
                              f"no {what} table for state variable {prev.name}/{curr.name}")
            return [found[i] for i in sorted(found)]

        init_f = by_var(init, "initial belief", "state")
        trans_f = by_var(trans, "transition", "state")

        b = np.ones(S)
        for f in init_f:
            b *= f.table.gather(self._flat(f, f.axes, None, digits, digits))
        if abs(b.sum() - 1.0) > PROBABILITY_TOLERANCE:
            self.fail(self._one(self.root, "InitialStateBelief"),
                      f"the initial belief sums to {b.sum():.6g}, not 1")

        seen = [i for i, (_, _, fo) in enumerate(self.state_vars) if fo]
        obs_f: List[_Factor] = []
        if self.obs_vars and not fully:
            found = {f.var.index: f for f in obs}
            for j, v in enumerate(self.obs_vars):
                if j not in found:
                    self.fail(self._one(self.root, "ObsFunction"),
                              f"no observation table for {v.name}")
            if len(obs) != len(found):
                self.fail(self._one(self.root, "ObsFunction"),
                          "two observation tables for one observation variable")
            obs_f = [found[j] for j in range(len(self.obs_vars))]
        self._check_flat_memory(trans_f, obs_f, fully, digits, S)

        T = []
        for a in range(A):
            parts = [f.table.rows(self._flat(f, f.parents, a, digits, digits)) for f in trans_f]
            T.append(sp.csr_matrix(reduce(rowwise_kron, parts)))

        state_names = joint_names([prev.values for prev, _, _ in self.state_vars])
        # The fully observed variables' joint value, numbered like joint states (an MDP: the
        # state itself); None when every state variable is hidden.
        observed_key = None
        if seen:
            observed_key = np.zeros(S, dtype=np.int64)
            for i in seen:
                observed_key = observed_key * sizes[i] + digits[i]
        if fully:
            observations = list(state_names)
            O = [sp.identity(S, format="csr") for _ in range(A)]
        else:
            value_lists = [self.state_vars[i][0].values for i in seen] + \
                          [v.values for v in self.obs_vars]
            observations = joint_names(value_lists) if value_lists else ["none"]
            O = []
            for a in range(A):
                parts = [sp.csr_matrix((np.ones(S), (all_s, digits[i])), shape=(S, sizes[i]))
                         for i in seen]
                parts += [f.table.rows(self._flat(f, f.parents, a, digits, digits))
                          for f in obs_f]
                O.append(sp.csr_matrix(reduce(rowwise_kron, parts)) if parts
                         else sp.csr_matrix(np.ones((S, 1))))

        R = []
        for a in range(A):
            if S <= FULL_REWARD_STATES:
                rows, cols = np.repeat(all_s, S), np.tile(all_s, S)
            else:
                rows = np.repeat(all_s, np.diff(T[a].indptr))
                cols = T[a].indices
            vals = np.zeros(rows.size)
            prev_digits = [d[rows] for d in digits]
            curr_digits = [d[cols] for d in digits]
            for f in rewards:
                vals += self._reward_values(f, obs_f, a, prev_digits, curr_digits)
            m = sp.csr_matrix((vals, (rows, cols)), shape=(S, S))
            m.eliminate_zeros()
            R.append(m)
        if rewards:
            # Each <Func> was checked; their sum may still be too large.
            largest = max((float(np.abs(m.data).max()) for m in R if m.nnz), default=0.0)
            problem = reward_bound_problem(largest, discount)
            if problem:
                self.fail(self._one(self.root, "RewardFunction"), f"the summed rewards: {problem}")

        meta = {"format": "pomdpx", "pomdpx": {
            "state_variables": [{"prev": p.name, "curr": c.name, "values": list(p.values),
                                 "fully_observable": fo} for p, c, fo in self.state_vars],
            "observation_variables": [{"name": v.name, "values": list(v.values)}
                                      for v in self.obs_vars],
            "action_variable": self.action.name,
            "reward_variables": [v.name for v in self.reward_vars]}}
        if fully and self.obs_vars:
            meta["notes"] = ["every state variable is fully observable: <ObsFunction> ignored"]
        name = Path(self.source).stem if self.source != "<string>" else "model"
        model = Model(states=list(state_names), actions=list(self.action.values),
                      observations=observations, discount=discount, initial_belief=b,
                      T=T, O=O, R=R, fully_observable=fully, minimise=minimise, name=name,
                      source=self.source, meta=meta, observed_key=observed_key)
        try:
            model.validate()
        except ModelError as exc:
            raise ModelFormatError(self.source, None, str(exc)) from None
        return model

    def _check_flat_memory(self, trans_f: List[_Factor], obs_f: List[_Factor], fully: bool,
                           digits: List[np.ndarray], S: int) -> None:
        """Refuse, before they are built, flat T, O and R that would not fit in the memory
        limit. Their non-zeros are counted exactly: a row of a Kronecker product has the
        product of its factors' row non-zeros."""
        if self.memory_limit is None:
            return
        A = self.action.size
        Z = int(np.prod([v.size for v in self.obs_vars])) if self.obs_vars else 1

        def flat_nonzeros(factors: List[_Factor], a: int) -> int:
            per_state = np.ones(S, dtype=np.int64)
            for f in factors:
                per_state *= f.table.row_nonzeros()[self._flat(f, f.parents, a, digits, digits)]
            return int(per_state.sum())

        t_nnz = [flat_nonzeros(trans_f, a) for a in range(A)]
        o_nnz = [S if fully else flat_nonzeros(obs_f, a) for a in range(A)]
        r_nnz = [S * S for _ in range(A)] if S <= FULL_REWARD_STATES else t_nnz
        # R is built from row, column and per-variable digit arrays of every cell it keeps.
        r_build = 8 * (5 + 2 * len(digits)) * max(r_nnz)
        needed = (memory.tables_bytes(t_nnz + o_nnz + r_nnz, S) + r_build
                  + memory.model_overhead(S, A, S if fully else Z) + 8 * S * len(digits))
        memory.require(needed, self.memory_limit, self.source,
                       f"building T, O and R ({S} states; {sum(t_nnz)}, {sum(o_nnz)} and "
                       f"{sum(r_nnz)} non-zeros)")

    def _reward_values(self, f: _Factor, obs_f: List[_Factor], action: int, prev_digits,
                       curr_digits) -> np.ndarray:
        """One <Func>'s reward at each (s, s') cell for ``action``. A reward that depends on
        observation variables is their expectation given (action, s'), as SARSOP reads it:
        Σ_o Π_i P(o_i | action, s') f(..., o) (the observation variables are independent given
        them, each with its own table)."""
        seen = [v for v in f.parents if v.role == "obs"]
        if not seen:
            return f.table.gather(self._flat(f, f.parents, action, prev_digits, curr_digits))
        if not obs_f:
            raise ModelFormatError(self.source, str(f.line), f"{f.label}: a reward conditioned "
                                   f"on the observation {seen[0].name!r} needs observations, "
                                   "but every state variable is fully observable (the "
                                   "<ObsFunction> is ignored)")
        # P(o_v = k | action, s') for each cell, per observation variable the reward reads.
        probs = []
        for v in seen:
            g = obs_f[v.index]
            probs.append([g.table.gather(self._flat(g, g.axes, action, prev_digits, curr_digits,
                                                    {v.index: k})) for k in range(v.size)])
        total = np.zeros(len(curr_digits[0]) if curr_digits else 1)
        for combo in itertools.product(*(range(v.size) for v in seen)):
            weight = reduce(np.multiply, (probs[i][k] for i, k in enumerate(combo)))
            if not np.any(weight):
                continue
            chosen = {v.index: k for v, k in zip(seen, combo)}
            total += weight * f.table.gather(self._flat(f, f.parents, action, prev_digits,
                                                        curr_digits, chosen))
        return total

    def _flat(self, factor: _Factor, axes: List[_Var], action: Optional[int], prev_digits,
              curr_digits, observed: Optional[Dict[int, int]] = None) -> np.ndarray:
        """Flat index into the table over ``axes`` for each state (or state pair), with
        ``observed`` giving the value of each observation variable (by its index) it has.

        Given only the parents, it indexes rows of the table reshaped to (parent
        configurations, values of the variable).
        """
        sizes = [v.size for v in axes]
        flat = np.zeros(len(prev_digits[0]) if prev_digits else 1, dtype=np.int64)
        stride = 1
        for v, size in zip(reversed(axes), reversed(sizes)):
            if v.role == "action":
                value = action
            elif v.role == "prev":
                value = prev_digits[v.index]
            elif v.role == "curr":
                value = curr_digits[v.index]
            elif v.role == "obs" and observed is not None and v.index in observed:
                value = observed[v.index]
            else:
                raise ModelFormatError(self.source, str(factor.line), f"{factor.label}: "
                                       f"{v.name} ({v.role}) cannot be used here")
            flat = flat + np.asarray(value, dtype=np.int64) * stride
            stride *= size
        return flat


def _is_number(word: str) -> bool:
    try:
        float(word)
        return True
    except ValueError:
        return False


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------
_MATRIX_LIMIT = 32


def _names(model: Model) -> Dict[str, str]:
    """Variable names: the model's own when it came from a one-variable POMDPX file."""
    names = dict(_DEFAULT_NAMES)
    info = model.meta.get("pomdpx") if isinstance(model.meta, dict) else None
    if info and len(info.get("state_variables", [])) == 1:
        names["state_prev"] = info["state_variables"][0]["prev"]
        names["state_curr"] = info["state_variables"][0]["curr"]
        names["action"] = info.get("action_variable", names["action"])
        if len(info.get("observation_variables", [])) == 1:
            names["observation"] = info["observation_variables"][0]["name"]
        if len(info.get("reward_variables", [])) == 1:
            names["reward"] = info["reward_variables"][0]
    return names


def _matrix_text(dense: np.ndarray, indent: str) -> str:
    rows = [indent + " ".join(format_number(x) for x in row) for row in dense]
    return "\n" + "\n".join(rows) + "\n" + indent[:-2]


def _entries(tag: str, model_actions: Sequence[str], tables: Sequence[sp.csr_matrix],
             rows: Sequence[str], cols: Sequence[str], dense_zeros: bool) -> List[str]:
    out = []
    ind = "        "
    for a, name in enumerate(model_actions):
        m = sp.csr_matrix(tables[a])
        n_rows, n_cols = m.shape
        if n_rows <= _MATRIX_LIMIT and n_cols <= _MATRIX_LIMIT:
            out.append(f"{ind}<Entry>\n{ind}  <Instance>{escape(name)} - -</Instance>\n"
                       f"{ind}  <{tag}>{_matrix_text(m.toarray(), ind + '    ')}</{tag}>\n"
                       f"{ind}</Entry>")
            continue
        m.sort_indices()
        for r in range(n_rows):
            for k in range(m.indptr[r], m.indptr[r + 1]):
                if m.data[k] == 0 and not dense_zeros:
                    continue
                out.append(f"{ind}<Entry><Instance>{escape(name)} {escape(rows[r])} "
                           f"{escape(cols[m.indices[k]])}</Instance>"
                           f"<{tag}>{format_number(m.data[k])}</{tag}></Entry>")
    return out


def dump(model: Model) -> str:
    """The model as one-variable POMDPX text; :func:`loads` reads it back to identical tables."""
    source = model.source or model.name or "<model>"
    for kind, names in (("state", model.states), ("action", model.actions),
                        ("observation", model.observations)):
        check_writable_names(kind, names, "<>&", source)
    names = _names(model)
    mdp = model.fully_observable and list(model.observations) == list(model.states) and \
        all(is_identity(o) for o in model.O)
    description = f"{model.name or 'model'}: written by ros_hrc"
    if model.source:
        description += f" from {Path(model.source).name}"
    if model.minimise:
        description += f" {_COST_MARK}"
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             f'<pomdpx version="1.0" id={quoteattr(model.name or "model")}',
             '        xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"',
             '        xsi:noNamespaceSchemaLocation="pomdpx.xsd">',
             f"  <Description>{escape(description)}</Description>",
             f"  <Discount>{format_number(model.discount)}</Discount>",
             "  <Variable>",
             f'    <StateVar vnamePrev={quoteattr(names["state_prev"])} '
             f'vnameCurr={quoteattr(names["state_curr"])} fullyObs="{"true" if mdp else "false"}">',
             f"      <ValueEnum>{escape(' '.join(model.states))}</ValueEnum>",
             "    </StateVar>"]
    if not mdp:
        lines += [f'    <ObsVar vname={quoteattr(names["observation"])}>',
                  f"      <ValueEnum>{escape(' '.join(model.observations))}</ValueEnum>",
                  "    </ObsVar>"]
    lines += [f'    <ActionVar vname={quoteattr(names["action"])}>',
              f"      <ValueEnum>{escape(' '.join(model.actions))}</ValueEnum>",
              "    </ActionVar>",
              f'    <RewardVar vname={quoteattr(names["reward"])}/>',
              "  </Variable>",
              "  <InitialStateBelief>",
              f"    <CondProb><Var>{escape(names['state_prev'])}</Var><Parent>null</Parent>",
              '      <Parameter type="TBL"><Entry><Instance>-</Instance>',
              "        <ProbTable>" + " ".join(format_number(x) for x in model.initial_belief)
              + "</ProbTable>",
              "      </Entry></Parameter>",
              "    </CondProb>",
              "  </InitialStateBelief>",
              "  <StateTransitionFunction>",
              f"    <CondProb><Var>{escape(names['state_curr'])}</Var>"
              f"<Parent>{escape(names['action'])} {escape(names['state_prev'])}</Parent>",
              '      <Parameter type="TBL">']
    lines += _entries("ProbTable", model.actions, model.T, model.states, model.states, False)
    lines += ["      </Parameter>", "    </CondProb>", "  </StateTransitionFunction>"]
    if not mdp:
        lines += ["  <ObsFunction>",
                  f"    <CondProb><Var>{escape(names['observation'])}</Var>"
                  f"<Parent>{escape(names['action'])} {escape(names['state_curr'])}</Parent>",
                  '      <Parameter type="TBL">']
        lines += _entries("ProbTable", model.actions, model.O, model.states,
                          model.observations, False)
        lines += ["      </Parameter>", "    </CondProb>", "  </ObsFunction>"]
    lines += ["  <RewardFunction>",
              f"    <Func><Var>{escape(names['reward'])}</Var><Parent>{escape(names['action'])} "
              f"{escape(names['state_prev'])} {escape(names['state_curr'])}</Parent>",
              '      <Parameter type="TBL">']
    lines += _entries("ValueTable", model.actions, model.R, model.states, model.states, False)
    lines += ["      </Parameter>", "    </Func>", "  </RewardFunction>", "</pomdpx>"]
    return "\n".join(lines) + "\n"
