"""Value iteration and the MDP-derived bounds."""
import numpy as np
import pytest

from solver_models import TIGER_OPTIMUM, build_chain
from ros_hrc.errors import SolverError
from ros_hrc.pomdp import mdp


def test_value_iteration_on_a_chain_gives_the_known_values():
    gamma = 0.9
    chain = build_chain(4, discount=gamma)
    sol = mdp.value_iteration(chain, epsilon=1e-9)
    expected = [gamma ** 2 / (1 - gamma), gamma / (1 - gamma), 1 / (1 - gamma), 1 / (1 - gamma)]
    assert np.allclose(sol.V, expected, atol=1e-8)
    assert list(sol.policy[:3]) == [1, 1, 1]          # always move right before the goal
    assert sol.error_bound <= 1e-9


def test_value_iteration_error_bound_holds_when_stopped_early():
    chain = build_chain(4, discount=0.95)
    exact = mdp.value_iteration(chain, epsilon=1e-10).V
    rough = mdp.value_iteration(chain, epsilon=1.0)
    assert np.max(np.abs(rough.V - exact)) <= rough.error_bound + 1e-12


def test_evaluate_policy_matches_the_optimal_values_for_the_greedy_policy():
    chain = build_chain(5, discount=0.8)
    sol = mdp.value_iteration(chain, epsilon=1e-10)
    assert np.allclose(mdp.evaluate_policy(chain, sol.policy), sol.V, atol=1e-8)
    stay = np.zeros(5, dtype=int)
    assert np.allclose(mdp.evaluate_policy(chain, stay)[:4], 0.0)


def test_value_iteration_refuses_a_non_positive_epsilon(chain):
    with pytest.raises(SolverError):
        mdp.value_iteration(chain, epsilon=0.0)


def test_tiger_bounds_are_ordered_around_the_optimum(tiger):
    b0 = tiger.initial_belief
    blind = (mdp.blind_lower_bound(tiger) @ b0).max()
    fib = (mdp.fast_informed_bound(tiger) @ b0).max()
    qmdp = (mdp.mdp_upper_bound(tiger) @ b0).max()
    assert blind == pytest.approx(-20.0, abs=1e-4)     # listen forever
    assert blind <= TIGER_OPTIMUM <= fib <= qmdp + 1e-9
    assert qmdp == pytest.approx(189.0, abs=1e-3)      # -1 + 0.95 * 200


def test_blind_lower_bound_values_each_fixed_action(tiger):
    L = mdp.blind_lower_bound(tiger)
    # Opening left forever: reward -45 a step on average after the first, -100/10 first.
    assert L[1, 0] == pytest.approx(-100 + 0.95 * -45 / 0.05, abs=1e-3)
    assert L[1, 1] == pytest.approx(10 + 0.95 * -45 / 0.05, abs=1e-3)
