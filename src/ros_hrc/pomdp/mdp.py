"""Exact value iteration for MDPs, and the MDP-derived bounds POMDP solvers start from.

All functions work on the model's per-action sparse T (dense arrays are used when the model is
small, ``Model.dense_tables_fit``, where they are faster); rewards R(s, a, s') enter through
``model.R_sa``. Memory is O(non-zeros of T + A·S) for a large model.

Every iterative function stops at ``deadline`` (a ``time.perf_counter()`` instant) if given,
after at least one iteration where it needs one for a valid result: an offline solver builds
its bounds inside its own time budget.

Bounds on the optimal POMDP value V*(b) (each returned as per-action vectors, value = max_a b·Q[a]):
    blind_lower_bound      value of repeating one action forever (Hauskrecht's blind policies)
    mdp_upper_bound        Q of the fully observable MDP (QMDP), made strict by the VI error bound
    fast_informed_bound    Hauskrecht's FIB, tighter than QMDP, for small models
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ros_hrc.errors import SolverError
from ros_hrc.pomdp.model import DENSE_STATE_LIMIT, Model

__all__ = ["DENSE_STATE_LIMIT", "FIB_DENSE_ENTRIES", "MdpSolution", "value_iteration",
           "evaluate_policy", "mdp_upper_bound", "fast_informed_bound", "blind_lower_bound"]

#: The fast informed bound iterates a dense (A, Z, S, S) array; above this many numbers
#: (64 MB) it is not built and the QMDP bound, looser but valid, stands in.
FIB_DENSE_ENTRIES = 8_000_000


@dataclass
class MdpSolution:
    """Result of value iteration.

    ``V`` is within ``error_bound`` of the optimal values (sup norm); ``policy`` is greedy in ``Q``.
    """

    V: np.ndarray            # (S,)
    Q: np.ndarray            # (A, S)
    policy: np.ndarray       # (S,) action per state
    iterations: int
    residual: float          # last Bellman residual max|V_k - V_{k-1}|
    discount: float

    @property
    def error_bound(self) -> float:
        """max_s |V(s) - V*(s)| is at most this (the standard contraction bound)."""
        if self.discount == 0.0:
            return 0.0
        return self.discount * self.residual / (1.0 - self.discount)


class _Backup:
    """Computes Σ_s' T(s'|s,a) V(s') for every action, dense or sparse."""

    def __init__(self, model: Model) -> None:
        self.dense = model.dense_tables_fit
        self.T = model.dense_T if self.dense else model.T

    def expect(self, V: np.ndarray) -> np.ndarray:
        """(A, S) array of expected next values."""
        if self.dense:
            return self.T @ V
        return np.vstack([t @ V for t in self.T])


def value_iteration(model: Model, epsilon: float = 1e-6, max_iterations: int = 1_000_000,
                    timeout: Optional[float] = None,
                    progress: Optional[Callable[[int, float], None]] = None,
                    deadline: Optional[float] = None) -> MdpSolution:
    """Value iteration until the values are within ``epsilon`` of optimal (sup norm).

    Works for any model (the observations are ignored: this is the underlying MDP). Stops early,
    with a larger ``error_bound``, on ``max_iterations``, ``timeout`` seconds or ``deadline``;
    it always makes one iteration, so the error bound is finite.
    """
    if epsilon <= 0:
        raise SolverError(f"epsilon must be positive, got {epsilon}")
    gamma = float(model.discount)
    R = np.asarray(model.R_sa, dtype=float)
    backup = _Backup(model)
    # Residual at which the contraction bound γ r / (1 - γ) drops below epsilon.
    target = epsilon * (1.0 - gamma) / gamma if gamma > 0 else np.inf
    V = np.zeros(model.n_states)
    Q = R.copy()
    residual = np.inf
    start = time.perf_counter()
    it = 0
    while it < max_iterations:
        Q = R + gamma * backup.expect(V)
        V_new = Q.max(axis=0)
        residual = float(np.max(np.abs(V_new - V))) if V.size else 0.0
        V = V_new
        it += 1
        if residual <= target:
            break
        if progress is not None and it % 100 == 0:
            progress(it, residual)
        if timeout is not None and time.perf_counter() - start > timeout:
            break
        if deadline is not None and time.perf_counter() > deadline:
            break
    return MdpSolution(V=V, Q=Q, policy=Q.argmax(axis=0), iterations=it, residual=residual,
                       discount=gamma)


def evaluate_policy(model: Model, policy: np.ndarray, epsilon: float = 1e-9,
                    max_iterations: int = 1_000_000) -> np.ndarray:
    """Values of a fixed state->action policy (iterative evaluation to ``epsilon``)."""
    gamma = float(model.discount)
    S = model.n_states
    pol = np.asarray(policy, dtype=np.int64)
    rows = np.arange(S)
    R = model.R_sa[pol, rows]
    backup = _Backup(model)
    V = np.zeros(S)
    target = epsilon * (1.0 - gamma) / gamma if gamma > 0 else np.inf
    for _ in range(max_iterations):
        V_new = R + gamma * backup.expect(V)[pol, rows]
        done = np.max(np.abs(V_new - V)) <= target
        V = V_new
        if done:
            break
    return V


def mdp_upper_bound(model: Model, solution: Optional[MdpSolution] = None,
                    epsilon: float = 1e-6, deadline: Optional[float] = None) -> np.ndarray:
    """QMDP upper bound: (A, S) array Q with V*(b) <= max_a b·Q[a] for every belief b.

    The MDP's Q values are raised by the VI error bound so the bound holds despite stopping early.
    """
    sol = solution if solution is not None else value_iteration(model, epsilon,
                                                                deadline=deadline)
    slack = sol.error_bound
    gamma = float(model.discount)
    V_up = sol.V + slack
    return np.asarray(model.R_sa, dtype=float) + gamma * _Backup(model).expect(V_up)


def fast_informed_bound(model: Model, epsilon: float = 1e-6, max_iterations: int = 10_000,
                        timeout: Optional[float] = None,
                        deadline: Optional[float] = None) -> np.ndarray:
    """The fast informed bound (A, S): tighter than QMDP because it accounts for observations.

    Q(s,a) = R(s,a) + γ Σ_o max_a' Σ_s' T(s'|s,a) O(o|s',a) Q(s',a'), iterated from the QMDP
    bound; every iterate is itself a valid upper bound, so stopping early is safe.
    Only for small models (cost A²·Z·S² per iteration, a dense (A, Z, S, S) array of at most
    FIB_DENSE_ENTRIES numbers); for the others it is the QMDP bound.
    """
    gamma = float(model.discount)
    Q = mdp_upper_bound(model, epsilon=epsilon, deadline=deadline)
    if not fib_is_dense(model) or (deadline is not None and time.perf_counter() > deadline):
        return Q
    T = model.dense_T                    # (A, S, S')
    O = model.dense_O                    # (A, S', Z)
    R = np.asarray(model.R_sa, dtype=float)
    # M[a, o] = T_a * O_a[:, o] as (A, Z, S, S')
    M = T[:, None, :, :] * np.transpose(O, (0, 2, 1))[:, :, None, :]
    start = time.perf_counter()
    for _ in range(max_iterations):
        # inner[a, o, s, a'] = Σ_s' M[a,o,s,s'] Q[a', s']
        inner = M @ Q.T
        Q_new = R + gamma * inner.max(axis=3).sum(axis=1)
        Q_new = np.minimum(Q_new, Q)     # monotone from above; guards rounding
        change = float(np.max(np.abs(Q_new - Q)))
        Q = Q_new
        if change <= epsilon * (1.0 - gamma):
            break
        if timeout is not None and time.perf_counter() - start > timeout:
            break
        if deadline is not None and time.perf_counter() > deadline:
            break
    return Q


def fib_is_dense(model: Model) -> bool:
    """Whether :func:`fast_informed_bound` iterates (rather than returning QMDP)."""
    S = model.n_states
    return model.dense_tables_fit and model.n_actions * model.n_observations * S * S \
        <= FIB_DENSE_ENTRIES


def blind_lower_bound(model: Model, epsilon: float = 1e-6,
                      max_iterations: int = 100_000,
                      deadline: Optional[float] = None) -> np.ndarray:
    """(A, S) values of repeating each action forever: V*(b) >= max_a b·L[a].

    Iterated upward from min_s R(s,a)/(1-γ); each iterate is the value of repeating ``a`` for k
    steps and then collecting the worst reward forever, so stopping early (at ``deadline``)
    stays a lower bound.
    """
    gamma = float(model.discount)
    R = np.asarray(model.R_sa, dtype=float)
    L = np.repeat((R.min(axis=1) / (1.0 - gamma))[:, None], model.n_states, axis=1)
    if gamma == 0.0:
        return R.copy()
    backup = _Backup(model)
    target = epsilon * (1.0 - gamma)
    A = model.n_actions
    for _ in range(max_iterations):
        if backup.dense:
            expected = np.einsum("ast,at->as", backup.T, L)
        else:
            expected = np.vstack([backup.T[a] @ L[a] for a in range(A)])
        L_new = R + gamma * expected
        change = float(np.max(np.abs(L_new - L)))
        L = np.maximum(L_new, L)
        if change <= target:
            break
        if deadline is not None and time.perf_counter() > deadline:
            break
    return L
