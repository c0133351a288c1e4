"""The model's arrays in the shapes HSVI's backups want (:mod:`ros_hrc.pomdp.hsvi`): dense T when
the model is small, sparse otherwise; O transposed and dense (A·Z·S numbers, the solver's size
limit); for a small model, the backup's tensor.
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from ros_hrc.errors import SolverError
from ros_hrc.pomdp.model import Model

#: Largest A·Z·S (dense observation array) this solver accepts.
MAX_DENSE_ENTRIES = 20_000_000

#: Most numbers (A·S·Z·S) of the backup tensor ``HsviTables.G`` (8 MB).
BACKUP_TENSOR = 1_000_000


def check_size(model: Model) -> None:
    """Refuse a model whose dense observation array (A·Z·S numbers) is too large for this
    solver (SolverError)."""
    A, S, Z = model.n_actions, model.n_states, model.n_observations
    if A * Z * S > MAX_DENSE_ENTRIES:
        raise SolverError(f"model too large for the point-based solver "
                          f"({A} actions x {Z} observations x {S} states); "
                          f"plan online with DESPOT instead")


class HsviTables:
    """The model's arrays in the shapes the backups want (dense T when small, sparse otherwise)."""

    def __init__(self, model: Model) -> None:
        self.A, self.S, self.Z = model.n_actions, model.n_states, model.n_observations
        check_size(model)
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
