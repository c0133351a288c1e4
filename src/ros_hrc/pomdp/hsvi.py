"""HSVI2, heuristic search value iteration (Smith and Simmons 2004, 2005): an anytime offline
solver.

Two bounds on the optimal value function V* are kept and tightened along sampled belief paths:

* lower bound: a set of alpha vectors (each the value of a conditional plan, so every vector is
  a valid bound); it starts from the blind policies (repeat one action forever);
* upper bound: corner values plus a set of (belief, value) points, read with the sawtooth
  interpolation; it starts from the fast informed bound.

A trial starts at the initial belief (a root: see mixed observability below) and descends,
taking the action with the best upper bound and the observation with the largest weighted excess
gap, until the gap at depth t is below ``target / γ^t``; it then backs both bounds up along the
path, deepest first. The target is a fraction ``TRIAL_ZETA`` of the gap at the root, never below
``precision`` (HSVI2's and SARSOP's dynamic target): trials stay shallow while the bounds are
loose and go deeper as they close. The solver stops when the gap at the start is below
``precision`` (the exact rule) or the time is up, and returns the lower-bound vectors as a
``Policy``. Both bounds are valid at every moment (anytime).

The beliefs the trials visit form SARSOP's tree of reachable beliefs: each node keeps its
successors of non-zero probability under every action and observation, and both bounds at
them and at itself, cached between visits. A cached value is brought up to date with the
points (vectors) added since (the sawtooth is a minimum over points, the lower bound a maximum
over vectors, and the solver logs every point and vector it adds), not recomputed over all of
them; every cached value is a valid bound whatever happens later, since V* does not change. A
model whose successors are too large to keep (``KEEP_SUCCESSORS``) has no tree and computes
them at each visit.

Before the first trial, a small model's corners (the point masses) are backed up in a few
rounds (PBVI at the corners, ``VERTEX_ROUNDS``): the blind policies' vectors are far below V*
there, and the trials then need fewer backups.

Sweeps, our addition to HSVI2: synchronous backups of both bounds at once at the heaviest
beliefs the trials have met and at their one-step successors. They run only when the trials
stall (their rate of narrowing the gap, over the last few, falls to the last sweep's; zero
before any sweep) and go on while they narrow it faster than the trials did.

Mixed observability (POMDPX ``fullyObs`` variables, ``Model.observed_key``): the fully observed
values are seen before the first action, so the value to bound is Σ_k P(k) V*(b_k) over the
initial belief split by them (``Model.start_split``), as in SARSOP. Each b_k is a root: all are
in the belief set and the upper bound's points, a trial starts at the root with the largest
weighted excess gap P(k)·(gap(b_k) − precision), and the bounds reported at the start (and the
policy's) are the weighted sums. Without a key there is one root, the initial belief.

When every observation tells the fully observed values after it, ``solve`` hands the model to
:mod:`ros_hrc.pomdp.momdp`, the same search with beliefs and bounds kept per block of states
sharing those values (SARSOP's MOMDP representation): RockSample_4_3 0.7 s instead of 38 s.

A fully observable model is an MDP: ``solve`` then runs value iteration instead.

Time and memory: ``solve``'s timeout counts from the call, so building the tables and the MDP
bounds (blind policies, QMDP or the fast informed bound) is inside it; every stage stops at the
deadline with bounds that are still valid (each iterate of those bounds is one). Memory is
O(non-zeros of T + A·Z·S) plus the stored vectors (alpha vectors, upper-bound points and their
log, beliefs, the current trial's path: S numbers each; a tree node's A·Z successors, within
``TREE_NUMBERS``), never an S x S array for a large model. With
``memory_limit`` the solver refuses, before building anything, a model whose tables and working
arrays would not fit (:class:`~ros_hrc.pomdp.memory.MemoryLimitError`), and stops, as at a
timeout, when its stored vectors would outgrow the rest of the budget (after pruning once);
``stats["memory_limit_reached"]`` then says so.
"""
from __future__ import annotations

import hashlib
import math
import time
from collections import deque
from dataclasses import dataclass
from typing import Callable, Deque, Iterator, List, Optional, Tuple

import numpy as np

from ros_hrc.errors import SolverError
from ros_hrc.pomdp import mdp, memory
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.policy import Policy

#: A bound change smaller than this is treated as no change (stops rounding noise piling up).
_TINY = 1e-10

#: Largest A·Z·S (dense observation array) this solver accepts.
MAX_DENSE_ENTRIES = 20_000_000

#: Work per sweep, in sawtooth terms (beliefs x actions x observations x points x states).
SWEEP_BUDGET = 3e6

#: Numbers in one block of the sawtooth's (states x beliefs x points) temporary, and in one
#: chunk of a sweep's (beliefs x actions x observations x states) arrays: 32 MB each.
RATIO_BLOCK = 4_000_000
SWEEP_CHUNK = 4_000_000

#: A trial keeps each step's successor beliefs (A·Z·S numbers) for the backups on its way back
#: while they are at most this many numbers; larger ones are computed again in the backup.
KEEP_SUCCESSORS = 1_000_000

#: Numbers (8 bytes each) the belief tree may keep: its nodes' successors (64 MB).
TREE_NUMBERS = 8_000_000

#: Most upper-bound points for which the sawtooth is taken from X.T made contiguous.
CONTIGUOUS_POINTS = 600

#: Most numbers (A·S·Z·S) of the backup tensor ``_Tables.G`` (8 MB).
BACKUP_TENSOR = 1_000_000

#: Rounds of backups at the corners (the point masses) before the first trial, at most; they
#: stop once a round moves no corner's bound by more than VERTEX_ROUND_STOP x the gap at the
#: start. Only for models of at most VERTEX_STATES states (a round is S backups).
VERTEX_ROUNDS = 10
VERTEX_ROUND_STOP = 0.1
VERTEX_STATES = 100

#: A trial's target gap is this fraction of the root's gap (never below the precision).
TRIAL_ZETA = 0.95

#: Fewest stored vectors (beliefs, points, alpha vectors) the memory budget must leave room for.
MIN_VECTORS = 64


@dataclass
class SolveProgress:
    """What a progress callback receives, about once per trial."""

    seconds: float
    trials: int
    lower: float
    upper: float
    n_alphas: int
    n_points: int


def _log_rate(gap_before: float, gap_after: float, seconds: float) -> float:
    """How fast the gap narrowed: ln(before / after) per second. The gap shrinks about
    geometrically, so this rate stays comparable as the gap closes (a difference would not)."""
    if gap_after >= gap_before or gap_before <= 0.0:
        return 0.0
    return math.log(gap_before / max(gap_after, 1e-300)) / max(seconds, 1e-9)


def _check_size(model: Model) -> None:
    A, S, Z = model.n_actions, model.n_states, model.n_observations
    if A * Z * S > MAX_DENSE_ENTRIES:
        raise SolverError(f"model too large for the point-based solver "
                          f"({A} actions x {Z} observations x {S} states); "
                          f"plan online with DESPOT instead")


def memory_needed(model: Model) -> int:
    """Bytes HSVI needs besides its stored vectors: the model, the solver's tables, the MDP
    bounds and the working arrays of a trial step, a backup and a sweep's chunk (an upper
    estimate, from the sizes and T's non-zeros)."""
    A, S, Z = model.n_actions, model.n_states, model.n_observations
    azs = A * Z * S
    nnz_t = sum(t.nnz for t in model.T)
    tables = 8 * azs + 8 * 4 * A * S + memory.csr_bytes(nnz_t, A * S)      # OT, R, T transposed
    if model.dense_tables_fit:
        tables += 8 * A * S * (S + Z)                                       # dense T and O
    bounds = 8 * 10 * A * S                     # value iteration, blind and informed bounds
    if mdp.fib_is_dense(model):
        bounds += 8 * (2 * A * Z * S * S + A * A * Z * S)
    working = 8 * 8 * azs                       # successors, their bounds, a backup
    n_max = max(32, int(math.sqrt(SWEEP_BUDGET / max(azs, 1))))
    sweep = 8 * 6 * max(azs, min(SWEEP_CHUNK, n_max * azs))
    sawtooth = 8 * 3 * RATIO_BLOCK
    # The roots (one per fully observed start value): split from the initial belief, stacked,
    # and each also a belief and an upper-bound point.
    roots = 8 * 8 * S * _root_count(model)
    return memory.model_bytes(model) + tables + bounds + working + sweep + sawtooth + roots


def _root_count(model: Model) -> int:
    """How many roots ``Model.start_split`` will make, counted without making them."""
    b = np.asarray(model.initial_belief)
    if model.observed_key is None:
        return 1
    return max(1, int(np.unique(np.asarray(model.observed_key)[b > 0]).size))


class _Tables:
    """The model's arrays in the shapes the backups want (dense T when small, sparse otherwise)."""

    def __init__(self, model: Model) -> None:
        self.A, self.S, self.Z = model.n_actions, model.n_states, model.n_observations
        _check_size(model)
        self.gamma = float(model.discount)
        self.R = np.asarray(model.R_sa, dtype=float)                    # (A, S)
        self.dense = model.dense_tables_fit
        self.T = model.dense_T if self.dense else model.T                # (A, S, S') or list
        if self.dense:
            self.OT = np.transpose(model.dense_O, (0, 2, 1)).copy()     # (A, Z, S')
        else:
            self.OT = np.stack([o.T.toarray() for o in model.O])
            self.Tt = [t.T.tocsr() for t in model.T]
        # A small model's backup as one batched product: G[a, s, (z, s')] =
        # γ·T(s'|s,a)·O(z|s',a), so the backed-up vector of action a is R[a] + G[a] @ α_(a,·).
        self.G: Optional[np.ndarray] = None
        if self.dense and self.A * self.S * self.Z * self.S <= BACKUP_TENSOR:
            self.G = (self.gamma * self.T[:, :, None, :] * self.OT[:, None, :, :]).reshape(
                self.A, self.S, self.Z * self.S)

    def successors(self, b: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """P(z | b, a) as (A, Z) and the next beliefs as (A, Z, S) (zero rows where P = 0)."""
        if self.dense:
            pred = b @ self.T                                            # (A, S')
        else:
            pred = np.vstack([t @ b for t in self.Tt])
        joint = pred[:, None, :] * self.OT                               # (A, Z, S')
        p = joint.sum(axis=2)
        safe = np.where(p > 0, p, 1.0)
        return p, joint / safe[:, :, None]

    def back(self, w: np.ndarray) -> np.ndarray:
        """Σ_s' T(s'|s,a) w[a, s'] for each action: (A, S)."""
        if self.dense:
            return np.einsum("ast,at->as", self.T, w)
        return np.vstack([self.T[a] @ w[a] for a in range(self.A)])


class _LowerBound:
    """Alpha vectors and their actions; with ``log``, also every vector ever added, in order
    (pruning does not touch it), so that cached values are brought up to date with the vectors
    added since (:meth:`cached`); ``log_index[i]`` is the row of ``alphas[i]`` in the log."""

    def __init__(self, alphas: np.ndarray, actions: np.ndarray, log: bool = False) -> None:
        self.alphas = alphas
        self.actions = actions
        self.log = log
        self.log_n = 0
        self._log = np.empty((max(16, alphas.shape[0]) if log else 0, alphas.shape[1]))
        self.log_index = np.arange(alphas.shape[0] if log else 0)
        if log:
            self._append_log(alphas)

    def _append_log(self, alphas: np.ndarray) -> None:
        need = self.log_n + alphas.shape[0]
        if need > self._log.shape[0]:
            grown = np.empty((max(need, 2 * self._log.shape[0]), self._log.shape[1]))
            grown[:self.log_n] = self._log[:self.log_n]
            self._log = grown
        self._log[self.log_n:need] = alphas
        self.log_n = need

    def cached(self, X: np.ndarray, cache: Optional["_LowerCached"]) -> "_LowerCached":
        """The lower bound at the rows of X and the vector giving it, from ``cache`` (an
        earlier call's result for the same rows) brought up to date with the vectors added
        since. Every vector ever added is a valid bound, so the maximum over them is one too
        (at least the current vectors' maximum). A fresh evaluation, over the current vectors,
        when there is no cache or more new vectors than current ones. Without a log: the
        current vectors."""
        if not self.log:
            prod = X @ self.alphas.T
            return _LowerCached(prod.max(axis=1), prod.argmax(axis=1), 0, self.alphas)
        lo = 0 if cache is None else cache.seen
        if cache is not None and lo == self.log_n:
            return cache
        if cache is not None and lo + 1 == self.log_n:           # one new vector (usual)
            vals = X @ self._log[lo]
            better = vals > cache.vals
            cache.vals[better] = vals[better]
            cache.arg[better] = lo
        else:
            if cache is None or self.log_n - lo > self.actions.size:
                prod = X @ self.alphas.T
                rows = self.log_index
            else:
                prod = X @ self._log[lo:self.log_n].T
                rows = np.arange(lo, self.log_n)
            arg = rows[prod.argmax(axis=1)]
            vals = prod.max(axis=1)
            if cache is None:
                return _LowerCached(vals, arg, self.log_n, self._log)
            better = vals > cache.vals
            cache.vals[better] = vals[better]
            cache.arg[better] = arg[better]
        cache.seen, cache.vectors = self.log_n, self._log
        return cache

    def values(self, X: np.ndarray) -> np.ndarray:
        return (X @ self.alphas.T).max(axis=-1)

    def best(self, X: np.ndarray) -> np.ndarray:
        return (X @ self.alphas.T).argmax(axis=-1)

    def add(self, alpha: np.ndarray, action: int) -> None:
        """One more vector (those it dominates everywhere are dropped)."""
        # Vectors the new one dominates everywhere can never be the best again.
        dominated = (self.alphas <= alpha + _TINY).all(axis=1)
        if dominated.any():
            keep = ~dominated
            self.alphas, self.actions = self.alphas[keep], self.actions[keep]
            if self.log:
                self.log_index = self.log_index[keep]
        self.alphas = np.concatenate((self.alphas, alpha[None]))
        self.actions = np.concatenate((self.actions, (action,)))
        if self.log:
            self.log_index = np.concatenate((self.log_index, (self.log_n,)))
            self._append_log(alpha[None])

    def extend(self, alphas: np.ndarray, actions: np.ndarray) -> None:
        """Several more vectors, none dropped (a sweep's; it prunes after)."""
        self.alphas = np.concatenate((self.alphas, alphas))
        self.actions = np.concatenate((self.actions, actions))
        if self.log:
            self.log_index = np.concatenate((self.log_index,
                                             np.arange(self.log_n, self.log_n + len(actions))))
            self._append_log(alphas)

    def prune(self, *belief_blocks: np.ndarray, corners: bool = False) -> None:
        """Keep the vectors best at one of the beliefs (the others are valid too, but cost
        time), and with ``corners`` at one of the corners (the point masses).

        The best vector at corner s is the argmax of column s: the same as ``best`` at the
        rows of an identity matrix, without making that S x S matrix.
        """
        found = [self.best(block) for block in belief_blocks if len(block)]
        if corners:
            found.append(self.alphas.argmax(axis=0))
        keep = np.unique(np.concatenate(found))
        self.alphas = self.alphas[keep]
        self.actions = self.actions[keep]
        if self.log:
            self.log_index = self.log_index[keep]


def _quiet_ratios(X_t: np.ndarray, inv_t: np.ndarray) -> np.ndarray:
    """:meth:`_UpperBound.ratios` from X.T, for a caller that holds
    ``np.errstate(invalid="ignore")``."""
    return np.fmin.reduce(X_t[:, :, None] * inv_t[:, None, :], axis=0)


class _UpperBound:
    """Corner values and (belief, value) points, evaluated by sawtooth interpolation."""

    def __init__(self, corner: np.ndarray, log: bool = False) -> None:
        self.corner = corner.astype(float)
        S = corner.size
        self.points = np.empty((0, S))
        self.vals = np.empty(0)
        self.excess = np.empty(0)          # value minus the corner interpolation (<= 0 when useful)
        self.inv_t = np.empty((S, 0))      # 1/points (inf off the support), state-major
        self._pruned_size = 0
        # Every point ever added, in order (pruning does not touch it), so that a cached value
        # is brought up to date with the points added since, not recomputed over all points.
        # Cached values stay valid upper bounds whatever happens later (V* does not change);
        # ``epoch`` counts corner changes, after which caches are recomputed to benefit.
        self.log = log
        self.epoch = 0
        self.log_n = 0
        self._log_points = np.empty((16 if log else 0, S))
        self._log_inv_t = np.empty((S, 16 if log else 0))
        self._log_vals = np.empty(16 if log else 0)

    def _append_log(self, B: np.ndarray, values: np.ndarray) -> None:
        k = values.size
        need = self.log_n + k
        if need > self._log_vals.size:
            cap = max(need, 2 * self._log_vals.size)
            S = self.corner.size
            points, inv_t, vals = np.empty((cap, S)), np.empty((S, cap)), np.empty(cap)
            points[:self.log_n] = self._log_points[:self.log_n]
            inv_t[:, :self.log_n] = self._log_inv_t[:, :self.log_n]
            vals[:self.log_n] = self._log_vals[:self.log_n]
            self._log_points, self._log_inv_t, self._log_vals = points, inv_t, vals
        self._log_points[self.log_n:need] = B
        with np.errstate(divide="ignore"):
            self._log_inv_t[:, self.log_n:need] = (1.0 / B).T
        self._log_vals[self.log_n:need] = values
        self.log_n = need

    def cached_values(self, X: np.ndarray, cache: Optional["_Cached"],
                      X_t: Optional[np.ndarray] = None) -> "_Cached":
        """The upper bound at the rows of X, from ``cache`` (the same rows' values, an earlier
        call's result) brought up to date with the points added since; a fresh evaluation when
        there is no cache, the corners have changed or there are more new points than live
        ones. Each value is a minimum of valid bounds, so it is one too. ``X_t``: X.T, C-contiguous,
        given by a caller that holds ``np.errstate(invalid="ignore")`` (the trials: the
        sawtooth's products are faster from it, without an errstate per call)."""
        if cache is None:
            return _Cached(self.values(X, X_t), X @ self.corner, self.log_n, self.epoch)
        if cache.epoch != self.epoch or self.log_n - cache.seen > self.vals.size:
            # Afresh, but never above the cached values (valid too): a bound that went up
            # where pruning dropped a point could send trials round in circles.
            np.minimum(cache.vals, self.values(X, X_t), out=cache.vals)
            cache.base, cache.seen, cache.epoch = X @ self.corner, self.log_n, self.epoch
            return cache
        if self.log_n > cache.seen:
            lo = cache.seen
            excess = self._log_vals[lo:self.log_n] - self._log_points[lo:self.log_n] @ self.corner
            inv_t = self._log_inv_t[:, lo:self.log_n]
            ratio = self.ratios(X, inv_t) if X_t is None else _quiet_ratios(X_t, inv_t)
            tents = cache.base[:, None] + ratio * excess[None, :]
            np.minimum(cache.vals, tents.min(axis=1), out=cache.vals)
            cache.seen = self.log_n
        return cache

    def _set(self, points: np.ndarray, vals: np.ndarray) -> None:
        self.points, self.vals = points, vals
        self.excess = vals - points @ self.corner
        with np.errstate(divide="ignore"):
            self.inv_t = np.ascontiguousarray((1.0 / points).T)

    @staticmethod
    def ratios(X: np.ndarray, inv_t: np.ndarray) -> np.ndarray:
        """(m, n): min over s of X[i, s] / P[j, s] on P's support.

        State-major layout makes the min a reduction over the leading axis (fast slabs); 0·inf
        (s outside both supports) gives nan, which ``fmin`` ignores.
        """
        with np.errstate(invalid="ignore"):
            return _quiet_ratios(X.T, inv_t)

    def values(self, X: np.ndarray, X_t: Optional[np.ndarray] = None) -> np.ndarray:
        """Upper bound at each row of X (m, S); ``X_t``: as in :meth:`cached_values`."""
        base = X @ self.corner
        if self.vals.size == 0:
            return base
        m, S = X.shape
        n = self.vals.size
        if m * S * n <= RATIO_BLOCK:
            # From X.T contiguous while the points are few (faster there, slower past a few
            # hundred points, where numpy's broadcast copies it).
            ratio = self.ratios(X, self.inv_t) if X_t is None or n > CONTIGUOUS_POINTS \
                else _quiet_ratios(X_t, self.inv_t)
            tents = base[:, None] + ratio * self.excess[None, :]
            return np.minimum(base, tents.min(axis=1))
        # In blocks of rows and points, so the (S, rows, points) temporary stays within
        # RATIO_BLOCK numbers; every step is an exact min, so the result is the same.
        rows = max(1, RATIO_BLOCK // (S * n))
        cols = n if rows > 1 else max(1, RATIO_BLOCK // S)
        out = np.empty(m)
        for lo in range(0, m, rows):
            x, b = X[lo:lo + rows], base[lo:lo + rows]
            best = b.copy()
            for c in range(0, n, cols):
                tents = b[:, None] + self.ratios(x, self.inv_t[:, c:c + cols]) \
                    * self.excess[None, c:c + cols]
                best = np.minimum(best, tents.min(axis=1))
            out[lo:lo + rows] = best
        return out

    def add(self, B: np.ndarray, values: np.ndarray, prune: bool = True) -> None:
        """Record that V* <= values[i] at belief B[i] (rows at a vertex lower that corner);
        ``prune``: prune when the points have doubled since the last pruning."""
        B = np.atleast_2d(B)
        values = np.atleast_1d(np.asarray(values, dtype=float))
        vertex = B.max(axis=1) >= 1.0 - 1e-12
        if vertex.any():
            idx = B[vertex].argmax(axis=1)
            np.minimum.at(self.corner, idx, values[vertex])
            self.excess = self.vals - self.points @ self.corner
            self.epoch += 1
            B, values = B[~vertex], values[~vertex]
        if values.size == 0:
            return
        if self.log:
            self._append_log(B, values)
        points, vals = self.points, self.vals
        if values.size == 1 and vals.size:
            # Points at which the new point alone gives a bound at least as low are redundant;
            # this also replaces an older point at the same belief (trials revisit beliefs).
            b, v = B[0], values[0]
            with np.errstate(divide="ignore"):
                ratio = self.ratios(points, (1.0 / b)[:, None])[:, 0]
            keep = points @ self.corner + ratio * (v - b @ self.corner) > vals + _TINY
            points, vals = points[keep], vals[keep]
        self._set(np.vstack([points, B]), np.concatenate([vals, values]))
        if prune and self.vals.size > 2 * self._pruned_size + 16:
            self.prune()

    def add_one(self, b: np.ndarray, value: float) -> None:
        """``add`` for one belief (a trial's backup), without the batch's array handling: the
        new point's excess and reciprocal are appended, not the whole set's recomputed. The
        caller holds ``np.errstate(divide="ignore", invalid="ignore")``."""
        if b.max() >= 1.0 - 1e-12 or self.vals.size == 0:
            self.add(b[None], np.array([value]))
            return
        if self.log:
            self._append_log(b[None], np.array([value]))
        inv_b = 1.0 / b
        base_b = float(b @ self.corner)
        # Points at which the new point alone gives a bound at least as low are redundant;
        # this also replaces an older point at the same belief (trials revisit beliefs).
        ratio = _quiet_ratios(self.points.T, inv_b[:, None])[:, 0]
        keep = (self.vals - self.excess) + ratio * (value - base_b) > self.vals + _TINY
        points, vals, excess, inv_t = self.points, self.vals, self.excess, self.inv_t
        if not keep.all():
            # (inv_t.compress, not inv_t[:, keep]: that one is not C-contiguous, and the
            # sawtooth's products over a non-contiguous inv_t are several times slower)
            points, vals, excess = points[keep], vals[keep], excess[keep]
            inv_t = inv_t.compress(keep, axis=1)
        self.points = np.concatenate((points, b[None]))
        self.vals = np.concatenate((vals, (value,)))
        self.excess = np.concatenate((excess, (value - base_b,)))
        self.inv_t = np.concatenate((inv_t, inv_b[:, None]), axis=1)
        if self.vals.size > 2 * self._pruned_size + 16:
            self.prune()

    def prune(self) -> None:
        """Drop points that do not lower the bound at their own belief (HSVI2's rule).

        Removing points only loosens the bound, so the result is valid whatever is dropped; the
        tie rule (a later point wins) keeps one of several points at the same belief.
        """
        n = self.vals.size
        if n >= 2:
            keep = np.ones(n, dtype=bool)
            base = self.points @ self.corner
            # Rows in chunks so the (S, rows, n) temporary stays small.
            step = max(1, 2_000_000 // (n * self.corner.size))
            later = np.arange(n)
            for lo in range(0, n, step):
                rows = np.arange(lo, min(lo + step, n))
                tent = base[rows, None] + self.ratios(self.points[rows], self.inv_t) * self.excess
                tent[rows - lo, rows] = np.inf
                v = self.vals[rows][:, None]
                strictly = (tent < v - _TINY).any(axis=1)
                tie = ((tent <= v + _TINY) & (later[None, :] > rows[:, None])).any(axis=1)
                keep[rows] = ~(strictly | tie) & (self.vals[rows] < base[rows] - _TINY)
            self._set(self.points[keep], self.vals[keep])
        self._pruned_size = self.vals.size


@dataclass
class _Cached:
    """Upper-bound values at some beliefs, as of ``seen`` logged points and corner ``epoch``;
    ``base`` is the corner interpolation at them."""

    vals: np.ndarray
    base: np.ndarray
    seen: int
    epoch: int


@dataclass
class _LowerCached:
    """Lower-bound values at some beliefs and, for each, the row of ``vectors`` that gives it,
    as of ``seen`` logged vectors."""

    vals: np.ndarray
    arg: np.ndarray
    seen: int
    vectors: np.ndarray


class _Node:
    """A belief of the trials' tree (SARSOP's reachable belief tree): its successors under
    every action and observation, computed once, and both bounds there and at itself, cached
    between visits (:meth:`_UpperBound.cached_values`, :meth:`_LowerBound.cached`).

    ``rows`` is the belief followed by its successors of non-zero probability, action by
    action (``succ[j]``, row 1 + j, is the successor under (a, z) = divmod(succ[j], Z), of
    probability ``p_succ[j]``; action a's are rows 1 + start[a] to 1 + start[a + 1]), the rows
    of both caches (``up``, ``lo``); ``children`` the nodes of the successors a trial went to,
    by row. A successor of probability zero counts in no bound at the node, so it is not kept.
    """

    __slots__ = ("b", "key", "rows", "rows_t", "rb", "up", "lo", "kept", "children",
                 "succ", "p_succ", "start", "p_matrix", "has_zero")

    def __init__(self, b: np.ndarray, key: Optional[bytes] = None) -> None:
        self.b = b
        self.key = key
        self.rows: Optional[np.ndarray] = None
        self.rows_t: Optional[np.ndarray] = None
        self.rb: Optional[np.ndarray] = None
        self.up: Optional[_Cached] = None
        self.lo: Optional[_LowerCached] = None
        self.kept = False
        self.children: dict = {}

    def drop_successors(self) -> None:
        """Forget the successors (computed again when needed), keeping the cached bounds."""
        self.rows = self.rows_t = self.p_matrix = None


def _belief_key(b: np.ndarray) -> bytes:
    """A digest of the rounded belief, not its bytes: the key of a 50,000-state belief would
    otherwise take as much memory as the belief."""
    return hashlib.blake2b(np.round(b, 10).tobytes(), digest_size=16).digest()


class _BeliefSet:
    """Distinct beliefs met by the trials and the sweeps, each with a reach weight.

    The weight of a belief is the largest P(k)·γ^t·P(path) over the ways it has been reached from
    a root b_k; sweeps back up the heaviest beliefs (those that matter most to the value at the
    start) and add the successors of each belief the first time it is swept, so the set grows
    toward closure.
    """

    def __init__(self, S: int, capacity: Optional[int] = None) -> None:
        self.S = S
        self.capacity = capacity               # most beliefs kept (None: no limit)
        self._rows: List[np.ndarray] = []
        self._weights: List[float] = []
        self._expanded: List[bool] = []
        self._keys: dict = {}

    def __len__(self) -> int:
        return len(self._rows)

    def add(self, B: np.ndarray, weights) -> None:
        B = np.atleast_2d(B)
        weights = np.broadcast_to(np.asarray(weights, dtype=float), (B.shape[0],))
        for b, w in zip(B, weights):
            self.add_one(b, w)

    def add_one(self, b: np.ndarray, weight: float, key: Optional[bytes] = None) -> None:
        """``add`` for one belief; ``key``: its ``_belief_key`` if known."""
        if key is None:
            key = _belief_key(b)
        i = self._keys.get(key)
        if i is None:
            if self.capacity is not None and len(self._rows) >= self.capacity:
                return                         # full: the memory budget is spent
            self._keys[key] = len(self._rows)
            self._rows.append(b.copy())
            self._weights.append(float(weight))
            self._expanded.append(False)
        elif weight > self._weights[i]:
            self._weights[i] = float(weight)

    def top(self, n: int) -> np.ndarray:
        """Indices of the ``n`` heaviest beliefs."""
        w = np.asarray(self._weights)
        if w.size <= n:
            return np.arange(w.size)
        return np.argpartition(-w, n - 1)[:n]

    def rows(self, idx: np.ndarray) -> np.ndarray:
        return np.array([self._rows[i] for i in idx]).reshape(len(idx), self.S)

    def blocks(self, rows: int) -> Iterator[np.ndarray]:
        """Every belief, as arrays of at most ``rows`` rows (a copy of the whole set at once
        would double its memory)."""
        for lo in range(0, len(self._rows), rows):
            yield np.array(self._rows[lo:lo + rows]).reshape(-1, self.S)

    def weights(self, idx: np.ndarray) -> np.ndarray:
        return np.array([self._weights[i] for i in idx])

    def take_unexpanded(self, idx: np.ndarray) -> np.ndarray:
        """Which of ``idx`` have not had their successors added yet (and mark them added)."""
        mask = np.array([not self._expanded[i] for i in idx], dtype=bool)
        for i in np.asarray(idx)[mask]:
            self._expanded[i] = True
        return mask


class HsviSolver:
    """The solver's state; ``run`` may be called again to continue (anytime).

    ``deadline`` (a ``time.perf_counter()`` instant) bounds the setup: the MDP bounds stop
    there, still valid. ``memory_limit`` (bytes) is the budget of :data:`memory_needed` plus
    the stored vectors; None: no limit.
    """

    def __init__(self, model: Model, deadline: Optional[float] = None,
                 memory_limit: Optional[int] = None) -> None:
        if model.fully_observable:
            raise SolverError("HSVI is for POMDPs; solve an MDP with value iteration")
        began = time.perf_counter()
        _check_size(model)
        S = model.n_states
        # Vectors of S numbers the budget leaves for beliefs, points and alpha vectors.
        self.max_vectors: Optional[int] = None
        if memory_limit is not None:
            fixed = memory_needed(model)
            memory.require(fixed + MIN_VECTORS * 8 * S, memory_limit,
                           model.source or model.name or "the model",
                           f"solving ({S} states, {model.n_actions} actions, "
                           f"{model.n_observations} observations)")
            self.max_vectors = int((memory_limit - fixed) // (8 * S))
        self.model = model
        self.t = _Tables(model)
        self.b0 = np.asarray(model.initial_belief, dtype=float)
        # The roots: the initial belief split by the fully observed values seen at the start
        # (one root, the initial belief, when there are none).
        split = model.start_split()
        self.root_weights = np.array([w for w, _ in split])
        self.roots = np.array([b for _, b in split]).reshape(len(split), self.t.S)
        blind = mdp.blind_lower_bound(model, deadline=deadline)
        fib = mdp.fast_informed_bound(model, deadline=deadline)
        # The belief tree keeps every node's successors and cached bounds while they take at
        # most TREE_NUMBERS numbers (a small model's whole tree); a model whose successors are
        # too large to keep has no tree.
        self.keep_successors = self.t.A * self.t.Z * self.t.S <= KEEP_SUCCESSORS
        self.lower = _LowerBound(blind.copy(), np.arange(model.n_actions),
                                 log=self.keep_successors)
        self.tree: dict = {}
        self.tree_budget = TREE_NUMBERS if self.keep_successors else 0
        # A node costs its successors (A·Z rows of S, twice: ``rows`` and ``rows_t``), an (A,
        # A·Z) matrix and a few A·Z arrays, in vectors of S.
        self.node_vectors = (2 * self.t.A * self.t.Z + -(-(6 + self.t.A) * self.t.A * self.t.Z
                                                         // self.t.S) + 3)
        self.upper = _UpperBound(fib.max(axis=0), log=self.tree_budget > 0)
        for root in self.roots:
            self.upper.add(root, float((fib @ root).max()))
        capacity = None if self.max_vectors is None else max(len(self.roots),
                                                             self.max_vectors // 2)
        self.beliefs = _BeliefSet(self.t.S, capacity)
        for w, root in zip(self.root_weights, self.roots):
            self.beliefs.add(root, w)
        self.trials = 0
        self.sweeps = 0
        self.sweep_seconds = 0.0
        self.backups = 0
        self.memory_limit_reached = False
        self.corner_rounds_done = False
        self.seconds = time.perf_counter() - began

    # -- memory --------------------------------------------------------------------------------
    def _vectors_in_use(self) -> int:
        """Stored vectors of S numbers, with the copies their updates make: a point is kept
        with its reciprocal and copied when points are added; alpha vectors are copied too."""
        return (len(self.beliefs) + 4 * self.upper.vals.size + 2 * self.lower.actions.size
                + 2 * self.upper.log_n + self.lower.log_n + len(self.tree) * self.node_vectors)

    def _room(self, vectors: int) -> bool:
        """Whether ``vectors`` more fit in the memory budget."""
        return self.max_vectors is None or self._vectors_in_use() + vectors <= self.max_vectors

    def _sweep_growth(self) -> int:
        """Vectors one sweep may add before it prunes: a point and an alpha vector per belief
        it backs up, and their copies, plus its rows."""
        n_max = max(32, int(np.sqrt(SWEEP_BUDGET / (self.t.A * self.t.Z * self.t.S))))
        return 8 * min(n_max, len(self.beliefs))

    def _step_cost(self) -> int:
        """Vectors one more step of a trial's path costs: the belief, its successors when they
        are kept, and what its backup adds (a belief, a point, an alpha vector, their copies)."""
        return 8 + (self.t.A * self.t.Z if self.keep_successors else 0)

    # -- bounds at one belief ------------------------------------------------------------------
    def bounds(self, b: Optional[np.ndarray] = None) -> Tuple[float, float]:
        """(lower, upper) at ``b``; by default at the start: Σ_k P(k)·bound(b_k) over the roots
        (the bounds at the initial belief when nothing is fully observed)."""
        if b is None:
            lo, up = self._root_bounds()
            return float(self.root_weights @ lo), float(self.root_weights @ up)
        x = np.asarray(b, dtype=float)
        return float(self.lower.values(x[None])[0]), float(self.upper.values(x[None])[0])

    def _root_bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """The lower and upper bounds at each root."""
        return self.lower.values(self.roots), self.upper.values(self.roots)

    # -- the belief tree ------------------------------------------------------------------------
    def _node(self, b: np.ndarray) -> _Node:
        """The tree's node at belief b (made on the first visit). Nodes are kept while the
        tree's budget lasts; past it (and for models whose successors are too large to keep) a
        node lives for one trial and its successors are computed again."""
        key = _belief_key(b) if self.tree_budget > 0 else None
        node = self.tree.get(key) if key is not None else None
        if node is not None:
            return node
        node = _Node(b, key)
        if key is not None and self._room(self.node_vectors):
            self.tree[key] = node
            node.kept = True
            self.tree_budget -= 2 * self.t.A * self.t.Z * self.t.S
        return node

    def _child(self, node: _Node, row: int) -> _Node:
        """The node of successor ``row`` of ``node`` (a row of ``node.rows``), remembered when
        both are kept (no belief key to compute on the next visit)."""
        child = node.children.get(row)
        if child is None:
            child = self._node(node.rows[row])
            if node.kept and child.kept:
                node.children[row] = child
        return child

    def _refresh(self, node: _Node) -> None:
        """Bring the node's cached bounds (at its belief and its successors) up to date,
        computing its successors first if they are not kept."""
        if node.rows is None:
            t = self.t
            p, B = t.successors(node.b)
            p_flat = p.ravel()
            succ = np.flatnonzero(p_flat > 0)
            node.rows = np.concatenate((node.b[None], B.reshape(-1, t.S)[succ]))
            node.rows_t = np.ascontiguousarray(node.rows.T)
            action = succ // t.Z
            if node.rb is None:
                node.succ, node.p_succ = succ, p_flat[succ]
                node.start = np.searchsorted(action, np.arange(t.A + 1))
                node.has_zero = (p <= 0).any(axis=1)
                node.rb = t.R @ node.b
            # Q = R·b + γ Σ_z p(z|b,a)·U(successor): one product with this (A, successors).
            node.p_matrix = np.zeros((t.A, succ.size))
            node.p_matrix[action, np.arange(succ.size)] = t.gamma * node.p_succ
        node.up = self.upper.cached_values(node.rows, node.up, node.rows_t)
        node.lo = self.lower.cached(node.rows, node.lo)

    def _q_upper(self, node: _Node) -> np.ndarray:
        """Upper-bound Q values at a refreshed node, (A,)."""
        return node.rb + node.p_matrix @ node.up.vals[1:]

    # -- one trial -----------------------------------------------------------------------------
    def _trial(self, precision: float, deadline: float) -> None:
        # The sawtooth's 0·inf (a state outside both supports) and a new point's 1/0: expected
        # (see _UpperBound.ratios), silenced once for the whole trial.
        with np.errstate(divide="ignore", invalid="ignore"):
            self._trial_quiet(precision, deadline)

    def _trial_quiet(self, precision: float, deadline: float) -> None:
        gamma = self.t.gamma
        # The root whose weighted gap exceeds the target the most: while the weighted sum of
        # the gaps is above ``precision``, some root's gap is, and this picks one of those.
        lo, up = self._root_bounds()
        k = int(np.argmax(self.root_weights * (up - lo - precision)))
        # The trial's target is a fraction ZETA of the root's gap, never below the precision
        # (HSVI2's and SARSOP's dynamic target): early trials stay shallow, where the bounds
        # are loose everywhere, and go deeper as the gap closes. The solver still stops only
        # at a gap <= precision.
        width = max(precision, TRIAL_ZETA * float(up[k] - lo[k]))
        node = self._node(self.roots[k])
        path: List[Tuple[_Node, float]] = []
        weight = float(self.root_weights[k])
        step_cost = self._step_cost()
        link: Optional[Tuple[_Node, int]] = None     # the node's row in its parent's caches
        while True:
            self._refresh(node)
            up_vals, lo_vals = node.up.vals, node.lo.vals
            lo_b = float(lo_vals[0])
            # The stored bound, not the one-step lookahead: stopping on a gap that no stored point
            # records would leave the parent's backup unchanged and repeat the same trial forever.
            up_b = float(up_vals[0])
            if link is not None:
                # The node's own cache and its parent's may hold different valid bounds for
                # the same belief: both take the lower, so the parent's backup sees the value
                # the trial stops on (else it could repeat the same trial forever).
                parent, i = link
                up_b = min(up_b, float(parent.up.vals[i]))
                up_vals[0] = parent.up.vals[i] = up_b
            if up_b - lo_b <= width or gamma == 0.0:
                break
            path.append((node, weight))
            a = int(self._q_upper(node).argmax())
            width /= gamma
            first, last = int(node.start[a]), int(node.start[a + 1])
            score = node.p_succ[first:last] * (up_vals[1 + first:1 + last]
                                               - lo_vals[1 + first:1 + last] - width)
            j = int(score.argmax())
            # An observation of probability zero scores 0: it is the best when all others
            # score below, and a trial stops there.
            if (node.has_zero[a] and score[j] < 0.0) or time.perf_counter() > deadline:
                break
            p_az = float(node.p_succ[first + j])
            row = 1 + first + j
            if not self._room((len(path) + 1) * step_cost):
                break                          # a deeper path would not fit in the budget
            child = self._child(node, row)
            if not self.keep_successors:
                node.drop_successors()         # computed again in the backup
            link = (node, row)
            node = child
            weight *= gamma * p_az
        for node, weight in reversed(path):
            self._backup(node)
            self.beliefs.add_one(node.b, weight, node.key)
            if time.perf_counter() > deadline:
                break                          # the deeper backups are done; all stay valid
        self.trials += 1

    def _backup(self, node: _Node) -> None:
        """Point-based backup of both bounds at the node's belief."""
        t = self.t
        self._refresh(node)
        b = node.b
        A, Z, S = t.A, t.Z, t.S
        # Lower: the best vector at each successor, pulled back through O and T. At a
        # successor of probability zero the vector counts at no state of b, only at the
        # others: the oldest current vector is taken there (as the argmax of a zero row
        # did; the blind vector of the first action, say, makes far more vectors that
        # dominate none: 1,500 instead of 600 on robot_fitted.pomdp).
        arg = np.full(A * Z, self.lower.log_index[0] if self.lower.log else 0)
        arg[node.succ] = node.lo.arg[1:]
        chosen = node.lo.vectors[arg]                                      # (A·Z, S')
        if t.G is not None:
            cand = t.R + (t.G @ chosen.reshape(A, Z * S, 1))[:, :, 0]     # (A, S)
        else:
            w = np.einsum("azs,azs->as", t.OT, chosen.reshape(A, Z, S))
            cand = t.R + t.gamma * t.back(w)
        vals = cand @ b
        a = int(vals.argmax())
        if vals[a] > node.lo.vals[0] + _TINY:
            self.lower.add(cand[a], a)
        # Upper: one-step lookahead over the current upper bound.
        new_up = float(self._q_upper(node).max())
        if new_up < node.up.vals[0] - _TINY:
            self.upper.add_one(b, new_up)
        if not self.keep_successors:
            node.drop_successors()
        self.backups += 1

    # -- sweeps --------------------------------------------------------------------------------
    def _sweep_set(self) -> Tuple[np.ndarray, np.ndarray]:
        """Indices and rows of the beliefs one sweep backs up: the heaviest within a work budget."""
        t = self.t
        # A sweep costs about N·A·Z·(points)·S; points grow with N, so the budget caps N².
        n_max = max(32, int(np.sqrt(SWEEP_BUDGET / (t.A * t.Z * t.S))))
        idx = self.beliefs.top(n_max)
        return idx, self.beliefs.rows(idx)

    def _sweep(self, deadline: float = math.inf) -> None:
        """Back both bounds up at every belief of the sweep set at once (PBVI-style).

        In numpy a batch costs about as much as a single backup, and on problems whose trials
        cycle through the same beliefs (Tiger) sweeps propagate improvements far faster than
        trials alone. Both updates keep the bounds valid: any backup of valid vectors is a valid
        vector, and the Bellman backup of an upper bound is an upper bound. At ``deadline`` the
        sweep ends after its current chunk and keeps the backups done so far.
        """
        t = self.t
        idx, X = self._sweep_set()
        fresh = self.beliefs.take_unexpanded(idx)
        weights = self.beliefs.weights(idx)
        N, S = X.shape
        A, Z = t.A, t.Z
        n_pts = max(1, self.upper.vals.size)
        # Chunks keep the sawtooth's (beliefs x points x states) temporary array bounded.
        chunk = max(1, int(SWEEP_CHUNK // (A * Z * n_pts * S)))
        new_up = np.empty(N)
        new_alpha = np.empty((N, S))
        new_act = np.empty(N, dtype=np.int64)
        # The current bounds at the sweep's beliefs, chunk by chunk too (on a large model they
        # cost as much as a chunk): the backups change them only after the loop.
        old_lo = np.empty(N)
        old_up = np.empty(N)
        done = 0
        for lo in range(0, N, chunk):
            if lo > 0 and time.perf_counter() > deadline:
                break
            x = X[lo:lo + chunk]
            n = x.shape[0]
            if t.dense:
                pred = np.einsum("ns,ast->nat", x, t.T)
            else:
                pred = np.stack([np.vstack([tt @ xi for tt in t.Tt]) for xi in x])
            joint = pred[:, :, None, :] * t.OT[None]                      # (n, A, Z, S)
            p = joint.sum(axis=3)
            succ = joint / np.where(p > 0, p, 1.0)[..., None]
            flat = succ.reshape(n * A * Z, S)
            new = fresh[lo:lo + n]
            if new.any():
                reach = (weights[lo:lo + n, None, None] * t.gamma * p)[new]
                self.beliefs.add(succ[new][reach > 0], reach[reach > 0])
            ub = self.upper.values(flat).reshape(n, A, Z)
            q_up = x @ t.R.T + t.gamma * (p * ub).sum(axis=2)
            new_up[lo:lo + n] = q_up.max(axis=1)
            best = self.lower.best(flat).reshape(n, A, Z)
            w = np.einsum("azs,nazs->nas", t.OT, self.lower.alphas[best])
            if t.dense:
                back = np.einsum("ast,nat->nas", t.T, w)
            else:
                back = np.stack([t.back(wi) for wi in w])
            cand = t.R[None] + t.gamma * back                             # (n, A, S)
            a = np.einsum("nas,ns->na", cand, x).argmax(axis=1)
            new_alpha[lo:lo + n] = cand[np.arange(n), a]
            new_act[lo:lo + n] = a
            old_lo[lo:lo + n] = self.lower.values(x)
            old_up[lo:lo + n] = self.upper.values(x)
            done = lo + n
        if done < N:
            X, new_up, new_alpha, new_act = X[:done], new_up[:done], new_alpha[:done], \
                new_act[:done]
            old_lo, old_up = old_lo[:done], old_up[:done]
        # Lower: keep the candidates that improve at their own belief.
        gain = np.einsum("ns,ns->n", new_alpha, X) - old_lo
        better = gain > _TINY
        if better.any():
            self.lower.extend(new_alpha[better], new_act[better])
            self.lower.prune(X, corners=True)
        # Upper: record the backed-up values that improve on the current bound. Pruning the
        # points costs O(points² · S), seconds on a large model: not once the time is up.
        in_time = time.perf_counter() <= deadline
        lower_up = new_up < old_up - _TINY
        if lower_up.any():
            self.upper.add(X[lower_up], new_up[lower_up], prune=in_time)
            if in_time:
                self.upper.prune()
        self.backups += done
        self.sweeps += 1

    def _corner_rounds(self, precision: float, deadline: float) -> None:
        """PBVI-style rounds of backups at every corner (point mass) before the first trial,
        while a round moves some corner's bounds by more than VERTEX_ROUND_STOP x the gap at
        the start (at most VERTEX_ROUNDS). The blind policies' vectors are far below V* at the
        corners (2.9 below on robot_completed.pomdp, 25 on robot.pomdp); a few rounds there
        raise the lower bound everywhere for the cost of a few trials, and the trials need
        fewer backups (robot_completed.pomdp 290 -> 219 with the rounds' 35)."""
        S = self.t.S
        lo, up = self.bounds()
        if not self.keep_successors or S > VERTEX_STATES or up - lo <= precision:
            return
        stop = VERTEX_ROUND_STOP * (up - lo)
        corners = np.eye(S)
        with np.errstate(divide="ignore", invalid="ignore"):
            for _ in range(VERTEX_ROUNDS):
                lower_before = self.lower.values(corners)
                upper_before = self.upper.corner.copy()
                for e in corners:
                    if time.perf_counter() > deadline or not self._room(self._step_cost()):
                        return
                    self._backup(self._node(e))
                moved = max(float((self.lower.values(corners) - lower_before).max()),
                            float((upper_before - self.upper.corner).max()))
                if moved <= stop:
                    break

    def _sweeps(self, precision: float, deadline: float, rate_to_beat: float,
                max_sweeps: int = 10_000) -> float:
        """Sweep while it pays: while a sweep narrows the gap at the start faster per second
        (:func:`_log_rate`) than the trials have lately (``rate_to_beat``); at most
        ``max_sweeps``. Returns the last sweep's rate."""
        lo, up = self.bounds()
        rate = 0.0
        for _ in range(max_sweeps):
            if up - lo <= precision or time.perf_counter() > deadline:
                break
            if not self._room(self._sweep_growth()):
                break
            began = time.perf_counter()
            self._sweep(deadline)
            new_lo, new_up = self.bounds()
            spent = time.perf_counter() - began
            rate = _log_rate(up - lo, new_up - new_lo, spent)
            self.sweep_seconds += spent
            lo, up = new_lo, new_up
            if rate <= rate_to_beat:
                break
        return rate

    def _prune(self) -> None:
        self.upper.prune()
        # Beliefs in blocks, so their rows are never all copied at once.
        rows = max(1, RATIO_BLOCK // self.t.S)
        self.lower.prune(self.roots, *self.beliefs.blocks(rows), corners=True)

    def _out_of_memory(self) -> bool:
        """Whether the stored vectors leave no room for another trial step and a sweep, even
        after pruning; True also records that the budget stopped the solver."""
        needed = self._sweep_growth() + 2 * self._step_cost()
        if self._room(needed):
            return False
        self._prune()
        if self._room(needed):
            return False
        self.memory_limit_reached = True
        return True

    # -- the loop ------------------------------------------------------------------------------
    def run(self, timeout: Optional[float] = 60.0, precision: float = 1e-3,
            progress: Optional[Callable[[SolveProgress], None]] = None,
            max_trials: Optional[int] = None) -> Tuple[float, float]:
        """Improve the bounds until their gap at the start (see ``bounds``) is <= ``precision``,
        time is up or (with a memory limit) the stored vectors would outgrow the budget."""
        if precision <= 0:
            raise SolverError(f"precision must be positive, got {precision}")
        start = time.perf_counter()
        deadline = start + timeout if timeout is not None else float("inf")
        if not self.corner_rounds_done:
            self.corner_rounds_done = True
            self._corner_rounds(precision, deadline)
        lo, up = self.bounds()
        trials = 0
        # Trials and sweeps share the time by how fast each narrows the gap at the start
        # (_log_rate): the trials' rate over their last few (one trial's gain is lumpy), a
        # sweep's own rate. Trials go first; sweeps run when the trials' rate falls to the
        # last sweep's (0 before any: only when trials stall), and go on while they are faster.
        recent: Deque[Tuple[float, float]] = deque(maxlen=8)
        sweep_rate = 0.0
        while up - lo > precision and time.perf_counter() < deadline:
            if max_trials is not None and trials >= max_trials:
                break
            if self._out_of_memory():
                break
            if len(recent) == recent.maxlen:
                trial_rate = sum(g for g, _ in recent) / max(sum(d for _, d in recent), 1e-9)
                if sweep_rate >= trial_rate:
                    sweep_rate = self._sweeps(precision, deadline, trial_rate)
                    recent.clear()             # the trials' rate after the sweeps is new
                    lo, up = self.bounds()
            if up - lo <= precision or time.perf_counter() > deadline:
                break
            began, gap = time.perf_counter(), up - lo
            self._trial(precision, deadline)
            trials += 1
            lo, up = self.bounds()
            spent = time.perf_counter() - began
            recent.append((_log_rate(gap, up - lo, spent) * spent, spent))
            if progress is not None:
                progress(SolveProgress(self.seconds + time.perf_counter() - start, self.trials,
                                       lo, up, self.lower.actions.size, self.upper.vals.size))
        self.seconds += time.perf_counter() - start
        return lo, up

    def policy(self, prune: bool = True) -> Policy:
        """The lower-bound vectors as a Policy, with the bounds at the start and statistics;
        ``prune`` first drops the vectors and points that are best nowhere the solver looked."""
        if prune:
            self._prune()
        lo, up = self.bounds()
        m = self.model
        return Policy(alphas=self.lower.alphas.copy(), actions=self.lower.actions.copy(),
                      state_names=list(m.states), action_names=list(m.actions),
                      discount=m.discount, lower=lo, upper=up, kind="alpha", model_name=m.name,
                      stats={"solver": "hsvi2", "seconds": self.seconds, "trials": self.trials,
                             "sweeps": self.sweeps, "backups": self.backups,
                             "alphas": int(self.lower.actions.size),
                             "upper_points": int(self.upper.vals.size),
                             "memory_limit_reached": self.memory_limit_reached})


def solve(model: Model, timeout: Optional[float] = 60.0, precision: float = 1e-3,
          progress: Optional[Callable[[SolveProgress], None]] = None,
          memory_limit: Optional[int] = None) -> Policy:
    """Solve ``model`` offline: HSVI2 for a POMDP, value iteration for an MDP; a model with
    fully observed variables that its observations tell (``momdp.applies``) by blocks, with
    the same search (:mod:`ros_hrc.pomdp.momdp`, as SARSOP does).

    The returned policy carries ``lower``/``upper``, bounds on the optimal value at the start
    (the initial belief; with fully observed variables Σ_k P(k) V*(b_k) over
    ``model.start_split()``, what SARSOP reports), and ``stats`` (seconds, trials, ...). Stops
    when ``upper - lower <= precision`` or ``timeout`` seconds (None: no limit) after the call,
    the building of the solver's tables included. ``memory_limit`` (bytes, None: none): see
    the module's docstring.
    """
    start = time.perf_counter()
    deadline = start + timeout if timeout is not None else None
    if model.fully_observable:
        return solve_mdp(model, timeout=timeout, precision=precision, memory_limit=memory_limit)
    from ros_hrc.pomdp import momdp                # imports this module
    if momdp.applies(model):
        return momdp.solve(model, timeout=timeout, precision=precision,
                           memory_limit=memory_limit, progress=progress)
    solver = HsviSolver(model, deadline=deadline, memory_limit=memory_limit)
    remaining = None if deadline is None else max(0.0, deadline - time.perf_counter())
    solver.run(timeout=remaining, precision=precision, progress=progress)
    # Pruning the upper bound's points costs O(points² · S): skipped once the time is up
    # (the unpruned vectors and points are as valid, and the bounds at least as tight).
    return solver.policy(prune=deadline is None or time.perf_counter() < deadline)


def mdp_memory_needed(model: Model) -> int:
    """Bytes value iteration needs: the model and a few (A, S) arrays (dense T when small)."""
    A, S = model.n_actions, model.n_states
    dense = 8 * A * S * S if model.dense_tables_fit else 0
    return memory.model_bytes(model) + 8 * 8 * A * S + dense


def solve_mdp(model: Model, timeout: Optional[float] = 60.0, precision: float = 1e-3,
              memory_limit: Optional[int] = None) -> Policy:
    """Value iteration, stored as a policy with one vector Q[a] per action (kind "mdp").

    Its bounds are b0·V ± the error bound: the start value of an MDP, whose start state is seen
    (each state its own key, so Σ_k P(k) V(b_k) = b0·V).
    """
    memory.require(mdp_memory_needed(model), memory_limit, model.source or model.name or
                   "the model", f"value iteration ({model.n_states} states, "
                                f"{model.n_actions} actions)")
    start = time.perf_counter()
    # The bracket b0·V ± error_bound must be narrower than the precision asked for.
    sol = mdp.value_iteration(model, epsilon=min(precision / 2.0, 1e-6), timeout=timeout)
    seconds = time.perf_counter() - start
    b0 = np.asarray(model.initial_belief, dtype=float)
    centre = float(b0 @ sol.V)
    slack = sol.error_bound
    return Policy(alphas=sol.Q.copy(), actions=np.arange(model.n_actions),
                  state_names=list(model.states), action_names=list(model.actions),
                  discount=model.discount, lower=centre - slack, upper=centre + slack, kind="mdp",
                  model_name=model.name,
                  stats={"solver": "value_iteration", "seconds": seconds,
                         "iterations": sol.iterations, "residual": sol.residual,
                         "state_policy": [int(a) for a in sol.policy]})
