"""Fast sampling of a model's generative step (s, a) -> (s', o, r), for simulators and planners.

A planner such as DESPOT calls the step millions of times, so every (action, state) row of T and
every (action, next state) row of O is turned, once, into a cumulative distribution stored in one
flat array. Rows are laid end to end and row ``k`` is shifted by ``k``, so its cumulative values lie
in ``[k, k + 1]``; sampling a whole batch of rows is then a single ``np.searchsorted`` of
``row + u`` (u uniform in [0, 1)). The reward R(s, a, s') of the transition that was drawn is read
from an array aligned with T's entries, so the step needs no sparse-matrix indexing at all.

Scalar samplers (``step1``) use the same tables through ``bisect`` for simulators that take one
step at a time, where numpy's per-call overhead would dominate.
"""
from __future__ import annotations

from bisect import bisect_right
from typing import List, Tuple

import numpy as np
import scipy.sparse as sp

from ros_hrc.pomdp.model import Model

#: Uniform numbers are clipped below 1 by this much so ``row + u`` never rounds up to the next
#: row (exact for row indices below about 4e6).
U_MAX = 1.0 - 1e-9
_U_MAX = U_MAX


def memory_needed(model: Model) -> int:
    """Bytes a ModelSampler of ``model`` peaks at while built (its arrays and the Python lists
    of the scalar path): measured 0.8 of this on RockSample_7_8 and a 8,000-state ring."""
    rows = model.n_actions * model.n_states
    return (180 * sum(t.nnz for t in model.T) + 150 * sum(o.nnz for o in model.O)
            + 100 * rows)


class _RowTable:
    """Rows of a stack of per-action CSR matrices as shifted cumulative distributions."""

    def __init__(self, mats: List[sp.csr_matrix], extra: List[sp.csr_matrix] = None) -> None:
        stacked = sp.vstack(mats, format="csr")
        stacked.eliminate_zeros()     # an explicit zero at a row's end would otherwise get its mass
        stacked.sort_indices()
        self.n_rows = stacked.shape[0]
        self.indptr = stacked.indptr.astype(np.int64)
        self.cols = stacked.indices.astype(np.int64)
        data = np.clip(stacked.data.astype(float), 0.0, None)
        row_of = np.repeat(np.arange(self.n_rows), np.diff(self.indptr))
        sums = np.bincount(row_of, weights=data, minlength=self.n_rows)
        # Rows are normalised here (printed tables round) so that each ends at exactly k + 1.
        safe = np.where(sums > 0, sums, 1.0)
        cum = np.cumsum(data / safe[row_of])
        starts = self.indptr[:-1]
        nonempty = np.diff(self.indptr) > 0
        before = np.zeros(self.n_rows)
        before[nonempty] = np.concatenate(([0.0], cum))[starts[nonempty]]
        within = np.clip(cum - before[row_of], 0.0, 1.0)
        ends = self.indptr[1:] - 1
        within[ends[nonempty]] = 1.0
        self.cum = within + row_of
        self.empty = ~nonempty | (sums <= 0)
        self.values = None
        if extra is not None:
            # A second matrix read at T's nonzero positions (the reward of each transition).
            ex = sp.vstack(extra, format="csr")
            self.values = np.asarray(ex[row_of, self.cols]).ravel().astype(float)
        # Python lists for the scalar path.
        self._cum_list = self.cum.tolist()
        self._indptr_list = self.indptr.tolist()
        self._cols_list = self.cols.tolist()
        self._values_list = self.values.tolist() if self.values is not None else None

    def sample(self, rows: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Entry positions drawn from ``rows`` with uniforms ``u`` (broadcast against rows).

        No clipping to the row is needed: row k's entries hold cumulative values in [k, k+1],
        its last exactly k+1 and the previous row's last exactly k, and u < 1 - 1e-9.
        """
        return np.searchsorted(self.cum, rows + np.minimum(u, _U_MAX), side="right")

    def sample1(self, row: int, u: float) -> int:
        """One entry position drawn from ``row``."""
        lo, hi = self._indptr_list[row], self._indptr_list[row + 1]
        pos = bisect_right(self._cum_list, row + min(u, _U_MAX), lo, hi)
        return min(max(pos, lo), hi - 1)


class ModelSampler:
    """A POMDP's generative model: draws s' ~ T(.|s,a), o ~ O(.|s',a), and gives R(s,a,s')."""

    def __init__(self, model: Model) -> None:
        self.model = model
        self.n_states = model.n_states
        self.n_actions = model.n_actions
        self.trans = _RowTable(model.T, model.R)
        self.obs = _RowTable(model.O)
        init = np.clip(np.asarray(model.initial_belief, dtype=float), 0.0, None)
        self._init_cum = np.cumsum(init / init.sum())

    def step(self, states: np.ndarray, actions, u_trans: np.ndarray,
             u_obs: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Vectorised step: arrays of states (and actions, array or int) to (s', o, r).

        The same uniforms give the same outcome: this is what makes DESPOT's scenarios
        deterministic.
        """
        rows = np.asarray(actions) * self.n_states + states
        pos = self.trans.sample(rows, u_trans)
        nxt = self.trans.cols[pos]
        rewards = self.trans.values[pos]
        opos = self.obs.sample(np.asarray(actions) * self.n_states + nxt, u_obs)
        return nxt, self.obs.cols[opos], rewards

    def step_rows(self, rows: np.ndarray, u_trans: np.ndarray,
                  u_obs: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Like ``step`` with precomputed rows ``action * n_states + state``."""
        pos = self.trans.sample(rows, u_trans)
        nxt = self.trans.cols[pos]
        opos = self.obs.sample(rows - rows % self.n_states + nxt, u_obs)
        return nxt, self.obs.cols[opos], self.trans.values[pos]

    def step_block(self, action_base: np.ndarray, states: np.ndarray, u_trans: np.ndarray,
                   u_obs: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every action for every state at once: the fast path of a DESPOT expansion.

        ``action_base`` is ``(actions * n_states)[:, None]``; ``states``, ``u_trans`` and
        ``u_obs`` have one entry per scenario and the uniforms must already be below
        ``U_MAX``. Returns (s', o, r), each of shape (actions, scenarios).
        """
        pos = np.searchsorted(self.trans.cum, (action_base + states) + u_trans, side="right")
        nxt = self.trans.cols[pos]
        opos = np.searchsorted(self.obs.cum, (action_base + nxt) + u_obs, side="right")
        return nxt, self.obs.cols[opos], self.trans.values[pos]

    def step1(self, state: int, action: int, u_trans: float,
              u_obs: float) -> Tuple[int, int, float]:
        """Scalar step for simulators: (s', o, r)."""
        pos = self.trans.sample1(action * self.n_states + state, u_trans)
        nxt = self.trans._cols_list[pos]
        opos = self.obs.sample1(action * self.n_states + nxt, u_obs)
        return nxt, self.obs._cols_list[opos], self.trans._values_list[pos]

    def sample_initial(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` states drawn from the model's initial belief."""
        return sample_from(self._init_cum, rng.random(n))


def sample_from(cum: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Indices drawn from a cumulative distribution ``cum`` (ending at 1) with uniforms ``u``."""
    idx = np.searchsorted(cum, u * cum[-1], side="right")
    return np.minimum(idx, cum.size - 1)
