"""Paired comparisons on the same human streams, and the counterfactual outcome of an episode.

No ROS; scipy for every test and interval (DESIGN §14, issue #21). Two robots, or a robot and
the human alone, are run on the same (human model, seed, episode) streams, so their episodes
come in pairs and the tests are the paired ones:

- success, pre-emption (any yes/no per episode): McNemar's exact test, i.e. the two-sided exact
  binomial test of the discordant pairs (``scipy.stats.binomtest``);
- times: the Wilcoxon signed-rank test (``scipy.stats.wilcoxon``);
- a proportion on its own: the Wilson score interval (``BinomTestResult.proportion_ci``).

:func:`episodes_to_detect` sizes a study: the fewest episodes per cell at which McNemar's exact
test finds a given difference in success with the given power (computed exactly from
``scipy.stats.binom``; no normal approximation).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence, Tuple

import numpy as np

__all__ = ["OUTCOMES", "counterfactual_outcome", "wilson", "McNemar", "mcnemar_exact",
           "Wilcoxon", "wilcoxon_paired", "mcnemar_power", "episodes_to_detect"]

#: An episode with the robot against the same human stream alone (DESIGN §14).
OUTCOMES: Tuple[str, ...] = ("both_succeed", "rescued", "pre_empted", "hindered", "both_fail")


def counterfactual_outcome(alone_success: bool, with_success: bool, succeeded_by: str) -> str:
    """What the robot did to this human, judged against the same human stream alone.

    ``succeeded_by`` is who holds the object at the end of the episode with the robot
    (``human``, ``robot`` or ``none``). A human who succeeds alone and whose object the robot
    took was pre-empted, whatever the labels said of his state of mind.
    """
    if succeeded_by not in ("human", "robot", "none"):
        raise ValueError(f"succeeded_by must be human, robot or none, got {succeeded_by!r}")
    if bool(with_success) != (succeeded_by != "none"):
        raise ValueError(f"with_success={with_success!r} contradicts succeeded_by={succeeded_by!r}")
    if alone_success:
        if not with_success:
            return "hindered"
        return "pre_empted" if succeeded_by == "robot" else "both_succeed"
    return "rescued" if with_success else "both_fail"


def wilson(successes: int, n: int, confidence: float = 0.95) -> Tuple[float, float, float]:
    """(p, low, high): a proportion and its Wilson score interval; n = 0 gives NaNs."""
    if n == 0:
        return (math.nan, math.nan, math.nan)
    from scipy import stats
    interval = stats.binomtest(int(successes), int(n)).proportion_ci(
        confidence_level=confidence, method="wilson")
    return (successes / n, float(interval.low), float(interval.high))


def _paired(first: Sequence, second: Sequence) -> Tuple[np.ndarray, np.ndarray]:
    a, b = np.asarray(first), np.asarray(second)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(f"paired samples must be two equally long lists, got {a.shape} and {b.shape}")
    return a, b


@dataclass(frozen=True)
class McNemar:
    """McNemar's exact test of two paired yes/no samples (``first`` against ``second``)."""

    n: int                  # pairs
    first_only: int         # pairs where only the first said yes
    second_only: int        # pairs where only the second said yes
    difference: float       # P(second) - P(first)
    p_value: float          # two-sided, exact


def mcnemar_exact(first: Sequence[bool], second: Sequence[bool]) -> McNemar:
    """McNemar's exact test: only the discordant pairs carry information, and under the null
    each is equally likely to go either way (a two-sided exact binomial test at 1/2)."""
    a, b = _paired(first, second)
    a, b = a.astype(bool), b.astype(bool)
    first_only, second_only = int(np.sum(a & ~b)), int(np.sum(~a & b))
    discordant = first_only + second_only
    if discordant == 0:
        p_value = 1.0
    else:
        from scipy import stats
        p_value = float(stats.binomtest(first_only, discordant, 0.5).pvalue)
    n = int(a.size)
    difference = (second_only - first_only) / n if n else math.nan
    return McNemar(n, first_only, second_only, difference, p_value)


@dataclass(frozen=True)
class Wilcoxon:
    """The Wilcoxon signed-rank test of paired values (``second - first``)."""

    n: int                   # pairs
    nonzero: int             # pairs whose difference is not 0 (the test uses only these)
    median_difference: float
    statistic: float
    p_value: float           # two-sided


def wilcoxon_paired(first: Sequence[float], second: Sequence[float]) -> Wilcoxon:
    """Wilcoxon's signed-rank test of ``second - first`` (two-sided; zero differences dropped,
    Wilcoxon's own rule). Every difference 0 (or no pairs) gives p = 1: nothing differs."""
    a, b = _paired(first, second)
    a, b = a.astype(float), b.astype(float)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError("wilcoxon_paired: values must be finite (drop unpaired episodes first)")
    d = b - a
    nonzero = int(np.count_nonzero(d))
    median = float(np.median(d)) if d.size else math.nan
    if nonzero == 0:
        return Wilcoxon(int(d.size), 0, median, math.nan, 1.0)
    from scipy import stats
    result = stats.wilcoxon(d, zero_method="wilcox", alternative="two-sided")
    return Wilcoxon(int(d.size), nonzero, median, float(result.statistic), float(result.pvalue))


def _rejection_given_discordant(most: int, share: float, alpha: float) -> np.ndarray:
    """r[m] = P(McNemar's exact test rejects | m discordant pairs), m = 0..most, when each
    discordant pair goes the second policy's way with probability ``share``."""
    from scipy import stats
    r = np.zeros(most + 1)
    for m in range(1, most + 1):
        k = np.arange(m + 1)
        # the exact two-sided p-value of each split k of m pairs, as binomtest gives it at 1/2
        p_values = np.minimum(1.0, 2 * np.minimum(stats.binom.cdf(k, m, 0.5),
                                                  stats.binom.sf(k - 1, m, 0.5)))
        r[m] = stats.binom.pmf(k[p_values <= alpha], m, share).sum()
    return r


def _check_rates(gain: float, loss: float) -> None:
    if not (0 <= loss and 0 < gain and gain + loss <= 1):
        raise ValueError(f"need 0 <= loss, 0 < gain and gain + loss <= 1, got {gain}, {loss}")


def mcnemar_power(n: int, gain: float, loss: float = 0.0, alpha: float = 0.05) -> float:
    """The power of McNemar's exact two-sided test at level ``alpha`` with ``n`` pairs, when a
    pair goes the second policy's way with probability ``gain`` and the first's with ``loss``
    (so the difference in success is ``gain - loss``). Exact: the number of discordant pairs is
    Binomial(n, gain + loss) and, given m of them, the split is Binomial(m, gain / (gain + loss))."""
    from scipy import stats
    _check_rates(gain, loss)
    r = _rejection_given_discordant(n, gain / (gain + loss), alpha)
    return float(np.dot(stats.binom.pmf(np.arange(n + 1), n, gain + loss), r))


def episodes_to_detect(difference: float = 0.15, loss: float = 0.05, alpha: float = 0.05,
                       power: float = 0.8, limit: int = 1000) -> int:
    """The fewest paired episodes at which McNemar's exact test detects a ``difference`` in
    success with at least ``power``, when the weaker policy still wins a share ``loss`` of the
    pairs (noise both ways: more discordant pairs, more episodes needed)."""
    from scipy import stats
    gain = difference + loss
    _check_rates(gain, loss)
    r = _rejection_given_discordant(limit, gain / (gain + loss), alpha)
    for n in range(1, limit + 1):
        if np.dot(stats.binom.pmf(np.arange(n + 1), n, gain + loss), r[:n + 1]) >= power:
            return n
    raise ValueError(f"more than {limit} episodes would be needed")
