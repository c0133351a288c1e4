"""Reading POMDPX (:mod:`ros_hrc.pomdp.pomdpx`): :func:`load` / :func:`loads`.

The XML is parsed safely, each element with its line (:mod:`ros_hrc.pomdp.pomdpx_xml`); the
variables and conditional tables are read into :mod:`ros_hrc.pomdp.pomdpx_tables`' classes,
then multiplied out into one flat model (:mod:`ros_hrc.pomdp.pomdpx_flat`).

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
* Malformed XML is reported at expat's line (:mod:`ros_hrc.pomdp.pomdpx_xml`). A word of a
  table that is not a number is reported at its own line (a table may span many).

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
"""
from __future__ import annotations

import re
from typing import List, Optional, Union

import numpy as np

from ros_hrc.errors import ModelFormatError
from ros_hrc.pomdp import memory
from ros_hrc.pomdp.fileformat import (MAX_DIGITS, PROBABILITY_TOLERANCE, STRING_SOURCE,
                                      check_set_size, default_names, discount_problem,
                                      first_non_number, is_number_text, name_lookup, read_file,
                                      resolve_token, shown_token, strip_bom)
from ros_hrc.pomdp.model import (Model, reward_bound_problem, rows_not_summing_to_one,
                                 sum_problem)
from ros_hrc.pomdp.pomdpx_flat import FactoredModel
from ros_hrc.pomdp.pomdpx_tables import DenseTable, Factor, SparseTable, Variable
from ros_hrc.pomdp.pomdpx_xml import COST_MARK, children, local_name, parse_xml

__all__ = ["load", "loads"]

#: Conditional tables up to this many cells are dense arrays; larger ones are kept sparse.
_DENSE_CELLS = 5_000_000
#: One <Entry> may not expand to more cells than this (a '*' over a huge flat variable).
_ENTRY_CELLS = 20_000_000


def load(path, memory_limit: Optional[int] = None) -> Model:
    """Read a POMDPX file into a :class:`Model` (``memory_limit``: bytes, see the module's
    docstring; None: no check)."""
    path = str(path)
    data = read_file(path, memory_limit)
    return _Reader(parse_xml(data, path), path, memory_limit).read()


def loads(text: Union[str, bytes], source: str = STRING_SOURCE,
          memory_limit: Optional[int] = None) -> Model:
    """Parse POMDPX text; ``source`` names it in error messages."""
    if isinstance(text, str):
        text = strip_bom(text)
    return _Reader(parse_xml(text, source), source, memory_limit).read()


class _Reader(FactoredModel):
    """Reads the XML into the declared variables and their factors (conditional tables)."""

    def __init__(self, root, source: str, memory_limit: Optional[int] = None) -> None:
        super().__init__(root, source, memory_limit)
        self.discount = 0.0
        self.table_bytes = 0            # what the conditional tables read so far hold

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

    # -- driver -----------------------------------------------------------------------------
    def read(self) -> Model:
        root = self.root
        if local_name(root.tag) != "pomdpx":
            self.fail(root, f"the root element is <{local_name(root.tag)}>, not <pomdpx>")
        known = {"Description", "Discount", "Variable", "InitialStateBelief",
                 "StateTransitionFunction", "ObsFunction", "RewardFunction"}
        for child in children(root):
            if local_name(child.tag) not in known:
                self.fail(child, f"unknown element <{local_name(child.tag)}> in <pomdpx>")
        discount = self.discount = self._discount()
        self._variables(self._one(root, "Variable"))
        description = self._one(root, "Description", required=False)
        minimise = description is not None and COST_MARK in (description.text or "")

        init = self._factors(self._one(root, "InitialStateBelief"), "CondProb", "initial")
        trans = self._factors(self._one(root, "StateTransitionFunction"), "CondProb", "transition")
        fully = all(fo for _, _, fo in self.state_vars)
        obs_elem = self._one(root, "ObsFunction", required=False)
        obs: List[Factor] = []
        if self.obs_vars and not fully:
            if obs_elem is None:
                self.fail(root, "<pomdpx> has observation variables but no <ObsFunction>")
            obs = self._factors(obs_elem, "CondProb", "observation")
        reward_elem = self._one(root, "RewardFunction", required=False)
        rewards = self._factors(reward_elem, "Func", "reward") if reward_elem is not None else []
        return self.flat_model(discount, minimise, fully, init, trans, obs, rewards)

    def _discount(self) -> float:
        elem = self._one(self.root, "Discount")
        try:
            value = float((elem.text or "").strip())
        except ValueError:
            self.fail(elem, f"<Discount> is not a number: {(elem.text or '').strip()!r}")
        problem = discount_problem(value)
        if problem:
            self.fail(elem, problem)
        return value

    # -- <Variable> --------------------------------------------------------------------------
    def _values(self, elem, prefix: str) -> List[str]:
        enum = self._one(elem, "ValueEnum", required=False)
        num = self._one(elem, "NumValues", required=False)
        if (enum is None) == (num is None):
            self.fail(elem, f"<{local_name(elem.tag)}> needs exactly one of <ValueEnum> or "
                            "<NumValues>")
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
            self.fail(elem, f"<{local_name(elem.tag)}> has no {name}= attribute")
        return value

    def _add_var(self, elem, var: Variable) -> Variable:
        if var.name in self.vars:
            self.fail(elem, f"the variable name {var.name!r} is used twice")
        var.lookup = name_lookup(var.values)
        self.vars[var.name] = var
        return var

    def _variables(self, elem) -> None:
        for child in children(elem):
            tag = local_name(child.tag)
            if tag == "StateVar":
                values = self._values(child, "s")
                flag = (child.get("fullyObs") or "false").strip().lower()
                if flag not in ("true", "false"):
                    self.fail(child, f"fullyObs must be 'true' or 'false', found {flag!r}")
                i = len(self.state_vars)
                prev = self._add_var(child, Variable(self._attr(child, "vnamePrev"), "prev", i,
                                                     values))
                curr = self._add_var(child, Variable(self._attr(child, "vnameCurr"), "curr", i,
                                                     values))
                self.state_vars.append((prev, curr, flag == "true"))
            elif tag == "ObsVar":
                var = Variable(self._attr(child, "vname"), "obs", len(self.obs_vars),
                               self._values(child, "o"))
                self.obs_vars.append(self._add_var(child, var))
            elif tag == "ActionVar":
                if self.action is not None:
                    self.fail(child, "only one <ActionVar> is supported")
                self.action = self._add_var(child, Variable(self._attr(child, "vname"), "action",
                                                            0, self._values(child, "a")))
            elif tag == "RewardVar":
                self.reward_vars.append(self._add_var(child, Variable(self._attr(child, "vname"),
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

    def _factors(self, elem, tag: str, kind: str) -> List[Factor]:
        out = []
        for child in children(elem):
            if local_name(child.tag) != tag:
                self.fail(child, f"unexpected <{local_name(child.tag)}> in "
                                 f"<{local_name(elem.tag)}> (expected <{tag}>)")
            out.append(self._factor(child, kind))
        return out

    def _factor(self, elem, kind: str) -> Factor:
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
        label = f"<{local_name(elem.tag)}> for {var.name}"
        axes = parents + ([] if kind == "reward" else [var])
        shape = tuple(v.size for v in axes) or (1,)
        cells = int(np.prod(shape))
        if cells <= _DENSE_CELLS:
            self._table_memory(elem, 8 * cells)
        table = DenseTable(shape) if cells <= _DENSE_CELLS else SparseTable(shape)
        param = self._one(elem, "Parameter")
        ptype = (param.get("type") or "TBL").strip()
        if ptype != "TBL":
            self.fail(param, f"<Parameter type={ptype!r}> is not supported (only TBL)")
        value_tag = "ValueTable" if kind == "reward" else "ProbTable"
        for entry in children(param):
            if local_name(entry.tag) != "Entry":
                self.fail(entry, f"unexpected <{local_name(entry.tag)}> in <Parameter>")
            self._entry(entry, axes, table, value_tag, label, probabilities=kind != "reward")
        table.finish()
        factor = Factor(None if kind == "reward" else var, parents, table,
                        getattr(elem, "line", None), label)
        if kind != "reward":
            self._check_normalised(elem, factor)
        return factor

    def _entry(self, entry, axes: List[Variable], table, value_tag: str, label: str,
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
        if isinstance(table, SparseTable):
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
                k = first_non_number(words)
                if k is None:
                    raise
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

    def _check_normalised(self, elem, factor: Factor) -> None:
        sums = factor.table.last_axis_sums()
        bad = rows_not_summing_to_one(sums)
        if not bad.size:
            return
        config = np.unravel_index(int(bad[0]), [p.size for p in factor.parents]) \
            if factor.parents else ()
        given = ", ".join(f"{p.name}={p.values[i]}" for p, i in zip(factor.parents, config))
        what = f"P({factor.var.name} | {given})" if given else f"P({factor.var.name})"
        self.fail(elem, f"{factor.label}: {what} {sum_problem(sums[bad[0]], bad.size)}")
