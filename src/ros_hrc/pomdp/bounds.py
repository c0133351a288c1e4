"""The two bounds on the optimal value function V* that HSVI2 tightens (:mod:`ros_hrc.pomdp.hsvi`,
and block by block :mod:`ros_hrc.pomdp.momdp`):

* :class:`LowerBound`: a set of alpha vectors (each the value of a conditional plan, so every
  vector is a valid bound); the solvers start it from the blind policies (repeat one action
  forever);
* :class:`UpperBound`: corner values plus a set of (belief, value) points, read with the
  sawtooth interpolation; the solvers start it from the fast informed bound.

With ``log``, each bound also keeps every vector (point) ever added, in order, so that a value
cached at some beliefs (:class:`LowerCached`, :class:`UpperCached`) is brought up to date with
the vectors (points) added since instead of recomputed over all of them: the sawtooth is a
minimum over points, the lower bound a maximum over vectors, and every cached value stays a
valid bound whatever happens later, since V* does not change.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

#: A bound change smaller than this is treated as no change (stops rounding noise piling up).
TINY = 1e-10

#: Numbers in one block of the sawtooth's (states x beliefs x points) temporary: 32 MB.
RATIO_BLOCK = 4_000_000

#: Most upper-bound points for which the sawtooth is taken from X.T made contiguous.
CONTIGUOUS_POINTS = 600


class LowerBound:
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

    def cached(self, X: np.ndarray, cache: Optional["LowerCached"]) -> "LowerCached":
        """The lower bound at the rows of X and the vector giving it, from ``cache`` (an
        earlier call's result for the same rows) brought up to date with the vectors added
        since. Every vector ever added is a valid bound, so the maximum over them is one too
        (at least the current vectors' maximum). A fresh evaluation, over the current vectors,
        when there is no cache or more new vectors than current ones. Without a log: the
        current vectors."""
        if not self.log:
            prod = X @ self.alphas.T
            return LowerCached(prod.max(axis=1), prod.argmax(axis=1), 0, self.alphas)
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
                return LowerCached(vals, arg, self.log_n, self._log)
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
        dominated = (self.alphas <= alpha + TINY).all(axis=1)
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
    """:meth:`UpperBound.ratios` from X.T, for a caller that holds
    ``np.errstate(invalid="ignore")``."""
    return np.fmin.reduce(X_t[:, :, None] * inv_t[:, None, :], axis=0)


class UpperBound:
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

    def cached_values(self, X: np.ndarray, cache: Optional["UpperCached"],
                      X_t: Optional[np.ndarray] = None) -> "UpperCached":
        """The upper bound at the rows of X, from ``cache`` (the same rows' values, an earlier
        call's result) brought up to date with the points added since; a fresh evaluation when
        there is no cache, the corners have changed or there are more new points than live
        ones. Each value is a minimum of valid bounds, so it is one too. ``X_t``: X.T, C-contiguous,
        given by a caller that holds ``np.errstate(invalid="ignore")`` (the trials: the
        sawtooth's products are faster from it, without an errstate per call)."""
        if cache is None:
            return UpperCached(self.values(X, X_t), X @ self.corner, self.log_n, self.epoch)
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
            keep = points @ self.corner + ratio * (v - b @ self.corner) > vals + TINY
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
        keep = (self.vals - self.excess) + ratio * (value - base_b) > self.vals + TINY
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
                strictly = (tent < v - TINY).any(axis=1)
                tie = ((tent <= v + TINY) & (later[None, :] > rows[:, None])).any(axis=1)
                keep[rows] = ~(strictly | tie) & (self.vals[rows] < base[rows] - TINY)
            self._set(self.points[keep], self.vals[keep])
        self._pruned_size = self.vals.size


@dataclass
class UpperCached:
    """Upper-bound values at some beliefs, as of ``seen`` logged points and corner ``epoch``;
    ``base`` is the corner interpolation at them."""

    vals: np.ndarray
    base: np.ndarray
    seen: int
    epoch: int


@dataclass
class LowerCached:
    """Lower-bound values at some beliefs and, for each, the row of ``vectors`` that gives it,
    as of ``seen`` logged vectors."""

    vals: np.ndarray
    arg: np.ndarray
    seen: int
    vectors: np.ndarray
