"""The neutral (PO)MDP model every parser produces and every solver consumes.

Argument orders are fixed throughout the toolkit: T(s' | s, a) is ``T[a][s, s']``,
O(o | s', a) is ``O[a][s', o]``, and rewards are R(s, a, s') in ``R[a][s, s']``
(an observation-dependent reward is folded into its expectation over o).
Tables are scipy CSR matrices so large models (RockSample_7_8: 12,545 states) stay small;
``dense_*`` give numpy arrays for the small models where dense algebra is faster.

Mixed observability (a MOMDP, as SARSOP reads POMDPX): ``observed_key`` gives each state the
values of its fully observed variables as one integer; states with equal keys are told apart
only by the hidden variables. Those values are known at every step, the first included: after
a step they arrive in the observation (the POMDPX reader puts them there), and at the start the
true state's key is seen before the first action. So a run starts from
:meth:`Model.start_belief` of its true start state, and the optimal value at the start is
Σ_k P(k) V*(b_k) over :meth:`Model.start_split` (at least V*(initial belief): knowing k can
only help). Without a key (a plain POMDP) both are the initial belief itself.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import List, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import ModelError

#: How far a probability row may be from summing to one before a model is rejected.
#: Printed tables (the seed's, pomdp.org's) carry 3-6 significant digits.
PROBABILITY_TOLERANCE = 1e-4

#: The largest |value| a model may reach: every reward must satisfy |R| / (1 - discount) <=
#: MAX_VALUE. Values, bounds, sums of returns and the squares in a confidence interval's
#: variance then all stay far from float64's overflow at 1.8e308 (1e150 squared is 1e300).
MAX_VALUE = 1e150

#: Dense copies of T and O (``dense_T``, ``dense_O``) serve models of at most this many
#: states, and only while each copy has at most DENSE_ENTRY_LIMIT numbers (32 MB): above
#: either the solvers work on the CSR tables (see :attr:`Model.dense_tables_fit`).
DENSE_STATE_LIMIT = 300
DENSE_ENTRY_LIMIT = 4_000_000


@dataclass
class Model:
    """A discrete POMDP (an MDP when ``fully_observable``).

    For an MDP the observations are the states themselves (``O[a]`` is the identity), and each
    state is its own ``observed_key`` (set here when not given).
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
    observed_key: Optional[np.ndarray] = None  # (S,) int: the fully observed variables' values

    def __post_init__(self) -> None:
        if self.observed_key is None and self.fully_observable:
            # An MDP: the whole state is seen, so every state is a key of its own.
            self.observed_key = np.arange(len(self.states))

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

    @property
    def dense_tables_fit(self) -> bool:
        """Whether the dense fast paths may copy T and O into (A, S, S) and (A, S, Z) arrays:
        at most DENSE_STATE_LIMIT states and DENSE_ENTRY_LIMIT numbers per copy."""
        S, A, Z = self.n_states, self.n_actions, self.n_observations
        return S <= DENSE_STATE_LIMIT and A * S * max(S, Z) <= DENSE_ENTRY_LIMIT

    @cached_property
    def dense_T(self) -> np.ndarray:
        """T as a dense (A, S, S') array; only for small models."""
        self._refuse_dense("T", self.n_states)
        return np.stack([t.toarray() for t in self.T])

    @cached_property
    def dense_O(self) -> np.ndarray:
        """O as a dense (A, S', O) array; only for small models."""
        self._refuse_dense("O", self.n_observations)
        return np.stack([o.toarray() for o in self.O])

    def _refuse_dense(self, label: str, width: int) -> None:
        # A dense copy of a large model's table would take gigabytes: callers check
        # dense_tables_fit first; this guards any that does not.
        entries = self.n_actions * self.n_states * width
        if entries > 10 * DENSE_ENTRY_LIMIT:
            raise ModelError(f"a dense copy of {label} ({self.n_actions} x {self.n_states} x "
                             f"{width} numbers) is too large; use the sparse tables")

    # -- mixed observability -------------------------------------------------------------------
    def start_belief(self, state: int) -> np.ndarray:
        """The belief at the start of a run whose true start state is ``state``: the initial
        belief conditioned on the fully observed values of ``state`` (a copy of the initial
        belief when nothing is fully observed, or when the condition holds with probability one).
        """
        b = np.asarray(self.initial_belief, dtype=float)
        if self.observed_key is None:
            return b.copy()
        if not 0 <= state < self.n_states:
            raise ModelError(f"state {state} out of range 0..{self.n_states - 1}")
        same = self.observed_key == self.observed_key[state]
        if np.all(same | (b == 0)):
            # Conditioning on a certain event changes nothing; returning b itself keeps such
            # models (one start key, e.g. RockSample's rover position) bit for bit as before.
            return b.copy()
        conditioned = np.where(same, b, 0.0)
        mass = conditioned.sum()
        if mass <= 0:
            raise ModelError(f"state {self.states[state]!r} has probability zero in the "
                             f"initial belief")
        return conditioned / mass

    def start_split(self) -> List[Tuple[float, np.ndarray]]:
        """The initial belief split by what is seen at the start: (P(k), belief given k) for
        each fully observed value k of positive initial probability, in key order.

        The weights sum to one and the weighted beliefs add up to the initial belief b0
        (normalised), so Σ_k P(k) α·b_k = α·b0 for every vector α: a policy's value splits
        exactly; the optimum V* does not, which is the point. Without a key, or with one key
        only, this is ``[(1.0, b0)]``.
        """
        b = np.asarray(self.initial_belief, dtype=float)
        if self.observed_key is None:
            return [(1.0, b.copy())]
        keys = np.unique(self.observed_key[b > 0])
        if keys.size <= 1:
            return [(1.0, b.copy())]
        total = float(b.sum())
        split = []
        for k in keys:
            conditioned = np.where(self.observed_key == k, b, 0.0)
            mass = float(conditioned.sum())
            split.append((mass / total, conditioned / mass))
        return split

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
        if self.observed_key is not None:
            key = np.asarray(self.observed_key)
            if key.shape != (S,) or not np.issubdtype(key.dtype, np.integer):
                raise ModelError(f"observed_key must be {S} integers, one per state "
                                 f"(got {key.dtype} of shape {key.shape})")
        for table, width, label in ((self.T, S, "T"), (self.O, O, "O"), (self.R, S, "R")):
            if len(table) != A:
                raise ModelError(f"{label} has {len(table)} actions, expected {A}")
            for a, m in enumerate(table):
                rows = S
                if m.shape != (rows, width):
                    raise ModelError(f"{label}[{self.actions[a]}] has shape {m.shape}, "
                                     f"expected {(rows, width)}")
        if not np.all(np.isfinite(self.initial_belief)):
            raise ModelError("the initial belief has a non-finite number")
        for table, label in ((self.T, "T"), (self.O, "O"), (self.R, "R")):
            for a, m in enumerate(table):
                data = m.data if sp.issparse(m) else np.asarray(m)
                if data.size and not np.all(np.isfinite(data)):
                    raise ModelError(f"{label}[{self.actions[a]}] has a non-finite number")
        for a in range(A):
            _check_distribution(f"T[{self.actions[a]}]", self.T[a], tolerance, self.states)
            _check_distribution(f"O[{self.actions[a]}]", self.O[a], tolerance, self.states)
        problem = reward_bound_problem(max((_largest_magnitude(r) for r in self.R), default=0.0),
                                       self.discount)
        if problem:
            raise ModelError(problem)


def rows_not_summing_to_one(sums: np.ndarray,
                            tolerance: float = PROBABILITY_TOLERANCE) -> np.ndarray:
    """Indices of the rows of a probability table whose ``sums`` are not 1 within
    ``tolerance``."""
    return np.flatnonzero(np.abs(sums - 1.0) > tolerance)


def sum_problem(total: float, bad_rows: int, tolerance: float = PROBABILITY_TOLERANCE) -> str:
    """The end of a message about a row that sums to ``total``, one of ``bad_rows`` such."""
    return f"sums to {total:.6g}, not 1 (tolerance {tolerance:g}; {bad_rows} such row(s))"


def reward_bound_problem(largest_reward: float, discount: float) -> Optional[str]:
    """Why rewards as large as ``largest_reward`` (in magnitude) are refused at ``discount``,
    or None when |R| / (1 - discount) stays within MAX_VALUE."""
    largest_reward = abs(float(largest_reward))
    if largest_reward <= MAX_VALUE * (1.0 - discount):
        return None
    return (f"reward {largest_reward:.6g} is too large for discount {discount:g}: "
            f"|R| / (1 - discount) must be at most {MAX_VALUE:g}")


def _largest_magnitude(m) -> float:
    data = m.data if sp.issparse(m) else np.asarray(m)
    return float(np.abs(data).max()) if data.size else 0.0


def _check_distribution(label: str, rows, tolerance: float,
                        row_names: Optional[Sequence[str]] = None) -> None:
    """Every row non-negative and summing to one within ``tolerance``."""
    data = rows.data if sp.issparse(rows) else np.asarray(rows)
    if data.size and data.min() < 0:
        raise ModelError(f"{label} has a negative probability ({data.min():g})")
    sums = np.asarray(rows.sum(axis=1)).ravel()
    bad = rows_not_summing_to_one(sums, tolerance)
    if bad.size:
        i = int(bad[0])
        who = row_names[i] if row_names is not None else str(i)
        raise ModelError(f"{label} row {who} {sum_problem(sums[i], bad.size, tolerance)}")
