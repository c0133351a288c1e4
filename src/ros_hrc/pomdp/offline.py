"""Offline solving: the solver that fits the model, and value iteration's policy.

* A fully observable model is an MDP: value iteration (:func:`solve_mdp`).
* A POMDP whose observations tell its fully observed values after each step
  (:func:`ros_hrc.pomdp.momdp.applies`) is solved by blocks of states sharing those values
  (:mod:`ros_hrc.pomdp.momdp`, SARSOP's MOMDP representation): RockSample_4_3 0.7 s instead
  of 38 s.
* Any other POMDP: HSVI2 over the whole state space (:mod:`ros_hrc.pomdp.hsvi`).

``solve``'s timeout counts from the call, so building the solver's tables and the MDP bounds
is inside it.
"""
from __future__ import annotations

import time
from typing import Callable, Optional

import numpy as np

from ros_hrc.pomdp import mdp, memory
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.policy import Policy
from ros_hrc.pomdp.search import SolveProgress

__all__ = ["solve", "solve_mdp", "mdp_memory_needed"]


def solve(model: Model, timeout: Optional[float] = 60.0, precision: float = 1e-3,
          progress: Optional[Callable[[SolveProgress], None]] = None,
          memory_limit: Optional[int] = None) -> Policy:
    """Solve ``model`` offline: HSVI2 for a POMDP, value iteration for an MDP; a model with
    fully observed variables that its observations tell (``momdp.applies``) by blocks, with
    the same search (:mod:`ros_hrc.pomdp.momdp`, as SARSOP does).

    The returned policy carries ``lower``/``upper``, bounds on the optimal value at the start
    (the initial belief; with fully observed variables Σ_k P(k) V*(b_k) over
    ``model.start_split()``, what SARSOP reports), and ``stats`` (seconds, trials, ...). Stops
    when ``upper - lower <= precision`` or ``timeout`` seconds (None: no limit) after the call,
    the building of the solver's tables included. ``memory_limit`` (bytes, None: none): what
    each solver refuses and where it stops, see :mod:`ros_hrc.pomdp.hsvi` and
    :mod:`ros_hrc.pomdp.momdp`.
    """
    start = time.perf_counter()
    deadline = start + timeout if timeout is not None else None
    if model.fully_observable:
        return solve_mdp(model, timeout=timeout, precision=precision, memory_limit=memory_limit)
    # The point-based solvers are imported for a POMDP only: an MDP's solve is over before
    # they would have loaded (hrc_pomdp solve on a human MDP is mostly start-up).
    from ros_hrc.pomdp import hsvi, momdp
    if momdp.applies(model):
        return momdp.solve(model, timeout=timeout, precision=precision,
                           memory_limit=memory_limit, progress=progress)
    solver = hsvi.HsviSolver(model, deadline=deadline, memory_limit=memory_limit)
    remaining = None if deadline is None else max(0.0, deadline - time.perf_counter())
    solver.run(timeout=remaining, precision=precision, progress=progress)
    # Pruning the upper bound's points costs O(points² · S): skipped once the time is up
    # (the unpruned vectors and points are as valid, and the bounds at least as tight).
    return solver.policy(prune=deadline is None or time.perf_counter() < deadline)


def mdp_memory_needed(model: Model) -> int:
    """Bytes value iteration needs: the model and a few (A, S) arrays (dense T when small)."""
    A, S = model.n_actions, model.n_states
    dense = 8 * A * S * S if model.dense_tables_fit else 0
    return memory.model_bytes(model) + 8 * 8 * A * S + dense


def solve_mdp(model: Model, timeout: Optional[float] = 60.0, precision: float = 1e-3,
              memory_limit: Optional[int] = None) -> Policy:
    """Value iteration, stored as a policy with one vector Q[a] per action (kind "mdp").

    Its bounds are b0·V ± the error bound: the start value of an MDP, whose start state is seen
    (each state its own key, so Σ_k P(k) V(b_k) = b0·V).
    """
    memory.require(mdp_memory_needed(model), memory_limit, model.source or model.name or
                   "the model", f"value iteration ({model.n_states} states, "
                                f"{model.n_actions} actions)")
    start = time.perf_counter()
    # The bracket b0·V ± error_bound must be narrower than the precision asked for.
    sol = mdp.value_iteration(model, epsilon=min(precision / 2.0, 1e-6), timeout=timeout)
    seconds = time.perf_counter() - start
    b0 = np.asarray(model.initial_belief, dtype=float)
    centre = float(b0 @ sol.V)
    slack = sol.error_bound
    return Policy(alphas=sol.Q.copy(), actions=np.arange(model.n_actions),
                  state_names=list(model.states), action_names=list(model.actions),
                  discount=model.discount, lower=centre - slack, upper=centre + slack, kind="mdp",
                  model_name=model.name,
                  stats={"solver": "value_iteration", "seconds": seconds,
                         "iterations": sol.iterations, "residual": sol.residual,
                         "state_policy": [int(a) for a in sol.policy]})
