"""What HSVI's trials (:mod:`ros_hrc.pomdp.hsvi_trials`) and sweeps
(:mod:`ros_hrc.pomdp.hsvi_sweeps`) work on: the model's tables, both bounds, the roots, the
beliefs met (the trials' tree and the sweeps' set), the memory budget and the counters. The
solver (:class:`ros_hrc.pomdp.hsvi.HsviSolver`) is this state and the loop that runs them.
"""
from __future__ import annotations

from typing import Optional, Tuple

import numpy as np

from ros_hrc.pomdp import mdp
from ros_hrc.pomdp.belief_set import BeliefSet
from ros_hrc.pomdp.belief_tree import BeliefTree, keeps_successors
from ros_hrc.pomdp.bounds import LowerBound, UpperBound
from ros_hrc.pomdp.hsvi_tables import HsviTables
from ros_hrc.pomdp.model import Model


class HsviState:
    """The search's state, built from the model.

    ``deadline`` (a ``time.perf_counter()`` instant) bounds the setup: the MDP bounds stop
    there, still valid. ``max_vectors``: how many vectors of S numbers (beliefs, points, alpha
    vectors, tree nodes) the memory budget leaves room for; None: no limit.
    """

    def __init__(self, model: Model, deadline: Optional[float] = None,
                 max_vectors: Optional[int] = None) -> None:
        self.max_vectors = max_vectors
        self.model = model
        self.t = HsviTables(model)
        # The roots: the initial belief split by the fully observed values seen at the start
        # (one root, the initial belief, when there are none).
        split = model.start_split()
        self.root_weights = np.array([w for w, _ in split])
        self.roots = np.array([b for _, b in split]).reshape(len(split), self.t.S)
        blind = mdp.blind_lower_bound(model, deadline=deadline)
        fib = mdp.fast_informed_bound(model, deadline=deadline)
        # Both bounds log what they add when there is a tree whose nodes cache them.
        self.keep_successors = keeps_successors(self.t)
        self.lower = LowerBound(blind.copy(), np.arange(model.n_actions),
                                log=self.keep_successors)
        self.upper = UpperBound(fib.max(axis=0), log=self.keep_successors)
        self.tree = BeliefTree(self.t, self.lower, self.upper, self.room)
        for root in self.roots:
            self.upper.add(root, float((fib @ root).max()))
        capacity = None if self.max_vectors is None else max(len(self.roots),
                                                             self.max_vectors // 2)
        self.beliefs = BeliefSet(self.t.S, capacity)
        for w, root in zip(self.root_weights, self.roots):
            self.beliefs.add(root, w)
        self.trials = 0
        self.sweeps = 0
        self.sweep_seconds = 0.0
        self.backups = 0
        self.memory_limit_reached = False

    # -- memory --------------------------------------------------------------------------------
    def vectors_in_use(self) -> int:
        """Stored vectors of S numbers, with the copies their updates make: a point is kept
        with its reciprocal and copied when points are added; alpha vectors are copied too."""
        return (len(self.beliefs) + 4 * self.upper.vals.size + 2 * self.lower.actions.size
                + 2 * self.upper.log_n + self.lower.log_n
                + len(self.tree) * self.tree.node_vectors)

    def room(self, vectors: int) -> bool:
        """Whether ``vectors`` more fit in the memory budget."""
        return self.max_vectors is None or self.vectors_in_use() + vectors <= self.max_vectors

    def step_cost(self) -> int:
        """Vectors one more step of a trial's path costs: the belief, its successors when they
        are kept, and what its backup adds (a belief, a point, an alpha vector, their copies)."""
        return 8 + (self.t.A * self.t.Z if self.keep_successors else 0)

    # -- bounds --------------------------------------------------------------------------------
    def bounds(self, b: Optional[np.ndarray] = None) -> Tuple[float, float]:
        """(lower, upper) at ``b``; by default at the start: Σ_k P(k)·bound(b_k) over the roots
        (the bounds at the initial belief when nothing is fully observed)."""
        if b is None:
            lo, up = self.root_bounds()
            return float(self.root_weights @ lo), float(self.root_weights @ up)
        x = np.asarray(b, dtype=float)
        return float(self.lower.values(x[None])[0]), float(self.upper.values(x[None])[0])

    def root_bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """The lower and upper bounds at each root."""
        return self.lower.values(self.roots), self.upper.values(self.roots)
