"""HSVI2's trials (:mod:`ros_hrc.pomdp.hsvi`) and the point-based backup they end with.

A trial starts at a root (:func:`ros_hrc.pomdp.search.trial_start`) and descends the belief
tree (:mod:`ros_hrc.pomdp.belief_tree`), taking the action with the best upper bound and the
observation with the largest weighted excess gap, until the gap at depth t is below
``target / γ^t``; it then backs both bounds up along the path, deepest first, and adds the
beliefs it backed up to the sweeps' set with their reach weights.
"""
from __future__ import annotations

import time
from typing import List, Optional, Tuple

import numpy as np

from ros_hrc.pomdp.belief_tree import Node
from ros_hrc.pomdp.bounds import TINY
from ros_hrc.pomdp.hsvi_state import HsviState
from ros_hrc.pomdp.search import trial_start


def trial(state: HsviState, precision: float, deadline: float) -> None:
    """One trial: descend from a root, then back up along the path (until ``deadline``, a
    ``time.perf_counter()`` instant: the deeper backups are done, all bounds stay valid)."""
    # The sawtooth's 0·inf (a state outside both supports) and a new point's 1/0: expected
    # (see UpperBound.ratios), silenced once for the whole trial.
    with np.errstate(divide="ignore", invalid="ignore"):
        _trial_quiet(state, precision, deadline)


def _trial_quiet(state: HsviState, precision: float, deadline: float) -> None:
    gamma = state.t.gamma
    tree = state.tree
    k, width = trial_start(state.root_weights, *state.root_bounds(), precision)
    node = tree.node(state.roots[k])
    path: List[Tuple[Node, float]] = []
    weight = float(state.root_weights[k])
    step_cost = state.step_cost()
    link: Optional[Tuple[Node, int]] = None      # the node's row in its parent's caches
    while True:
        tree.refresh(node)
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
        a = int(node.q_upper().argmax())
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
        if not state.room((len(path) + 1) * step_cost):
            break                          # a deeper path would not fit in the budget
        child = tree.child(node, row)
        if not state.keep_successors:
            node.drop_successors()         # computed again in the backup
        link = (node, row)
        node = child
        weight *= gamma * p_az
    for node, weight in reversed(path):
        backup(state, node)
        state.beliefs.add_one(node.b, weight, node.key)
        if time.perf_counter() > deadline:
            break                          # the deeper backups are done; all stay valid
    state.trials += 1


def backup(state: HsviState, node: Node) -> None:
    """Point-based backup of both bounds at the node's belief."""
    t = state.t
    lower = state.lower
    state.tree.refresh(node)
    b = node.b
    A, Z, S = t.A, t.Z, t.S
    # Lower: the best vector at each successor, pulled back through O and T. At a
    # successor of probability zero the vector counts at no state of b, only at the
    # others: the oldest current vector is taken there (as the argmax of a zero row
    # did; the blind vector of the first action, say, makes far more vectors that
    # dominate none: 1,500 instead of 600 on robot_fitted.pomdp).
    arg = np.full(A * Z, lower.log_index[0] if lower.log else 0)
    arg[node.succ] = node.lo.arg[1:]
    chosen = node.lo.vectors[arg]                                      # (A·Z, S')
    if t.G is not None:
        cand = t.R + (t.G @ chosen.reshape(A, Z * S, 1))[:, :, 0]     # (A, S)
    else:
        w = np.einsum("azs,azs->as", t.OT, chosen.reshape(A, Z, S))
        cand = t.R + t.gamma * t.back(w)
    vals = cand @ b
    a = int(vals.argmax())
    if vals[a] > node.lo.vals[0] + TINY:
        lower.add(cand[a], a)
    # Upper: one-step lookahead over the current upper bound.
    new_up = float(node.q_upper().max())
    if new_up < node.up.vals[0] - TINY:
        state.upper.add_one(b, new_up)
    if not state.keep_successors:
        node.drop_successors()
    state.backups += 1
