"""HSVI's backups outside its trials (:mod:`ros_hrc.pomdp.hsvi`): sweeps and corner rounds.

Sweeps, our addition to HSVI2: synchronous backups of both bounds at once at the heaviest
beliefs the trials have met and at their one-step successors. The solver runs them only when
the trials stall (their rate of narrowing the gap, :func:`log_rate`, over the last few, falls to
the last sweep's; zero before any sweep) and goes on while they narrow it faster than the
trials did (:func:`sweeps`).

Before the first trial, a small model's corners (the point masses) are backed up in a few
rounds (PBVI at the corners, ``VERTEX_ROUNDS``, :func:`corner_rounds`): the blind policies'
vectors are far below V* there, and the trials then need fewer backups.
"""
from __future__ import annotations

import math
import time
from typing import Tuple

import numpy as np

from ros_hrc.pomdp.bounds import TINY
from ros_hrc.pomdp.hsvi_state import HsviState
from ros_hrc.pomdp.hsvi_trials import backup

#: Work per sweep, in sawtooth terms (beliefs x actions x observations x points x states).
SWEEP_BUDGET = 3e6

#: Numbers in one chunk of a sweep's (beliefs x actions x observations x states) arrays: 32 MB.
SWEEP_CHUNK = 4_000_000

#: Rounds of backups at the corners (the point masses) before the first trial, at most; they
#: stop once a round moves no corner's bound by more than VERTEX_ROUND_STOP x the gap at the
#: start. Only for models of at most VERTEX_STATES states (a round is S backups).
VERTEX_ROUNDS = 10
VERTEX_ROUND_STOP = 0.1
VERTEX_STATES = 100


def log_rate(gap_before: float, gap_after: float, seconds: float) -> float:
    """How fast the gap narrowed: ln(before / after) per second. The gap shrinks about
    geometrically, so this rate stays comparable as the gap closes (a difference would not)."""
    if gap_after >= gap_before or gap_before <= 0.0:
        return 0.0
    return math.log(gap_before / max(gap_after, 1e-300)) / max(seconds, 1e-9)


def sweep_size(successor_numbers: int) -> int:
    """Most beliefs one sweep backs up, for a model of A·Z·S = ``successor_numbers``: a sweep
    costs about N·A·Z·(points)·S, and points grow with N, so the budget caps N²."""
    return max(32, int(math.sqrt(SWEEP_BUDGET / successor_numbers)))


def sweep_growth(state: HsviState) -> int:
    """Vectors one sweep may add before it prunes: a point and an alpha vector per belief
    it backs up, and their copies, plus its rows."""
    t = state.t
    return 8 * min(sweep_size(t.A * t.Z * t.S), len(state.beliefs))


def _sweep_set(state: HsviState) -> Tuple[np.ndarray, np.ndarray]:
    """Indices and rows of the beliefs one sweep backs up: the heaviest within a work budget."""
    t = state.t
    idx = state.beliefs.top(sweep_size(t.A * t.Z * t.S))
    return idx, state.beliefs.rows(idx)


def sweep(state: HsviState, deadline: float = math.inf) -> None:
    """Back both bounds up at every belief of the sweep set at once (PBVI-style).

    In numpy a batch costs about as much as a single backup, and on problems whose trials
    cycle through the same beliefs (Tiger) sweeps propagate improvements far faster than
    trials alone. Both updates keep the bounds valid: any backup of valid vectors is a valid
    vector, and the Bellman backup of an upper bound is an upper bound. At ``deadline`` the
    sweep ends after its current chunk and keeps the backups done so far.
    """
    t = state.t
    idx, X = _sweep_set(state)
    fresh = state.beliefs.take_unexpanded(idx)
    weights = state.beliefs.weights(idx)
    N, S = X.shape
    A, Z = t.A, t.Z
    n_pts = max(1, state.upper.vals.size)
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
            state.beliefs.add(succ[new][reach > 0], reach[reach > 0])
        ub = state.upper.values(flat).reshape(n, A, Z)
        q_up = x @ t.R.T + t.gamma * (p * ub).sum(axis=2)
        new_up[lo:lo + n] = q_up.max(axis=1)
        best = state.lower.best(flat).reshape(n, A, Z)
        w = np.einsum("azs,nazs->nas", t.OT, state.lower.alphas[best])
        if t.dense:
            back = np.einsum("ast,nat->nas", t.T, w)
        else:
            back = np.stack([t.back(wi) for wi in w])
        cand = t.R[None] + t.gamma * back                             # (n, A, S)
        a = np.einsum("nas,ns->na", cand, x).argmax(axis=1)
        new_alpha[lo:lo + n] = cand[np.arange(n), a]
        new_act[lo:lo + n] = a
        old_lo[lo:lo + n] = state.lower.values(x)
        old_up[lo:lo + n] = state.upper.values(x)
        done = lo + n
    if done < N:
        X, new_up, new_alpha, new_act = X[:done], new_up[:done], new_alpha[:done], \
            new_act[:done]
        old_lo, old_up = old_lo[:done], old_up[:done]
    # Lower: keep the candidates that improve at their own belief.
    gain = np.einsum("ns,ns->n", new_alpha, X) - old_lo
    better = gain > TINY
    if better.any():
        state.lower.extend(new_alpha[better], new_act[better])
        state.lower.prune(X, corners=True)
    # Upper: record the backed-up values that improve on the current bound. Pruning the
    # points costs O(points² · S), seconds on a large model: not once the time is up.
    in_time = time.perf_counter() <= deadline
    lower_up = new_up < old_up - TINY
    if lower_up.any():
        state.upper.add(X[lower_up], new_up[lower_up], prune=in_time)
        if in_time:
            state.upper.prune()
    state.backups += done
    state.sweeps += 1


def sweeps(state: HsviState, precision: float, deadline: float, rate_to_beat: float,
           max_sweeps: int = 10_000) -> float:
    """Sweep while it pays: while a sweep narrows the gap at the start faster per second
    (:func:`log_rate`) than the trials have lately (``rate_to_beat``); at most
    ``max_sweeps``. Returns the last sweep's rate."""
    lo, up = state.bounds()
    rate = 0.0
    for _ in range(max_sweeps):
        if up - lo <= precision or time.perf_counter() > deadline:
            break
        if not state.room(sweep_growth(state)):
            break
        began = time.perf_counter()
        sweep(state, deadline)
        new_lo, new_up = state.bounds()
        spent = time.perf_counter() - began
        rate = log_rate(up - lo, new_up - new_lo, spent)
        state.sweep_seconds += spent
        lo, up = new_lo, new_up
        if rate <= rate_to_beat:
            break
    return rate


def corner_rounds(state: HsviState, precision: float, deadline: float) -> None:
    """PBVI-style rounds of backups at every corner (point mass) before the first trial,
    while a round moves some corner's bounds by more than VERTEX_ROUND_STOP x the gap at
    the start (at most VERTEX_ROUNDS). The blind policies' vectors are far below V* at the
    corners (2.9 below on robot_completed.pomdp, 25 on robot.pomdp); a few rounds there
    raise the lower bound everywhere for the cost of a few trials, and the trials need
    fewer backups (robot_completed.pomdp 290 -> 219 with the rounds' 35)."""
    S = state.t.S
    lo, up = state.bounds()
    if not state.keep_successors or S > VERTEX_STATES or up - lo <= precision:
        return
    stop = VERTEX_ROUND_STOP * (up - lo)
    corners = np.eye(S)
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(VERTEX_ROUNDS):
            lower_before = state.lower.values(corners)
            upper_before = state.upper.corner.copy()
            for e in corners:
                if time.perf_counter() > deadline or not state.room(state.step_cost()):
                    return
                backup(state, state.tree.node(e))
            moved = max(float((state.lower.values(corners) - lower_before).max()),
                        float((upper_before - state.upper.corner).max()))
            if moved <= stop:
                break
