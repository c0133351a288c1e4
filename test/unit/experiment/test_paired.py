"""Paired statistics and counterfactual outcomes, against values worked out by hand."""
import math

import pytest

from ros_hrc.experiment.paired import (OUTCOMES, counterfactual_outcome, episodes_to_detect,
                                       mcnemar_exact, mcnemar_power, wilcoxon_paired, wilson)


@pytest.mark.parametrize("alone, with_robot, by, outcome", [
    (True, True, "human", "both_succeed"),
    (True, True, "robot", "pre_empted"),      # would have made it alone; the robot took it
    (False, True, "robot", "rescued"),
    (False, True, "human", "rescued"),         # e.g. a point that got the human there
    (True, False, "none", "hindered"),
    (False, False, "none", "both_fail"),
])
def test_counterfactual_outcome_of_a_constructed_pair(alone, with_robot, by, outcome):
    assert counterfactual_outcome(alone, with_robot, by) == outcome
    assert outcome in OUTCOMES


def test_counterfactual_refuses_contradictions():
    with pytest.raises(ValueError, match="contradicts"):
        counterfactual_outcome(True, True, "none")
    with pytest.raises(ValueError, match="succeeded_by"):
        counterfactual_outcome(True, True, "nobody")


def test_wilson_against_known_intervals():
    p, low, high = wilson(0, 10)
    assert p == 0 and low == pytest.approx(0, abs=1e-12)
    assert high == pytest.approx(3.8415 / 13.8415, abs=1e-4)      # z^2 / (n + z^2)
    p, low, high = wilson(8, 10)
    assert (low, high) == pytest.approx((0.4902, 0.9433), abs=1e-4)
    assert all(math.isnan(x) for x in wilson(0, 0))


def test_mcnemar_exact_against_the_binomial():
    # 2 pairs only the first policy won, 10 only the second: p = 2 * P(X <= 2 | 12, 1/2)
    first = [1] * 2 + [0] * 10 + [1] * 5 + [0] * 3
    second = [0] * 2 + [1] * 10 + [1] * 5 + [0] * 3
    result = mcnemar_exact(first, second)
    assert (result.n, result.first_only, result.second_only) == (20, 2, 10)
    assert result.p_value == pytest.approx(2 * (1 + 12 + 66) / 4096)
    assert result.difference == pytest.approx(8 / 20)


def test_mcnemar_without_discordant_pairs_finds_nothing():
    assert mcnemar_exact([1, 0, 1], [1, 0, 1]).p_value == 1.0


def test_wilcoxon_against_the_exact_null():
    # five positive differences of distinct sizes: the exact two-sided p is 2 / 2^5
    result = wilcoxon_paired([0, 0, 0, 0, 0, 3], [1, 2, 3, 4, 5, 3])
    assert (result.n, result.nonzero) == (6, 5)
    assert result.p_value == pytest.approx(2 / 32)
    assert result.median_difference == pytest.approx(2.5)


def test_wilcoxon_of_identical_samples_finds_nothing():
    assert wilcoxon_paired([1.5, 2.0], [1.5, 2.0]).p_value == 1.0


def test_paired_samples_must_pair():
    with pytest.raises(ValueError, match="equally long"):
        mcnemar_exact([1, 0], [1])
    with pytest.raises(ValueError, match="finite"):
        wilcoxon_paired([1.0, float("nan")], [1.0, 2.0])


def test_power_in_the_smallest_exact_cases():
    # every pair goes one way: 6 pairs give p = 2/64 < 0.05, 5 pairs give 2/32 > 0.05
    assert mcnemar_power(6, 1.0) == pytest.approx(1.0)
    assert mcnemar_power(5, 1.0) == pytest.approx(0.0)


def test_episodes_to_detect_a_15_point_difference():
    n = episodes_to_detect(0.15, loss=0.05)
    # Connor's (1987) normal approximation gives ~85; the exact test needs a few more.
    assert 85 <= n <= 100
    assert mcnemar_power(n, 0.20, 0.05) >= 0.8 > mcnemar_power(n - 1, 0.20, 0.05)
    assert episodes_to_detect(0.15, loss=0.0) < n    # less noise, fewer episodes
