"""The point-based solver (HSVI2 with sweeps) and the policy file."""
import numpy as np
import pytest

from solver_models import TIGER_OPTIMUM, build_chain, build_tiger
from ros_hrc.errors import SolverError
from ros_hrc.pomdp import hsvi, offline, policy as policy_mod
from ros_hrc.pomdp.policy import Policy

LISTEN, OPEN_LEFT, OPEN_RIGHT = 0, 1, 2


@pytest.fixture(scope="module")
def tiger_policy():
    return offline.solve(build_tiger(), timeout=30, precision=0.01)


def test_tiger_bounds_bracket_the_optimum_within_a_hundredth(tiger_policy):
    assert tiger_policy.lower <= TIGER_OPTIMUM + 0.005
    assert tiger_policy.upper >= TIGER_OPTIMUM - 0.005
    assert tiger_policy.upper - tiger_policy.lower <= 0.01


def test_tiger_policy_listens_until_two_consistent_observations(tiger_policy):
    assert tiger_policy.action(np.array([0.5, 0.5])) == LISTEN
    assert tiger_policy.action(np.array([0.85, 0.15])) == LISTEN
    assert tiger_policy.action(np.array([0.97, 0.03])) == OPEN_RIGHT
    assert tiger_policy.action(np.array([0.03, 0.97])) == OPEN_LEFT
    assert tiger_policy.value(np.array([0.5, 0.5])) == pytest.approx(tiger_policy.lower)


def test_solver_is_anytime_and_its_bounds_stay_valid(tiger):
    solver = hsvi.HsviSolver(tiger)
    previous = solver.bounds()
    for precision in (50.0, 5.0, 0.5):
        lo, up = solver.run(timeout=30, precision=precision)
        assert lo <= TIGER_OPTIMUM + 0.005 and up >= TIGER_OPTIMUM - 0.005
        assert lo >= previous[0] - 1e-9 and up <= previous[1] + 1e-9
        assert up - lo <= precision
        previous = (lo, up)


def test_a_tiny_timeout_still_returns_valid_bounds(tiger):
    pol = offline.solve(tiger, timeout=0.0, precision=1e-6)
    assert pol.lower <= TIGER_OPTIMUM <= pol.upper


def test_policy_save_and_load_round_trip(tiger_policy, tmp_path):
    path = tmp_path / "tiger.policy"          # any name: nothing is appended
    tiger_policy.save(str(path))
    assert path.exists() and not (tmp_path / "tiger.policy.npz").exists()
    loaded = policy_mod.load(str(path))
    assert np.array_equal(loaded.alphas, tiger_policy.alphas)
    assert np.array_equal(loaded.actions, tiger_policy.actions)
    assert loaded.lower == tiger_policy.lower and loaded.upper == tiger_policy.upper
    assert loaded.action_names == ["listen", "open-left", "open-right"]
    assert loaded.kind == "alpha" and loaded.stats["solver"] == "hsvi2"


def test_loading_something_that_is_not_a_policy_names_the_file(tmp_path):
    bad = tmp_path / "bad.policy"
    bad.write_text("not a policy\n")
    with pytest.raises(SolverError) as err:
        policy_mod.load(str(bad))
    assert str(bad) in str(err.value)
    with pytest.raises(SolverError):
        policy_mod.load(str(tmp_path / "missing.policy"))


def test_a_policy_for_another_model_is_refused(tiger_policy):
    with pytest.raises(SolverError):
        tiger_policy.check(build_chain(4))


def test_an_mdp_is_solved_by_value_iteration_and_saved_as_a_policy(tmp_path):
    gamma = 0.9
    chain = build_chain(4, discount=gamma)
    pol = offline.solve(chain, precision=1e-6)
    assert pol.kind == "mdp"
    v0 = gamma ** 2 / (1 - gamma)
    assert pol.lower - 1e-9 <= v0 <= pol.upper + 1e-9 and pol.upper - pol.lower <= 1e-6
    assert pol.stats["state_policy"][:3] == [1, 1, 1]
    point = np.eye(4)
    assert [pol.action(point[s]) for s in range(3)] == [1, 1, 1]
    pol.save(str(tmp_path / "chain.policy"))
    again = Policy.load(str(tmp_path / "chain.policy"))
    assert again.kind == "mdp" and np.array_equal(again.alphas, pol.alphas)


def test_hsvi_refuses_an_mdp_and_a_bad_precision(tiger):
    with pytest.raises(SolverError):
        hsvi.HsviSolver(build_chain(3))
    with pytest.raises(SolverError):
        hsvi.HsviSolver(tiger).run(precision=0.0)
