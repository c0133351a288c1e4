"""What HSVI2's two searches share besides their bounds (:mod:`ros_hrc.pomdp.bounds`): the
plain one over the whole state space (:mod:`ros_hrc.pomdp.hsvi`) and the one by blocks of fully
observed values (:mod:`ros_hrc.pomdp.momdp`).

Both bound Σ_k P(k) V*(b_k) over their roots b_k (the initial belief split by the values seen
at the start, ``Model.start_split``; one root without them) and run trials from one root at a
time with HSVI2's and SARSOP's dynamic target (:func:`trial_start`); both report their progress
about once per trial as a :class:`SolveProgress`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Tuple

import numpy as np

#: A trial's target gap is this fraction of the root's gap (never below the precision).
TRIAL_ZETA = 0.95


@dataclass
class SolveProgress:
    """What a progress callback receives, about once per trial."""

    seconds: float
    trials: int
    lower: float
    upper: float
    n_alphas: int
    n_points: int


def trial_start(root_weights: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                precision: float) -> Tuple[int, float]:
    """The root a trial starts at and the gap it descends to, from the bounds at each root.

    The root is the one whose weighted gap exceeds the precision the most: while the weighted
    sum of the gaps is above ``precision``, some root's gap is, and this picks one of those.
    The target is a fraction TRIAL_ZETA of that root's gap, never below the precision: early
    trials stay shallow, where the bounds are loose everywhere, and go deeper as the gap
    closes. The solvers still stop only at a gap <= precision.
    """
    k = int(np.argmax(root_weights * (upper - lower - precision)))
    return k, max(precision, TRIAL_ZETA * float(upper[k] - lower[k]))
