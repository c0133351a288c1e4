"""How a POMDPX file's variables and conditional tables become one flat model: the part of the
reader (:mod:`ros_hrc.pomdp.pomdpx_reader`) that comes after the XML.

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
"""
from __future__ import annotations

import itertools
from functools import reduce
from typing import Dict, List, Optional, Tuple

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import ModelFormatError
from ros_hrc.pomdp import memory
from ros_hrc.pomdp.fileformat import (FULL_REWARD_STATES, PROBABILITY_TOLERANCE, joint_names,
                                      model_name, validated)
from ros_hrc.pomdp.model import Model, reward_bound_problem
from ros_hrc.pomdp.pomdpx_tables import Factor, Variable, rowwise_kron
from ros_hrc.pomdp.pomdpx_xml import children, local_name

#: Most joint states a model may have.
_MAX_STATES = 2_000_000


class FactoredModel:
    """A POMDPX document's declared variables (the reader fills them in) and the flat model
    its factors make (:meth:`flat_model`). ``root`` is the document's root element; errors
    name ``source`` and the line of the element at fault."""

    def __init__(self, root, source: str, memory_limit: Optional[int] = None) -> None:
        self.root = root
        self.source = source
        self.memory_limit = memory_limit
        self.vars: Dict[str, Variable] = {}
        # (prev, curr, fully observed) for each state variable
        self.state_vars: List[Tuple[Variable, Variable, bool]] = []
        self.obs_vars: List[Variable] = []
        self.action: Optional[Variable] = None
        self.reward_vars: List[Variable] = []

    def fail(self, elem, what: str):
        """Raise ModelFormatError at ``elem``'s line (or its tag when the line is unknown)."""
        line = getattr(elem, "line", None) if elem is not None else None
        where = str(line) if line else (f"<{local_name(elem.tag)}>" if elem is not None else None)
        raise ModelFormatError(self.source, where, what)

    def _one(self, parent, tag: str, required: bool = True):
        """``parent``'s one child ``tag`` (None when absent and not ``required``)."""
        found = children(parent, tag)
        if len(found) > 1:
            self.fail(found[1], f"<{local_name(parent.tag)}> has more than one <{tag}>")
        if not found:
            if required:
                self.fail(parent, f"<{local_name(parent.tag)}> has no <{tag}>")
            return None
        return found[0]

    def flat_model(self, discount: float, minimise: bool, fully: bool, init: List[Factor],
                   trans: List[Factor], obs: List[Factor], rewards: List[Factor]) -> Model:
        """The flat model of the declared variables and these factors (the initial belief's,
        transition, observation and reward tables), checked (ModelFormatError naming the
        element at fault)."""
        sizes = [prev.size for prev, _, _ in self.state_vars]
        S = int(np.prod(sizes))
        if S > _MAX_STATES:
            self.fail(self.root, f"{S} joint states is more than {_MAX_STATES} supported")
        strides = [int(np.prod(sizes[i + 1:])) for i in range(len(sizes))]
        all_s = np.arange(S)
        digits = [(all_s // strides[i]) % sizes[i] for i in range(len(sizes))]
        A = self.action.size

        def by_var(factors: List[Factor], what: str, role_of_var) -> List[Factor]:
            found: Dict[int, Factor] = {}
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
        obs_f: List[Factor] = []
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
        model = Model(states=list(state_names), actions=list(self.action.values),
                      observations=observations, discount=discount, initial_belief=b,
                      T=T, O=O, R=R, fully_observable=fully, minimise=minimise,
                      name=model_name(self.source), source=self.source, meta=meta,
                      observed_key=observed_key)
        return validated(model, self.source)

    def _check_flat_memory(self, trans_f: List[Factor], obs_f: List[Factor], fully: bool,
                           digits: List[np.ndarray], S: int) -> None:
        """Refuse, before they are built, flat T, O and R that would not fit in the memory
        limit. Their non-zeros are counted exactly: a row of a Kronecker product has the
        product of its factors' row non-zeros."""
        if self.memory_limit is None:
            return
        A = self.action.size
        Z = int(np.prod([v.size for v in self.obs_vars])) if self.obs_vars else 1

        def flat_nonzeros(factors: List[Factor], a: int) -> int:
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

    def _reward_values(self, f: Factor, obs_f: List[Factor], action: int, prev_digits,
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

    def _flat(self, factor: Factor, axes: List[Variable], action: Optional[int], prev_digits,
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
