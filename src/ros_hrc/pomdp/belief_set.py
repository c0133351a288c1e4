"""The distinct beliefs HSVI's trials and sweeps have met (:mod:`ros_hrc.pomdp.hsvi`), each with a
reach weight: the beliefs a sweep backs up (:mod:`ros_hrc.pomdp.hsvi_sweeps`) and at which the
lower bound's vectors are pruned.
"""
from __future__ import annotations

import hashlib
from typing import Iterator, List, Optional

import numpy as np


def belief_key(b: np.ndarray) -> bytes:
    """A digest of the rounded belief, not its bytes: the key of a 50,000-state belief would
    otherwise take as much memory as the belief."""
    return hashlib.blake2b(np.round(b, 10).tobytes(), digest_size=16).digest()


class BeliefSet:
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
        """``add`` for one belief; ``key``: its ``belief_key`` if known."""
        if key is None:
            key = belief_key(b)
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
