"""The statistics of an experiment: intervals, paired comparisons, the summary and its tables.

No ROS; scipy through :mod:`ros_hrc.experiment.paired` (one piece of code per test).

:func:`mean_ci` (bootstrap percentile), :func:`proportion_ci` (Wilson score: :func:`paired.wilson`),
:func:`best_reactive` (the tuned baseline), :func:`compare` (paired tests of two policies on
the same streams), :func:`summarize` (one dict per human model x robot policy, and per policy
pooled over the held-out humans), :func:`write_summary` (CSV + Markdown, each written whole or
not at all). Every episode is one independent draw (its own streams); a comparison pairs the
episodes of two policies that ran on the same (human model, seed, episode) stream.
"""
from __future__ import annotations

import csv
import io
import math
import operator
import os
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

from ros_hrc.experiment import paired
from ros_hrc.experiment.episode import ALONE_POLICY, is_reactive, robot_policy
from ros_hrc.experiment.rows import UNPAIRED, EpisodeRow
from ros_hrc.experiment.store import ensure_parent
from ros_hrc.pomdp.output import write_text_atomically

def _check_confidence(confidence: float) -> None:
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")


#: The bootstrap of :func:`mean_ci`: its resamples, and the seed of their draws (a summary
#: written twice from the same rows is the same).
BOOTSTRAP_RESAMPLES = 9999
BOOTSTRAP_SEED = 0


def mean_ci(values: Iterable[float], confidence: float = 0.95) -> Tuple[float, float, float]:
    """(mean, low, high): the mean and its bootstrap percentile confidence interval
    (``scipy.stats.bootstrap``, :data:`BOOTSTRAP_RESAMPLES` resamples of the values, drawn
    from :data:`BOOTSTRAP_SEED`).

    The percentile interval is made of means of resampled values, so it stays within their
    range: a count or a duration never gets a negative bound, which Student's t gave skewed
    counts (``Steps 3.5 [-2.9, 9.9]`` from two episodes). It assumes no shape of the
    distribution; with few values it is narrower than it should be (docs/experiments.md).

    n = 0 gives (nan, nan, nan); n = 1 gives (x, nan, nan): one value says nothing about the
    spread, and a zero-width interval would claim a certainty the data do not have. Values
    must be finite (filter NaNs first, on purpose: dropping them here would change n silently).
    """
    _check_confidence(confidence)
    xs = [float(v) for v in values]
    if not all(math.isfinite(x) for x in xs):
        raise ValueError("mean_ci: values must be finite")
    n = len(xs)
    if n == 0:
        return (math.nan, math.nan, math.nan)
    mean = math.fsum(xs) / n
    if n == 1:
        return (mean, math.nan, math.nan)
    if min(xs) == max(xs):
        return (mean, mean, mean)     # every resample's mean is the one value
    import numpy as np
    # On first use: scipy.stats costs a program about 1.3 s of CPU to import, and
    # hrc_experiment needs it only for the summary at a run's end.
    from scipy import stats
    interval = stats.bootstrap((np.asarray(xs),), np.mean, confidence_level=confidence,
                               n_resamples=BOOTSTRAP_RESAMPLES, batch=1000,
                               method="percentile",
                               rng=np.random.default_rng(BOOTSTRAP_SEED)).confidence_interval
    return (mean, float(interval.low), float(interval.high))


def proportion_ci(successes: int, n: int, confidence: float = 0.95) -> Tuple[float, float, float]:
    """(p, low, high): a proportion and its Wilson score interval (:func:`paired.wilson`).

    Wilson rather than the normal approximation: it stays inside [0, 1] and keeps a sensible
    width at 0/n and n/n, which small experiments hit often. n = 0 gives (nan, nan, nan).
    """
    _check_confidence(confidence)
    successes, n = operator.index(successes), operator.index(n)
    if n < 0 or not 0 <= successes <= max(n, 0):
        raise ValueError(f"proportion_ci: need 0 <= successes <= n, got {successes}/{n}")
    return paired.wilson(successes, n, confidence)


def median(values: Iterable[float]) -> float:
    """The median of the finite values; NaN when there are none."""
    xs = sorted(float(v) for v in values if math.isfinite(float(v)))
    if not xs:
        return math.nan
    middle = len(xs) // 2
    return xs[middle] if len(xs) % 2 else (xs[middle - 1] + xs[middle]) / 2


#: The human model of the pooled entries: every human, over the streams held out from the
#: robot model's fit (``in_sample`` 0).
POOLED = "held-out (pooled)"


# --------------------------------------------------------------------------------------------
# The tuned baseline

def _budget(name: str) -> float:
    budget = robot_policy(name).reactive_budget
    return math.inf if budget is None else float(budget)


def reactive_rank(rows: Sequence[EpisodeRow]) -> Tuple[float, float, float]:
    """What :func:`best_reactive` sorts by (smaller is better): (-success rate, pre-emption
    rate, median time to success; NaN time as +inf)."""
    n = len(rows)
    success = sum(r.success for r in rows) / n if n else 0.0
    pre_empted = sum(r.outcome == "pre_empted" for r in rows) / n if n else 1.0
    time = median(r.time_to_success for r in rows)
    return (-success, pre_empted, math.inf if math.isnan(time) else time)


def best_reactive(rows: Iterable[EpisodeRow]) -> Optional[str]:
    """The best reactive robot among the rows' ``reactive`` / ``reactive@N`` policies: the
    highest success rate, then the fewest pre-emptions (a rate), then the shortest median time
    to success, then the smallest budget. None when the rows have no reactive robot."""
    groups: Dict[str, List[EpisodeRow]] = {}
    for row in rows:
        if is_reactive(row.robot_policy):
            groups.setdefault(row.robot_policy, []).append(row)
    if not groups:
        return None
    return min(groups, key=lambda name: (*reactive_rank(groups[name]), _budget(name), name))


# --------------------------------------------------------------------------------------------
# Paired comparisons

#: The one sign of a time in the summary, said in its header: a gain, the other's time to
#: success minus the robot policy's (the human alone's, or the baseline's), positive when the
#: robot policy succeeded sooner; the outcomes' time gain and the comparisons' both.
TIME_GAIN = ("Time gain: the other's time to success minus the robot policy's, over the pairs "
             "where both succeed (the other: the human alone, or the baseline compared "
             "against); positive: the robot policy succeeded sooner. Every table uses this "
             "sign.")
#: What one comparison gives (keys of :func:`compare`, each prefixed in the summary).
COMPARISON_KEYS: Tuple[str, ...] = (
    "policy", "pairs", "success_diff", "success_p", "pre_empted_diff", "pre_empted_p",
    "time_pairs", "time_gain_median", "time_p", "success_q", "pre_empted_q", "time_q",
    "own_success_diff", "own_success_p", "own_success_q")
#: The tests of a comparison whose p-values are adjusted together (see adjust_for_many_tests).
TESTS: Tuple[str, ...] = ("success", "pre_empted", "time", "own_success")


def empty_comparison() -> Dict[str, Any]:
    """A comparison that was not made (no baseline, or the policy is the baseline)."""
    return {"policy": "", "pairs": 0, **{k: math.nan for k in COMPARISON_KEYS[2:]}}


def compare(policy_rows: Sequence[EpisodeRow], baseline_rows: Sequence[EpisodeRow],
            baseline: str) -> Dict[str, Any]:
    """``policy_rows`` against ``baseline_rows`` on the streams both ran
    ((human model, seed, episode)): McNemar's exact test of success, of pre-emption and of the
    human's own success (he, not the robot, got the object), Wilcoxon's signed-rank test of the time to success on the pairs where both succeeded.
    A proportion's difference is the policy's minus the baseline's; the time is a gain, as
    everywhere in the summary (:data:`TIME_GAIN`): the median of the baseline's time minus
    the policy's over the pairs (positive: the policy succeeded sooner)."""
    by_stream = {(r.human_model, r.seed, r.episode): r for r in baseline_rows}
    pairs = [(by_stream[(r.human_model, r.seed, r.episode)], r) for r in policy_rows
             if (r.human_model, r.seed, r.episode) in by_stream]
    return _paired_tests(pairs, baseline)


def compare_with_alone(policy_rows: Sequence[EpisodeRow]) -> Dict[str, Any]:
    """``policy_rows`` against the human alone on the same streams, from each row's own
    counterfactual columns (alone_success, alone_time_to_success; alone never pre-empts)."""
    class Alone:   # the counterfactual half of a pair, as a row would give it
        def __init__(self, row: EpisodeRow) -> None:
            self.success = row.alone_success
            self.succeeded_by = "human" if row.alone_success else "none"
            self.outcome = "both_succeed" if row.alone_success else "both_fail"
            self.time_to_success = row.alone_time_to_success
    return _paired_tests([(Alone(r), r) for r in policy_rows if r.outcome != UNPAIRED],
                         ALONE_POLICY)


def _paired_tests(pairs: Sequence[Tuple[Any, EpisodeRow]], baseline: str) -> Dict[str, Any]:
    result = empty_comparison()
    result.update(policy=baseline, pairs=len(pairs))
    if not pairs:
        return result
    success = paired.mcnemar_exact([bool(b.success) for b, _ in pairs],
                                   [bool(p.success) for _, p in pairs])
    pre_empted = paired.mcnemar_exact([b.outcome == "pre_empted" for b, _ in pairs],
                                      [p.outcome == "pre_empted" for _, p in pairs])
    own = paired.mcnemar_exact([b.succeeded_by == "human" for b, _ in pairs],
                               [p.succeeded_by == "human" for _, p in pairs])
    timed = [(b.time_to_success, p.time_to_success) for b, p in pairs
             if b.success and p.success]
    result.update(success_diff=success.difference, success_p=success.p_value,
                  pre_empted_diff=pre_empted.difference, pre_empted_p=pre_empted.p_value,
                  own_success_diff=own.difference, own_success_p=own.p_value,
                  time_pairs=len(timed))
    if timed:
        # wilcoxon_paired tests second - first: the baseline's time minus the policy's, a gain.
        times = paired.wilcoxon_paired([p for _, p in timed], [b for b, _ in timed])
        result.update(time_gain_median=times.median_difference, time_p=times.p_value)
    return result


# --------------------------------------------------------------------------------------------
# The summary

#: Keys of each :func:`summarize` dict, in the summary CSV's column order.
SUMMARY_COLUMNS: Tuple[str, ...] = (
    "human_model", "robot_policy", "n", "confidence",
    "successes", "success_rate", "success_low", "success_high",
    "human_successes", "robot_successes", "object_left_belt", "step_limit",
    "alone_successes", "both_succeed", "rescued", "pre_empted", "hindered", "both_fail",
    "pre_empted_rate", "pre_empted_low", "pre_empted_high",
    "time_to_success_median", "time_gain_median", "time_gain_pairs",
    "wasted_actions_mean", "wasted_actions_low", "wasted_actions_high",
    "against_warning", "against_warning_episodes", "in_sample",
    "rescued_by_pointing", "warnings_after_help", "warnings_after_help_episodes",
    "best_reactive",
    *(f"vs_reactive_{k}" for k in COMPARISON_KEYS),
    *(f"vs_alone_{k}" for k in COMPARISON_KEYS),
    "steps_mean", "steps_low", "steps_high",
    "sim_seconds_mean", "sim_seconds_low", "sim_seconds_high",
    "reward_mean", "reward_low", "reward_high",
    "intrusive_actions_mean", "intrusive_actions_low", "intrusive_actions_high",
    "warnings_mean", "warnings_low", "warnings_high",
    "zero_probability_observations", "observations", "zero_probability_rate",
    "mean_decision_ms")

# summary prefix -> EpisodeRow column, for the quantities given as mean + bootstrap interval
_MEAN_CI_QUANTITIES: Tuple[Tuple[str, str], ...] = (
    ("wasted_actions", "wasted_actions"),
    ("steps", "steps"), ("sim_seconds", "sim_seconds"), ("reward", "robot_discounted_reward"),
    ("intrusive_actions", "intrusive_actions"), ("warnings", "warnings"))


def _entry(human_model: str, robot_policy: str, group: Sequence[EpisodeRow],
           confidence: float) -> Dict[str, Any]:
    successes = sum(r.success for r in group)
    p, low, high = proportion_ci(successes, len(group), confidence)
    outcomes = {o: sum(r.outcome == o for r in group) for o in paired.OUTCOMES}
    pre, pre_low, pre_high = proportion_ci(outcomes["pre_empted"], len(group), confidence)
    gains = [r.time_gain for r in group if math.isfinite(r.time_gain)]
    entry: Dict[str, Any] = {
        "human_model": human_model, "robot_policy": robot_policy, "n": len(group),
        "confidence": confidence, "successes": successes,
        "success_rate": p, "success_low": low, "success_high": high,
        "human_successes": sum(r.succeeded_by == "human" for r in group),
        "robot_successes": sum(r.succeeded_by == "robot" for r in group),
        "object_left_belt": sum(r.end_reason == "object_left_belt" for r in group),
        "step_limit": sum(r.end_reason == "step_limit" for r in group),
        "alone_successes": sum(r.alone_success for r in group if r.outcome != UNPAIRED),
        **outcomes,
        "pre_empted_rate": pre, "pre_empted_low": pre_low, "pre_empted_high": pre_high,
        "time_to_success_median": median(r.time_to_success for r in group),
        "time_gain_median": median(gains), "time_gain_pairs": len(gains),
        "against_warning": sum(r.against_warning for r in group),
        "against_warning_episodes": sum(r.against_warning > 0 for r in group),
        "in_sample": sum(r.in_sample for r in group),
        # Rescued episodes the human ended himself after the robot pointed: the point (not a
        # fetch) turned a failure alone into his own success.
        "rescued_by_pointing": sum(r.outcome == "rescued" and r.succeeded_by == "human"
                                   and r.points > 0 for r in group),
        "warnings_after_help": sum(r.warnings_after_help for r in group),
        "warnings_after_help_episodes": sum(r.warnings_after_help > 0 for r in group),
    }
    for prefix, column in _MEAN_CI_QUANTITIES:
        mean, low, high = mean_ci([getattr(r, column) for r in group], confidence)
        entry.update({f"{prefix}_mean": mean, f"{prefix}_low": low, f"{prefix}_high": high})
    # The rate per observation, pooled: every step's observation is one chance to disagree.
    zero = sum(r.zero_probability_observations for r in group)
    seen = sum(r.steps for r in group)
    entry.update({"zero_probability_observations": zero, "observations": seen,
                  "zero_probability_rate": zero / seen if seen else math.nan})
    timed = [r.mean_decision_ms for r in group if not math.isnan(r.mean_decision_ms)]
    entry["mean_decision_ms"] = math.fsum(timed) / len(timed) if timed else math.nan
    return entry


def _comparisons(entry: Dict[str, Any], group: Sequence[EpisodeRow],
                 reactive: Optional[str], reactive_rows: Sequence[EpisodeRow]) -> None:
    policy = entry["robot_policy"]
    entry["best_reactive"] = reactive or ""
    versus_reactive = empty_comparison()
    if reactive is not None and policy not in (reactive, ALONE_POLICY):
        versus_reactive = compare(group, reactive_rows, reactive)
    versus_alone = empty_comparison() if policy == ALONE_POLICY else compare_with_alone(group)
    entry.update({f"vs_reactive_{k}": v for k, v in versus_reactive.items()})
    entry.update({f"vs_alone_{k}": v for k, v in versus_alone.items()})


def summarize(rows: Iterable[Union[EpisodeRow, Mapping[str, Any]]],
              confidence: float = 0.95) -> List[Dict[str, Any]]:
    """One dict (keys :data:`SUMMARY_COLUMNS`) per (human_model, robot_policy), in order of
    first appearance, then, with two human models or more, one per robot policy pooled over
    every human's held-out streams (human model :data:`POOLED`; rows with in_sample 0).

    Each compares the policy on the same streams with the best reactive budget
    (:func:`best_reactive`: per human model; over all humans for the pooled entries) and with
    the human alone (:func:`compare`, :func:`compare_with_alone`). ``mean_decision_ms`` is the
    mean of the episodes' means over the episodes that have one (NaN if none): a plain number,
    no interval, since it measures the machine, not the policy. Rows may be EpisodeRows or
    dicts as :meth:`EpisodeRow.from_dict` takes them.
    """
    _check_confidence(confidence)
    groups: Dict[Tuple[str, str], List[EpisodeRow]] = {}
    for row in rows:
        if not isinstance(row, EpisodeRow):
            row = EpisodeRow.from_dict(row)
        groups.setdefault((row.human_model, row.robot_policy), []).append(row)
    humans = list(dict.fromkeys(h for h, _ in groups))
    policies = list(dict.fromkeys(p for _, p in groups))
    best = {human: best_reactive(r for (h, _), group in groups.items() if h == human
                                 for r in group) for human in humans}
    summary = []
    for (human, policy), group in groups.items():
        reactive = best[human]
        entry = _entry(human, policy, group, confidence)
        _comparisons(entry, group, reactive, groups.get((human, reactive), []) if reactive
                     else [])
        summary.append(entry)
    if len(humans) > 1:
        held_out = {policy: [r for (h, p), group in groups.items() if p == policy
                             for r in group if not r.in_sample] for policy in policies}
        reactive = best_reactive(r for group in held_out.values() for r in group)
        for policy in policies:
            if held_out[policy]:
                entry = _entry(POOLED, policy, held_out[policy], confidence)
                _comparisons(entry, held_out[policy], reactive,
                             held_out.get(reactive, []) if reactive else [])
                summary.append(entry)
    adjust_for_many_tests(summary)
    return summary


def adjust_for_many_tests(summary: Sequence[Dict[str, Any]],
                          prefixes: Sequence[str] = ("vs_reactive", "vs_alone"),
                          tests: Sequence[str] = TESTS) -> None:
    """Set each comparison's q-values (``*_q``): its p-values adjusted for the number of tests
    a summary makes, by Benjamini and Hochberg's false discovery rate
    (``scipy.stats.false_discovery_control``). A family is one test against one baseline
    (e.g. McNemar's test of success against the best reactive budget) over every row of the
    summary, per human and pooled; a q-value below 0.05 keeps the expected share of false
    discoveries among such claims below 5 %. Rows without the test get NaN. ``prefixes`` and
    ``tests`` name the families (``<prefix>_<test>_p``; a sequence study's are its own)."""
    for prefix in prefixes:
        for test in tests:
            tested = [e for e in summary if math.isfinite(e.get(f"{prefix}_{test}_p", math.nan))]
            for e in summary:
                e[f"{prefix}_{test}_q"] = math.nan
            if tested:
                from scipy import stats   # on first use, as in mean_ci
                q = stats.false_discovery_control([e[f"{prefix}_{test}_p"] for e in tested],
                                                  method="bh")
                for e, value in zip(tested, q):
                    e[f"{prefix}_{test}_q"] = float(value)


def format_ci(mean: float, low: float, high: float, digits: int = 2) -> str:
    """``"0.85 [0.71, 0.93]"``; ``"3.00 [n/a]"`` without an interval; ``"n/a"`` without a mean."""
    if math.isnan(mean):
        return "n/a"
    if math.isnan(low) or math.isnan(high):
        return f"{mean:.{digits}f} [n/a]"
    return f"{mean:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


def format_p(p: float) -> str:
    """A p-value as a table shows it: ``0.031``, ``<0.001``, ``n/a``."""
    if math.isnan(p):
        return "n/a"
    return "<0.001" if p < 0.001 else f"{p:.3f}"


def _number(value: float, digits: int = 2, signed: bool = False) -> str:
    if math.isnan(value):
        return "n/a"
    return f"{value:+.{digits}f}" if signed else f"{value:.{digits}f}"


def _rate_text(count: int, total: int) -> str:
    """``"3 / 120 (2.5 %)"``."""
    return f"{count} / {total} ({100.0 * count / total:.1f} %)" if total else "n/a"


def _markdown_cell(text: str) -> str:
    return text.replace("|", "\\|")  # a pipe in a name would split the cell


def markdown_table(headers: Sequence[str], rows: Iterable[Sequence[str]],
                   text_columns: int = 2) -> str:
    """A Markdown table (tabulate's ``pipe`` format): the first ``text_columns`` columns
    left-aligned, the others right; cells as given (already formatted: no number parsing)."""
    return _table(headers, rows, text_columns, "pipe")


def _table(headers: Sequence[str], rows: Iterable[Sequence[str]], text_columns: int,
           style: str) -> str:
    from tabulate import tabulate   # on first use: the summary's only user

    align = ["left"] * text_columns + ["right"] * (len(headers) - text_columns)
    return tabulate([list(cells) for cells in rows], headers=list(headers), tablefmt=style,
                    colalign=align, disable_numparse=True)


def _names(e: Mapping[str, Any]) -> List[str]:
    return [_markdown_cell(str(e["human_model"])), _markdown_cell(str(e["robot_policy"]))]


def markdown(summary: Sequence[Mapping[str, Any]]) -> str:
    """The summary as Markdown: outcomes against the human alone, the paired comparisons, the
    best reactive budget, the other measures, and what each column means."""
    levels = {entry["confidence"] for entry in summary} or {0.95}
    level = "/".join(f"{100 * c:g} %" for c in sorted(levels))
    outcomes = markdown_table(
        ["Human model", "Robot policy", "n", f"Success [{level} CI]", "Alone",
         "Rescued", "Pre-empted", f"Pre-empted rate [{level} CI]", "Hindered",
         "Both succeed", "Both fail", "Time to success (s, median)",
         "Time gain (s, median, alone − policy; pairs)", "Wasted actions (mean)",
         "Against a warning",
         "Label intrusions (mean)", "In-sample"],
        ([*_names(e), str(e["n"]),
          format_ci(e["success_rate"], e["success_low"], e["success_high"]),
          str(e["alone_successes"]), str(e["rescued"]), str(e["pre_empted"]),
          format_ci(e["pre_empted_rate"], e["pre_empted_low"], e["pre_empted_high"]),
          str(e["hindered"]), str(e["both_succeed"]), str(e["both_fail"]),
          _number(e["time_to_success_median"]),
          f"{_number(e['time_gain_median'], signed=True)} ({e['time_gain_pairs']})",
          _number(e["wasted_actions_mean"]),
          f"{e['against_warning']} in {e['against_warning_episodes']} ep.",
          _number(e["intrusive_actions_mean"]), str(e["in_sample"])] for e in summary))
    comparisons = []
    for e in summary:
        for prefix in ("vs_reactive", "vs_alone"):
            if not e[f"{prefix}_policy"]:
                continue
            comparisons.append(
                [*_names(e), _markdown_cell(str(e[f"{prefix}_policy"])),
                 str(e[f"{prefix}_pairs"]),
                 _number(e[f"{prefix}_success_diff"], signed=True),
                 format_p(e[f"{prefix}_success_p"]), format_p(e[f"{prefix}_success_q"]),
                 _number(e[f"{prefix}_pre_empted_diff"], signed=True),
                 format_p(e[f"{prefix}_pre_empted_p"]), format_p(e[f"{prefix}_pre_empted_q"]),
                 _number(e[f"{prefix}_own_success_diff"], signed=True),
                 format_p(e[f"{prefix}_own_success_p"]), format_p(e[f"{prefix}_own_success_q"]),
                 str(e[f"{prefix}_time_pairs"]),
                 _number(e[f"{prefix}_time_gain_median"], signed=True),
                 format_p(e[f"{prefix}_time_p"]), format_p(e[f"{prefix}_time_q"])])
    compared = markdown_table(["Human model", "Robot policy", "Against", "Pairs", "Δ success",
                       "p (McNemar)", "q", "Δ pre-empted", "p (McNemar)", "q",
                       "Δ own success", "p (McNemar)", "q", "Pairs both succeed",
                       "Time gain (s, median, other − policy)", "p (Wilcoxon)",
                       "q"], comparisons, 3)
    best = {}
    for e in summary:
        if e["best_reactive"]:
            best.setdefault(e["human_model"], e["best_reactive"])
    by_key = {(e["human_model"], e["robot_policy"]): e for e in summary}
    best_rows = []
    for human, name in best.items():
        e = by_key.get((human, name))
        if e is not None:
            best_rows.append([_markdown_cell(str(human)), _markdown_cell(name),
                              format_ci(e["success_rate"], e["success_low"], e["success_high"]),
                              str(e["pre_empted"]), _number(e["time_to_success_median"])])
    best_table = markdown_table(["Human model", "Best reactive", "Success", "Pre-empted",
                         "Time to success (s, median)"], best_rows)
    others = markdown_table(
        ["Human model", "Robot policy", "Steps", "Sim time (s)", "Discounted reward",
         "Warnings", "Warnings after help", "Rescued after a point",
         "Zero-probability observations", "Decision time (ms)"],
        ([*_names(e), format_ci(e["steps_mean"], e["steps_low"], e["steps_high"], 1),
          format_ci(e["sim_seconds_mean"], e["sim_seconds_low"], e["sim_seconds_high"]),
          format_ci(e["reward_mean"], e["reward_low"], e["reward_high"]),
          format_ci(e["warnings_mean"], e["warnings_low"], e["warnings_high"]),
          f"{e['warnings_after_help']} in {e['warnings_after_help_episodes']} ep.",
          str(e["rescued_by_pointing"]),
          _rate_text(e["zero_probability_observations"], e["observations"]),
          _number(e["mean_decision_ms"], 1)] for e in summary))
    return "\n".join([
        TIME_GAIN, "", "## Outcomes against the human alone", "", outcomes, "",
        f"n episodes per row, each on its own streams. Success and the pre-empted rate: Wilson "
        f"score intervals ({level}). Alone: how many of the same (human model, seed, episode) "
        "streams the human succeeded on with `no_robot`. Rescued: failed alone, succeeded with "
        "the robot; pre-empted: would have succeeded alone, the robot took the object; "
        "hindered: succeeded alone, failed with the robot. Time to success: simulated seconds "
        "from the episode's start, over the episodes that succeeded; time gain: alone minus "
        "with the robot, over the pairs where both succeeded (positive: the robot made it "
        "sooner; the sign of every time in this summary). Wasted actions: grasps that did not get the object and points at a human "
        "away from the belt. Against a warning: grasps and points while a warning was in "
        "force, and in how many episodes. Label intrusions: the old count, a grasp or point "
        "while the observer's label said no help was needed. In-sample: rows on streams the "
        f"robot's model was fitted on. {POOLED}: every human's streams held out from the fit.",
        "", "## Paired comparisons (same streams)", "", compared, "",
        "Each robot policy against the best reactive budget for that human (for the pool: the "
        "best over all humans) and against the human alone, on the streams both ran. Δ: the "
        "policy's minus the other's (proportions of the pairs). Time gain: the median of the "
        "other's time minus the policy's over the pairs where both succeeded (positive: the "
        "policy succeeded sooner; the outcomes table's sign). p: McNemar's exact "
        "test (two-sided) for success, for pre-emption and for the human's own success (he, "
        "not the robot, got the object), Wilcoxon's signed-rank test "
        "(two-sided) for the time to success over the pairs where both succeeded. q: the "
        "p-value adjusted for the many tests of this summary (Benjamini-Hochberg false "
        "discovery rate over every row's same test against the same kind of baseline).",
        "", "## Best reactive budget", "", best_table, "",
        "Best: the highest success rate, then the lowest pre-emption rate, then the shortest "
        "median time to success, then the smallest budget.",
        "", "## Other measures", "", others, "",
        f"Mean [{level} confidence interval, bootstrap percentile] over episodes; [n/a] where an "
        "interval needs two episodes or more. Warnings after help: warnings given on the step "
        "right after the robot's grasp or point, and in how many episodes. Rescued after a "
        "point: rescued episodes the human ended himself after the robot pointed. "
        "Zero-probability observations: how many of the "
        "episodes' observations the robot's model gave probability 0, of all, and the rate.",
        ""])


def terminal_table(headers: Sequence[str], rows: Iterable[Sequence[str]],
                   text_columns: int = 2) -> str:
    """A table for the terminal (tabulate's ``simple`` format), aligned as
    :func:`markdown_table`."""
    return _table(headers, rows, text_columns, "simple")


def headline(summary: Sequence[Mapping[str, Any]]) -> str:
    """What the terminal shows of a summary: per human model and robot policy, the episodes,
    the success rate and its interval, the human alone's successes and the time gain; the rest
    is in the summary's files."""
    levels = {entry["confidence"] for entry in summary} or {0.95}
    level = "/".join(f"{100 * c:g} %" for c in sorted(levels))
    return terminal_table(
        ["Human model", "Robot policy", "n", f"Success [{level} CI]", "Alone",
         "Time gain (s, median)"],
        [[str(e["human_model"]), str(e["robot_policy"]), str(e["n"]),
          format_ci(e["success_rate"], e["success_low"], e["success_high"]),
          str(e["alone_successes"]), _number(e["time_gain_median"], signed=True)]
         for e in summary])


def write_summary(summary: Sequence[Mapping[str, Any]], csv_path: Union[str, os.PathLike],
                  markdown_path: Union[str, os.PathLike]) -> Tuple[str, str]:
    """Write the :func:`summarize` output as a CSV (every number, full precision) and as
    Markdown tables (:func:`markdown`); returns both paths."""
    return write_summary_files(summary, SUMMARY_COLUMNS, markdown(summary), csv_path,
                               markdown_path)


def write_summary_files(summary: Sequence[Mapping[str, Any]], columns: Sequence[str],
                        markdown_text: str, csv_path: Union[str, os.PathLike],
                        markdown_path: Union[str, os.PathLike]) -> Tuple[str, str]:
    """A summary's ``columns`` as CSV (floats at full precision) and its Markdown text, each
    file written whole; returns both paths."""
    csv_path, markdown_path = os.fspath(csv_path), os.fspath(markdown_path)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for entry in summary:
        writer.writerow(repr(v) if isinstance(v, float) else str(v)
                        for v in (entry[c] for c in columns))
    # Each file whole or not at all: a full disk leaves the previous summary, never half of one.
    ensure_parent(csv_path)
    write_text_atomically(csv_path, buffer.getvalue())
    ensure_parent(markdown_path)
    write_text_atomically(markdown_path, markdown_text)
    return csv_path, markdown_path
