"""The neutral (PO)MDP model every parser produces and every solver consumes.

Argument orders are fixed throughout the toolkit: T(s' | s, a) is ``T[a][s, s']``,
O(o | s', a) is ``O[a][s', o]``, and rewards are R(s, a, s') in ``R[a][s, s']``
(an observation-dependent reward is folded into its expectation over o).
Tables are scipy CSR matrices so large models (RockSample_7_8: 12,545 states) stay small;
``dense_*`` give numpy arrays for the small models where dense algebra is faster.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import List, Optional, Sequence

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import ModelError

#: How far a probability row may be from summing to one before a model is rejected.
#: Printed tables (the seed's, pomdp.org's) carry 3-6 significant digits.
PROBABILITY_TOLERANCE = 1e-4


@dataclass
class Model:
    """A discrete POMDP (an MDP when ``fully_observable``).

    For an MDP the observations are the states themselves (``O[a]`` is the identity).
    """

    states: List[str]
    actions: List[str]
    observations: List[str]
    discount: float
    initial_belief: np.ndarray                 # shape (S,)
    T: List[sp.csr_matrix]                     # per action, (S, S')
    O: List[sp.csr_matrix]                     # per action, (S', O)
    R: List[sp.csr_matrix]                     # per action, (S, S') reward R(s, a, s')
    fully_observable: bool = False
    minimise: bool = False                     # Cassandra "values: cost"; R holds rewards (= -cost)
    name: str = ""
    source: Optional[str] = None               # the file it came from, for messages
    meta: dict = field(default_factory=dict)   # format-specific extras (e.g. POMDPX variables)

    # -- sizes -----------------------------------------------------------------
    @property
    def n_states(self) -> int:
        return len(self.states)

    @property
    def n_actions(self) -> int:
        return len(self.actions)

    @property
    def n_observations(self) -> int:
        return len(self.observations)

    # -- derived tables (computed once) ------------------------------------------
    @cached_property
    def R_sa(self) -> np.ndarray:
        """Expected immediate reward R(s, a) = sum_s' T(s'|s,a) R(s,a,s'), shape (A, S)."""
        return np.vstack([np.asarray(self.T[a].multiply(self.R[a]).sum(axis=1)).ravel()
                          for a in range(self.n_actions)])

    @cached_property
    def dense_T(self) -> np.ndarray:
        """T as a dense (A, S, S') array; only for small models."""
        return np.stack([t.toarray() for t in self.T])

    @cached_property
    def dense_O(self) -> np.ndarray:
        """O as a dense (A, S', O) array; only for small models."""
        return np.stack([o.toarray() for o in self.O])

    # -- lookups -----------------------------------------------------------------
    def index(self, kind: str, name: str) -> int:
        """Index of a state, action or observation by name; ModelError when unknown."""
        names: Sequence[str] = {"state": self.states, "action": self.actions,
                                "observation": self.observations}[kind]
        try:
            return list(names).index(name)
        except ValueError:
            raise ModelError(f"unknown {kind} {name!r}; known: {', '.join(names)}") from None

    def validate(self, tolerance: float = PROBABILITY_TOLERANCE) -> None:
        """Raise ModelError unless sizes agree, discount is in [0, 1) and rows are distributions."""
        S, A, O = self.n_states, self.n_actions, self.n_observations
        if not 0.0 <= self.discount < 1.0:
            raise ModelError(f"discount {self.discount} is outside [0, 1)")
        if self.initial_belief.shape != (S,):
            raise ModelError(f"initial belief has {self.initial_belief.size} entries, expected {S}")
        _check_distribution("initial belief", self.initial_belief[None, :], tolerance)
        for table, width, label in ((self.T, S, "T"), (self.O, O, "O"), (self.R, S, "R")):
            if len(table) != A:
                raise ModelError(f"{label} has {len(table)} actions, expected {A}")
            for a, m in enumerate(table):
                rows = S
                if m.shape != (rows, width):
                    raise ModelError(f"{label}[{self.actions[a]}] has shape {m.shape}, "
                                     f"expected {(rows, width)}")
        for a in range(A):
            _check_distribution(f"T[{self.actions[a]}]", self.T[a], tolerance, self.states)
            _check_distribution(f"O[{self.actions[a]}]", self.O[a], tolerance, self.states)


def _check_distribution(label: str, rows, tolerance: float,
                        row_names: Optional[Sequence[str]] = None) -> None:
    """Every row non-negative and summing to one within ``tolerance``."""
    data = rows.data if sp.issparse(rows) else np.asarray(rows)
    if data.size and data.min() < 0:
        raise ModelError(f"{label} has a negative probability ({data.min():g})")
    sums = np.asarray(rows.sum(axis=1)).ravel()
    bad = np.flatnonzero(np.abs(sums - 1.0) > tolerance)
    if bad.size:
        i = int(bad[0])
        who = row_names[i] if row_names is not None else str(i)
        raise ModelError(f"{label} row {who} sums to {sums[i]:.6g}, not 1 "
                         f"(tolerance {tolerance:g}; {bad.size} such row(s))")
