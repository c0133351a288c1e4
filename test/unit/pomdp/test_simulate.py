"""pomdpsim-like simulation: totals, confidence interval, reproducibility."""
import math

import numpy as np
import pytest

from solver_models import TIGER_OPTIMUM, build_chain
from ros_hrc.errors import SolverError
from ros_hrc.pomdp import offline
from ros_hrc.pomdp.planner import MdpPlanner, PolicyPlanner
from ros_hrc.pomdp.simulate import confidence_interval, simulate


def test_confidence_interval_is_mean_plus_minus_1_96_sd_over_root_n():
    mean, lo, hi, sd = confidence_interval(np.array([1.0, 2.0, 3.0, 4.0]))
    assert mean == 2.5
    assert sd == pytest.approx(math.sqrt(5.0 / 3.0))           # sample sd (n - 1)
    half = 1.96 * math.sqrt(5.0 / 3.0) / 2.0
    assert (lo, hi) == (pytest.approx(2.5 - half), pytest.approx(2.5 + half))


def test_confidence_interval_of_one_value_is_a_point_and_of_none_an_error():
    assert confidence_interval(np.array([3.0]))[1:3] == (3.0, 3.0)
    with pytest.raises(SolverError):
        confidence_interval(np.array([]))


def test_a_deterministic_chain_gives_its_exact_discounted_total():
    gamma, length = 0.9, 10
    chain = build_chain(4, discount=gamma)
    result = simulate(chain, lambda seed: MdpPlanner(chain), sim_len=length, sim_num=5, seed=1)
    # Rewards of 1 from the third step (entering the goal) on.
    expected = sum(gamma ** t for t in range(2, length))
    assert result.mean == pytest.approx(expected)
    assert result.ci95_low == pytest.approx(expected)
    assert result.ci95_high == pytest.approx(expected)
    assert result.undiscounted_mean == pytest.approx(length - 2)
    assert result.runs == 5 and result.steps == 50 and result.ms_per_step >= 0


def test_simulation_is_reproducible_from_its_seed(tiger):
    policy = offline.solve(tiger, timeout=30, precision=0.1)
    def run(seed):
        return simulate(tiger, lambda s: PolicyPlanner(tiger, policy, s), 30, 20, seed).returns
    assert np.array_equal(run(4), run(4))
    assert not np.array_equal(run(4), run(5))


def test_the_optimal_tiger_policy_scores_the_optimum(tiger):
    policy = offline.solve(tiger, timeout=30, precision=0.01)
    seen = []
    result = simulate(tiger, lambda s: PolicyPlanner(tiger, policy, s), sim_len=100,
                      sim_num=400, seed=0, progress=lambda n, m: seen.append(n))
    # 0.95^100 < 0.006: the 100-step total is the infinite-horizon value up to ~0.2.
    assert result.ci95_low - 0.2 <= TIGER_OPTIMUM <= result.ci95_high + 0.2
    assert seen == list(range(1, 401))


def test_bad_lengths_are_refused(tiger):
    with pytest.raises(SolverError):
        simulate(tiger, lambda s: MdpPlanner(tiger), sim_len=0, sim_num=1)
