"""HSVI on the mixed-observability factorisation (SARSOP's MOMDP representation).

A model with fully observed state variables (POMDPX ``fullyObs``, ``Model.observed_key``) is
known, at every step, to be in one block of states: those sharing the observed values, which
the last observation told. A belief is then a block and a distribution over the block's states
only, and a bound is a set of vectors per block. For RockSample_7_8 (12,800 states in 50 blocks
of 256) a belief is 256 numbers instead of 12,800, an alpha vector too, and the sawtooth
compares a belief with the points of its own block only: SARSOP's MOMDP solver works the same
way (Ong, Png, Hsu, Lee: "POMDPs for robotic tasks with mixed observability", RSS 2009).

The search is the one of :mod:`ros_hrc.pomdp.hsvi` (HSVI2 trials with the dynamic target of
:mod:`ros_hrc.pomdp.search`, the exact stopping rule on the gap at the start, Σ_k P(k)·bound(b_k)
over the roots), with the bounds of :class:`~ros_hrc.pomdp.bounds.LowerBound` and
:class:`~ros_hrc.pomdp.bounds.UpperBound` kept per block. Products are sparse where the model
is: a block's transitions are a sparse (block x next block) matrix, an observation's likelihood
a dense column over its next block.

The factorisation needs each observation to tell the next block: every (action, observation)
pair has its possible next states in one block. A POMDPX model's observation carries the fully
observed variables, so it does; :func:`applies` checks it.

:func:`solve` returns a :class:`~ros_hrc.pomdp.policy.Policy` over the whole state space: each
block's vectors, with R_min / (1 − γ) − 1 outside the block, below what any policy can earn.
So every vector is a valid lower bound everywhere, and at a belief inside one block (every
belief a run meets: it starts from the start state's block, ``Model.start_belief``) a vector of
another block never beats the block's own (each is the value of a plan, at least R_min / (1 − γ)
at every state).

Memory: the model, the block tables (about T and O again), the MDP bounds and the stored
vectors, each of its block's size; with ``memory_limit`` the final policy (alpha vectors x S
numbers) is counted too, since it is the largest array the solver makes.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable, List, Optional, Tuple

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import SolverError
from ros_hrc.pomdp import mdp, memory
from ros_hrc.pomdp.bounds import TINY, LowerBound, UpperBound
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.policy import Policy
from ros_hrc.pomdp.search import SolveProgress, trial_start

#: Fewest blocks for which the factorisation is worth it.
MIN_BLOCKS = 2


def _blocks(model: Model) -> Tuple[np.ndarray, List[np.ndarray], np.ndarray]:
    """(block of each state, states of each block, index of each state inside its block)."""
    keys, block = np.unique(np.asarray(model.observed_key), return_inverse=True)
    order = np.argsort(block, kind="stable")
    bounds = np.searchsorted(block[order], np.arange(keys.size + 1))
    states = [order[bounds[k]:bounds[k + 1]] for k in range(keys.size)]
    local = np.empty(model.n_states, dtype=np.int64)
    for members in states:
        local[members] = np.arange(members.size)
    return block, states, local


def applies(model: Model) -> bool:
    """Whether the model has fully observed values in at least MIN_BLOCKS blocks and each
    (action, observation) pair tells the next block."""
    if model.fully_observable or model.observed_key is None:
        return False
    block = np.unique(np.asarray(model.observed_key), return_inverse=True)[1]
    if block.max() + 1 < MIN_BLOCKS:
        return False
    for o in model.O:
        coo = o.tocoo()
        keep = coo.data != 0
        rows, cols = coo.row[keep], coo.col[keep]
        lo = np.full(model.n_observations, np.iinfo(np.int64).max)
        hi = np.full(model.n_observations, -1)
        np.minimum.at(lo, cols, block[rows])
        np.maximum.at(hi, cols, block[rows])
        if np.any((lo != hi) & (hi >= 0)):
            return False
    return True


@dataclass
class _Branch:
    """Where an action leads from a block: one next block, the observations that can follow
    and their likelihood columns over the next block's states (rows), and the block's
    transition matrix into it (block states x next block states)."""

    next_block: int
    observations: np.ndarray          # (n_z,)
    likelihood: np.ndarray            # (n_z, next block size)
    T: sp.csr_matrix                  # (block size, next block size)
    Tt: sp.csr_matrix                 # its transpose


class _Tables:
    """The model cut into blocks: for each (action, block) its branches and its rewards."""

    def __init__(self, model: Model) -> None:
        self.A, self.S = model.n_actions, model.n_states
        self.gamma = float(model.discount)
        self.block, self.states, self.local = _blocks(model)
        self.n_blocks = len(self.states)
        R = np.asarray(model.R_sa, dtype=float)
        self.R = [[R[a, self.states[k]] for k in range(self.n_blocks)] for a in range(self.A)]
        self.branches: List[List[List[_Branch]]] = []
        for a in range(self.A):
            O = model.O[a].tocsc()
            O.eliminate_zeros()
            # The next block of each observation (-1: never observed after a).
            z_block = np.full(model.n_observations, -1, dtype=np.int64)
            filled = np.diff(O.indptr) > 0
            z_block[filled] = self.block[O.indices[O.indptr[:-1][filled]]]
            by_block = {}
            for nb in np.unique(z_block[z_block >= 0]):
                zs = np.flatnonzero(z_block == nb)
                members = self.states[nb]
                by_block[int(nb)] = (zs, O[members][:, zs].toarray().T.copy())
            T = model.T[a].tocsr()
            per_block = []
            for k, members in enumerate(self.states):
                rows = T[members]
                rows.eliminate_zeros()
                nexts = np.unique(self.block[rows.indices]) if rows.nnz else np.empty(0, int)
                branches = []
                for nb in nexts:
                    nb = int(nb)
                    if nb not in by_block:
                        raise SolverError(f"action {model.actions[a]} leads to states that no "
                                          "observation follows")
                    cols = self.states[nb]
                    Tk = rows[:, cols].tocsr()
                    zs, like = by_block[nb]
                    branches.append(_Branch(nb, zs, like, Tk, Tk.T.tocsr()))
                per_block.append(branches)
            self.branches.append(per_block)


@dataclass
class _Successors:
    """One action's successors from a belief: per branch, the observations' probabilities and
    the next beliefs (rows, over the next block)."""

    branches: List[_Branch]
    probs: List[np.ndarray]
    beliefs: List[np.ndarray]


def _memory_needed(model: Model) -> int:
    """Bytes besides the stored vectors: the model, its blocks' tables (about T and O again)
    and the MDP bounds."""
    nnz = sum(t.nnz for t in model.T) + sum(o.nnz for o in model.O)
    return memory.model_bytes(model) + 8 * 4 * nnz + 8 * 12 * model.n_actions * model.n_states


class MomdpSolver:
    """The solver's state; ``run`` may be called again to continue (anytime)."""

    def __init__(self, model: Model, deadline: Optional[float] = None,
                 memory_limit: Optional[int] = None) -> None:
        began = time.perf_counter()
        if not applies(model):
            raise SolverError("the model has no fully observed blocks that its observations tell")
        self.max_numbers: Optional[int] = None
        if memory_limit is not None:
            fixed = _memory_needed(model)
            memory.require(fixed, memory_limit, model.source or model.name or "the model",
                           f"solving ({model.n_states} states in blocks)")
            self.max_numbers = int((memory_limit - fixed) // 8)
        self.model = model
        self.t = _Tables(model)
        t = self.t
        # What one more step of a trial may store until its backup: its successors, then a
        # belief, an alpha vector (in its block and in the final policy) and a point.
        self.step_numbers = t.S + 7 * max(m.size for m in t.states) + max(
            sum(br.likelihood.size for a in range(t.A) for br in t.branches[a][k])
            for k in range(t.n_blocks))
        blind = mdp.blind_lower_bound(model, deadline=deadline)
        upper = mdp.fast_informed_bound(model, deadline=deadline)
        # Outside its block a vector is worth less than any policy earns (R_min / (1 - γ)),
        # so it stays a valid bound there and is never the best, not even tied, at a belief of
        # another block: a tie could hand that belief this block's action.
        self.floor = float(np.min(model.R_sa)) / (1.0 - t.gamma) - 1.0
        self.lower = [LowerBound(blind[:, members].copy(), np.arange(t.A))
                      for members in t.states]
        self.upper = [UpperBound(upper[:, members].max(axis=0)) for members in t.states]
        # The roots: the initial belief split by the observed values (one block each).
        self.roots: List[Tuple[int, np.ndarray]] = []
        weights = []
        for w, b in model.start_split():
            k = int(t.block[int(np.flatnonzero(b)[0])])
            x = b[t.states[k]].copy()
            self.roots.append((k, x))
            weights.append(w)
            self.upper[k].add(x, float((upper[:, t.states[k]] @ x).max()))
        self.root_weights = np.array(weights)
        # The beliefs backed up in each block: a block's vectors are pruned to those best at
        # one of them (or at a corner) when they have doubled since the last pruning.
        self.seen: List[List[np.ndarray]] = [[] for _ in t.states]
        for k, x in self.roots:
            self.seen[k].append(x)
        self._pruned_size = [lb.actions.size for lb in self.lower]
        self.trials = 0
        self.backups = 0
        self.memory_limit_reached = False
        self.seconds = time.perf_counter() - began

    # -- bounds --------------------------------------------------------------------------------
    def _root_bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        lo = np.array([self.lower[k].values(x[None])[0] for k, x in self.roots])
        up = np.array([self.upper[k].values(x[None])[0] for k, x in self.roots])
        return lo, up

    def bounds(self) -> Tuple[float, float]:
        """(lower, upper) at the start: Σ_k P(k)·bound(b_k) over the roots."""
        lo, up = self._root_bounds()
        return float(self.root_weights @ lo), float(self.root_weights @ up)

    def _numbers_in_use(self) -> int:
        """Numbers stored: the blocks' vectors and points (with their copies and reciprocals),
        the beliefs backed up and the final policy (alpha vectors x S), made at the end."""
        alphas = sum(lb.actions.size for lb in self.lower)
        seen = sum(len(x) * members.size for x, members in zip(self.seen, self.t.states))
        return alphas * self.t.S + seen + sum(lb.alphas.size + 4 * ub.points.size
                                              for lb, ub in zip(self.lower, self.upper))

    # -- successors ----------------------------------------------------------------------------
    def _successors(self, k: int, x: np.ndarray) -> List[_Successors]:
        """Per action: every branch's observation probabilities and next beliefs."""
        out = []
        for a in range(self.t.A):
            probs, beliefs = [], []
            branches = self.t.branches[a][k]
            for br in branches:
                pred = br.Tt @ x                                         # (next block,)
                joint = br.likelihood * pred[None, :]                    # (n_z, next block)
                p = joint.sum(axis=1)
                probs.append(p)
                beliefs.append(joint / np.where(p > 0, p, 1.0)[:, None])
            out.append(_Successors(branches, probs, beliefs))
        return out

    def _q_upper(self, k: int, x: np.ndarray, succ: List[_Successors]):
        """Upper-bound Q values (A,) and each action's successors' upper bounds."""
        q = np.empty(self.t.A)
        ups = []
        for a, s in enumerate(succ):
            values = [self.upper[br.next_block].values(X) for br, X in zip(s.branches, s.beliefs)]
            ups.append(values)
            q[a] = float(self.t.R[a][k] @ x) + self.t.gamma * sum(
                float(p @ v) for p, v in zip(s.probs, values))
        return q, ups

    # -- one trial -----------------------------------------------------------------------------
    def _trial(self, precision: float, deadline: float) -> None:
        gamma = self.t.gamma
        r, width = trial_start(self.root_weights, *self._root_bounds(), precision)
        k, x = self.roots[r]
        path: List[Tuple[int, np.ndarray, List[_Successors]]] = []
        while True:
            lo_b = float(self.lower[k].values(x[None])[0])
            up_b = float(self.upper[k].values(x[None])[0])
            if up_b - lo_b <= width or gamma == 0.0:
                break
            succ = self._successors(k, x)
            path.append((k, x, succ))
            q_up, ups = self._q_upper(k, x, succ)
            a = int(np.argmax(q_up))
            width /= gamma
            best, choice = -math.inf, None
            for i, (br, p, X, u) in enumerate(zip(succ[a].branches, succ[a].probs,
                                                  succ[a].beliefs, ups[a])):
                score = p * (u - self.lower[br.next_block].values(X) - width)
                j = int(np.argmax(score))
                if score[j] > best:
                    best, choice = float(score[j]), (br.next_block, X[j], float(p[j]))
            if choice is None or choice[2] <= 0.0 or time.perf_counter() > deadline:
                break
            if self.max_numbers is not None and self._numbers_in_use() \
                    + (len(path) + 1) * self.step_numbers > self.max_numbers:
                self.memory_limit_reached = True
                break
            k, x = choice[0], choice[1]
        for k, x, succ in reversed(path):
            self._backup(k, x, succ)
            if time.perf_counter() > deadline:
                break
        self.trials += 1

    def _backup(self, k: int, x: np.ndarray, succ: List[_Successors]) -> None:
        t = self.t
        cand = np.empty((t.A, x.size))
        for a, s in enumerate(succ):
            back = t.R[a][k].copy()
            for br, X in zip(s.branches, s.beliefs):
                lower = self.lower[br.next_block]
                chosen = lower.alphas[lower.best(X)]                     # (n_z, next block)
                w = (br.likelihood * chosen).sum(axis=0)                 # Σ_z O(z|s') α_z(s')
                back += t.gamma * (br.T @ w)
            cand[a] = back
        vals = cand @ x
        a = int(np.argmax(vals))
        self.seen[k].append(x)
        if vals[a] > float(self.lower[k].values(x[None])[0]) + TINY:
            self.lower[k].add(cand[a], a)
            if self.lower[k].actions.size > 2 * self._pruned_size[k] + 16:
                self._prune(k)
        q_up, _ = self._q_upper(k, x, succ)
        new_up = float(q_up.max())
        if new_up < float(self.upper[k].values(x[None])[0]) - TINY:
            self.upper[k].add(x, new_up)
        self.backups += 1

    def _prune(self, k: int) -> None:
        """Keep the block's vectors best at a belief it has backed up or at a corner (SARSOP's
        pruning at the sampled beliefs: the others are valid too, but cost time and memory)."""
        self.lower[k].prune(np.array(self.seen[k]), corners=True)
        self._pruned_size[k] = self.lower[k].actions.size

    # -- the loop ------------------------------------------------------------------------------
    def run(self, timeout: Optional[float] = 60.0, precision: float = 1e-3,
            progress: Optional[Callable[[SolveProgress], None]] = None) -> Tuple[float, float]:
        """Trials until the gap at the start is <= ``precision``, the time is up or the stored
        vectors would outgrow the memory limit; ``progress`` after each trial."""
        if precision <= 0:
            raise SolverError(f"precision must be positive, got {precision}")
        start = time.perf_counter()
        deadline = start + timeout if timeout is not None else float("inf")
        lo, up = self.bounds()
        while up - lo > precision and time.perf_counter() < deadline \
                and not self.memory_limit_reached:
            self._trial(precision, deadline)
            lo, up = self.bounds()
            if progress is not None:
                progress(SolveProgress(
                    self.seconds + time.perf_counter() - start, self.trials, lo, up,
                    sum(lb.actions.size for lb in self.lower),
                    sum(ub.vals.size for ub in self.upper)))
        self.seconds += time.perf_counter() - start
        return lo, up

    def policy(self) -> Policy:
        """Each block's vectors over the whole state space (``floor`` elsewhere), after pruning
        them."""
        t = self.t
        for k in range(t.n_blocks):
            self._prune(k)
        # One array, filled block by block: no copies of it (it is the largest thing here).
        n = sum(lb.actions.size for lb in self.lower)
        alphas = np.empty((n, t.S))
        alphas[:] = self.floor
        row = 0
        for k, lb in enumerate(self.lower):
            rows = slice(row, row + lb.actions.size)
            alphas[rows, t.states[k]] = lb.alphas
            row += lb.actions.size
        actions = np.concatenate([lb.actions for lb in self.lower])
        lo, up = self.bounds()
        m = self.model
        return Policy(alphas=alphas, actions=actions,
                      state_names=list(m.states), action_names=list(m.actions),
                      discount=m.discount, lower=lo, upper=up, kind="alpha", model_name=m.name,
                      stats={"solver": "hsvi2-momdp", "seconds": self.seconds,
                             "trials": self.trials, "backups": self.backups,
                             "blocks": t.n_blocks,
                             "alphas": int(sum(lb.actions.size for lb in self.lower)),
                             "upper_points": int(sum(ub.vals.size for ub in self.upper)),
                             "memory_limit_reached": self.memory_limit_reached})


def solve(model: Model, timeout: Optional[float] = 60.0, precision: float = 1e-3,
          memory_limit: Optional[int] = None,
          progress: Optional[Callable[[SolveProgress], None]] = None) -> Policy:
    """Solve ``model`` by blocks (see the module docstring); the timeout counts from the call."""
    start = time.perf_counter()
    deadline = start + timeout if timeout is not None else None
    solver = MomdpSolver(model, deadline=deadline, memory_limit=memory_limit)
    remaining = None if deadline is None else max(0.0, deadline - time.perf_counter())
    solver.run(timeout=remaining, precision=precision, progress=progress)
    return solver.policy()
