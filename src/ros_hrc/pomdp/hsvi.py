"""HSVI2, heuristic search value iteration (Smith and Simmons 2004, 2005): an anytime offline
solver. :func:`ros_hrc.pomdp.offline.solve` chooses it for a POMDP.

Two bounds on the optimal value function V* are kept and tightened along sampled belief paths
(:mod:`ros_hrc.pomdp.bounds`): a lower bound of alpha vectors, started from the blind
policies, and an upper bound of corner values and belief points read with the sawtooth
interpolation, started from the fast informed bound.

A trial (:mod:`ros_hrc.pomdp.hsvi_trials`) starts at the initial belief (a root: see mixed
observability below) and descends, taking the action with the best upper bound and the
observation with the largest weighted excess gap, until the gap at depth t is below
``target / γ^t``; it then backs both bounds up along the path, deepest first. The target is a
fraction ``TRIAL_ZETA`` of the gap at the root, never below ``precision`` (HSVI2's and SARSOP's
dynamic target, :mod:`ros_hrc.pomdp.search`): trials stay shallow while the bounds are loose
and go deeper as they close. The solver stops when the gap at the start is below ``precision``
(the exact rule) or the time is up, and returns the lower-bound vectors as a ``Policy``. Both
bounds are valid at every moment (anytime).

The beliefs the trials visit form SARSOP's tree of reachable beliefs, whose nodes cache their
successors and both bounds there between visits (:mod:`ros_hrc.pomdp.belief_tree`). Between
trials, when they stall, the solver sweeps: synchronous backups at the heaviest beliefs met
(:mod:`ros_hrc.pomdp.belief_set`); before the first trial it backs a small model's corners up
in a few rounds (:mod:`ros_hrc.pomdp.hsvi_sweeps`). Trials and sweeps work on the solver's
state (:class:`~ros_hrc.pomdp.hsvi_state.HsviState`); this module is the loop that shares the
time between them and the policy it returns.

Mixed observability (POMDPX ``fullyObs`` variables, ``Model.observed_key``): the fully observed
values are seen before the first action, so the value to bound is Σ_k P(k) V*(b_k) over the
initial belief split by them (``Model.start_split``), as in SARSOP. Each b_k is a root: all are
in the belief set and the upper bound's points, a trial starts at the root with the largest
weighted excess gap P(k)·(gap(b_k) − precision), and the bounds reported at the start (and the
policy's) are the weighted sums. Without a key there is one root, the initial belief. (When
every observation tells the fully observed values after it, :mod:`ros_hrc.pomdp.momdp` solves
the model by blocks of states instead.)

Time and memory: the setup (the tables and the MDP bounds: blind policies, QMDP or the fast
informed bound) stops at ``deadline`` with bounds that are still valid (each iterate of those
bounds is one), and so does every stage of ``run``. Memory is O(non-zeros of T + A·Z·S) plus
the stored vectors (alpha vectors, upper-bound points and their log, beliefs, the current
trial's path: S numbers each; a tree node's A·Z successors, within ``TREE_NUMBERS``), never an
S x S array for a large model. With ``memory_limit`` the solver refuses, before building
anything, a model whose tables and working arrays would not fit
(:class:`~ros_hrc.pomdp.memory.MemoryLimitError`), and stops, as at a timeout, when its stored
vectors would outgrow the rest of the budget (after pruning once);
``stats["memory_limit_reached"]`` then says so.
"""
from __future__ import annotations

import time
from collections import deque
from typing import Callable, Deque, Optional, Tuple

import numpy as np

from ros_hrc.errors import SolverError
from ros_hrc.pomdp import mdp, memory
from ros_hrc.pomdp.belief_tree import Node
from ros_hrc.pomdp.bounds import RATIO_BLOCK
from ros_hrc.pomdp.hsvi_state import HsviState
from ros_hrc.pomdp.hsvi_sweeps import (SWEEP_CHUNK, corner_rounds, log_rate, sweep_growth,
                                       sweep_size, sweeps)
from ros_hrc.pomdp.hsvi_tables import check_size
from ros_hrc.pomdp.hsvi_trials import trial
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.policy import Policy
from ros_hrc.pomdp.search import SolveProgress

#: Fewest stored vectors (beliefs, points, alpha vectors) the memory budget must leave room for.
MIN_VECTORS = 64


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
    sweep = 8 * 6 * max(azs, min(SWEEP_CHUNK, sweep_size(azs) * azs))
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


class HsviSolver(HsviState):
    """The solver's state and its loop; ``run`` may be called again to continue (anytime).

    ``deadline`` (a ``time.perf_counter()`` instant) bounds the setup: the MDP bounds stop
    there, still valid. ``memory_limit`` (bytes) is the budget of :data:`memory_needed` plus
    the stored vectors; None: no limit.
    """

    def __init__(self, model: Model, deadline: Optional[float] = None,
                 memory_limit: Optional[int] = None) -> None:
        if model.fully_observable:
            raise SolverError("HSVI is for POMDPs; solve an MDP with value iteration")
        began = time.perf_counter()
        check_size(model)
        S = model.n_states
        # Vectors of S numbers the budget leaves for beliefs, points and alpha vectors.
        max_vectors: Optional[int] = None
        if memory_limit is not None:
            fixed = memory_needed(model)
            memory.require(fixed + MIN_VECTORS * 8 * S, memory_limit,
                           model.source or model.name or "the model",
                           f"solving ({S} states, {model.n_actions} actions, "
                           f"{model.n_observations} observations)")
            max_vectors = int((memory_limit - fixed) // (8 * S))
        super().__init__(model, deadline=deadline, max_vectors=max_vectors)
        self.corner_rounds_done = False
        self.seconds = time.perf_counter() - began

    def _trial(self, precision: float, deadline: float) -> None:
        """One trial (:func:`ros_hrc.pomdp.hsvi_trials.trial`)."""
        trial(self, precision, deadline)

    # The tree's refresh and a node's Q values, as the tests of the node caches reach them.
    def _refresh(self, node: Node) -> None:
        self.tree.refresh(node)

    def _q_upper(self, node: Node) -> np.ndarray:
        return node.q_upper()

    def _prune(self) -> None:
        self.upper.prune()
        # Beliefs in blocks, so their rows are never all copied at once.
        rows = max(1, RATIO_BLOCK // self.t.S)
        self.lower.prune(self.roots, *self.beliefs.blocks(rows), corners=True)

    def _out_of_memory(self) -> bool:
        """Whether the stored vectors leave no room for another trial step and a sweep, even
        after pruning; True also records that the budget stopped the solver."""
        needed = sweep_growth(self) + 2 * self.step_cost()
        if self.room(needed):
            return False
        self._prune()
        if self.room(needed):
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
            corner_rounds(self, precision, deadline)
        lo, up = self.bounds()
        trials = 0
        # Trials and sweeps share the time by how fast each narrows the gap at the start
        # (log_rate): the trials' rate over their last few (one trial's gain is lumpy), a
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
                    sweep_rate = sweeps(self, precision, deadline, trial_rate)
                    recent.clear()             # the trials' rate after the sweeps is new
                    lo, up = self.bounds()
            if up - lo <= precision or time.perf_counter() > deadline:
                break
            began, gap = time.perf_counter(), up - lo
            self._trial(precision, deadline)
            trials += 1
            lo, up = self.bounds()
            spent = time.perf_counter() - began
            recent.append((log_rate(gap, up - lo, spent) * spent, spent))
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
