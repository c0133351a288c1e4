"""HSVI's belief tree caches both bounds at each node (#24): they must equal what a full
computation gives (the lower one) or be a tighter valid bound (the upper one), and the rounds
at the corners before the first trial keep the bounds valid."""
from pathlib import Path

import numpy as np
import pytest

from ros_hrc.pomdp import hsvi
from ros_hrc.pomdp.io import load_model

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def partly_solved():
    """robot_completed.pomdp after a few trials: a tree of nodes whose caches were brought up
    to date at different times, with vectors and points added since."""
    solver = hsvi.HsviSolver(load_model(ROOT / "models/robot/robot_completed.pomdp"))
    solver.run(precision=1e-3, max_trials=6)
    assert len(solver.tree) > 20
    return solver


def _refreshed(solver):
    with np.errstate(divide="ignore", invalid="ignore"):
        for node in solver.tree.values():
            solver._refresh(node)
            yield node


def test_a_nodes_cached_lower_bound_is_the_best_vector_ever_added(partly_solved):
    lower = partly_solved.lower
    every_vector = lower._log[:lower.log_n]
    for node in _refreshed(partly_solved):
        full = (node.rows @ every_vector.T).max(axis=1)
        np.testing.assert_allclose(node.lo.vals, full, rtol=0, atol=1e-12)
        # The vector it names gives that value (the backup pulls that vector back).
        given = np.einsum("ms,ms->m", node.rows, node.lo.vectors[node.lo.arg])
        np.testing.assert_allclose(given, node.lo.vals, rtol=0, atol=1e-12)
        # At least the current vectors' bound (pruned ones are valid too).
        assert np.all(node.lo.vals >= lower.values(node.rows) - 1e-12)


def test_a_nodes_cached_upper_bound_is_at_most_the_sawtooth_and_above_the_lower(partly_solved):
    for node in _refreshed(partly_solved):
        assert np.all(node.up.vals <= partly_solved.upper.values(node.rows) + 1e-9)
        assert np.all(node.up.vals >= node.lo.vals - 1e-9)


def test_a_node_keeps_only_its_successors_of_nonzero_probability(partly_solved):
    t = partly_solved.t
    for node in _refreshed(partly_solved):
        p, B = t.successors(node.b)
        np.testing.assert_array_equal(node.succ, np.flatnonzero(p.ravel() > 0))
        np.testing.assert_allclose(node.rows[1:], B.reshape(-1, t.S)[node.succ], atol=1e-15)
        # Q = R·b + γ Σ_z p(z|b,a)·U(b_az), as over all A·Z successors.
        ub = np.zeros(t.A * t.Z)
        ub[node.succ] = node.up.vals[1:]
        q = t.R @ node.b + t.gamma * (p * ub.reshape(t.A, t.Z)).sum(axis=1)
        np.testing.assert_allclose(partly_solved._q_upper(node), q, atol=1e-12)


def test_the_rounds_at_the_corners_raise_the_lower_bound_there_and_stay_valid():
    model = load_model(ROOT / "models/robot/robot_completed.pomdp")
    solver = hsvi.HsviSolver(model)
    corners = np.eye(model.n_states)
    before_lo, before_up = solver.lower.values(corners), solver.upper.corner.copy()
    start = solver.bounds()
    solver.run(precision=1e-3, max_trials=0)          # the rounds only
    after_lo = solver.lower.values(corners)
    assert np.all(after_lo >= before_lo - 1e-12) and np.any(after_lo > before_lo + 0.1)
    assert np.all(solver.upper.corner <= before_up + 1e-12)
    assert np.all(after_lo <= solver.upper.corner + 1e-9)
    lo, up = solver.bounds()
    assert start[0] <= lo <= up <= start[1]
    assert solver.trials == 0 and solver.backups > 0
