"""The statistics of an experiment: confidence intervals, the summary and its tables.

Plain Python (scipy for the t and normal quantiles, imported on first use), no ROS.

:func:`mean_ci` (Student's t), :func:`proportion_ci` (Wilson score), :func:`summarize` (one
dict per human model x robot policy), :func:`write_summary` (CSV + Markdown table, each written whole or not at all). Every
episode counts as one independent sample: seeds and episodes are not told apart.
"""
from __future__ import annotations

import csv
import io
import math
import operator
import os
from typing import Any, Dict, Iterable, List, Mapping, Sequence, Tuple, Union

from ros_hrc.experiment.store import EpisodeRow, ensure_parent
from ros_hrc.pomdp.output import write_text_atomically

def _check_confidence(confidence: float) -> None:
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")


def mean_ci(values: Iterable[float], confidence: float = 0.95) -> Tuple[float, float, float]:
    """(mean, low, high): the mean and its Student's t confidence interval.

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
    from scipy import stats  # on first use: importing the module stays cheap

    sd = math.sqrt(math.fsum((x - mean) ** 2 for x in xs) / (n - 1))
    half = float(stats.t.ppf((1 + confidence) / 2, n - 1)) * sd / math.sqrt(n)
    return (mean, mean - half, mean + half)


def proportion_ci(successes: int, n: int, confidence: float = 0.95) -> Tuple[float, float, float]:
    """(p, low, high): the success proportion and its Wilson score interval.

    Wilson rather than the normal approximation: it stays inside [0, 1] and keeps a sensible
    width at 0/n and n/n, which small experiments hit often. n = 0 gives (nan, nan, nan).
    """
    _check_confidence(confidence)
    successes, n = operator.index(successes), operator.index(n)
    if n < 0 or not 0 <= successes <= max(n, 0):
        raise ValueError(f"proportion_ci: need 0 <= successes <= n, got {successes}/{n}")
    if n == 0:
        return (math.nan, math.nan, math.nan)
    from scipy import stats

    z = float(stats.norm.ppf((1 + confidence) / 2))
    p = successes / n
    z2n = z * z / n
    centre = (p + z2n / 2) / (1 + z2n)
    half = z * math.sqrt(p * (1 - p) / n + z2n / (4 * n)) / (1 + z2n)
    # At 0/n and n/n the outer end is exactly 0 or 1; rounding would miss it by a hair.
    low = 0.0 if successes == 0 else centre - half
    high = 1.0 if successes == n else centre + half
    return (p, low, high)


#: Keys of each :func:`summarize` dict, in the summary CSV's column order.
SUMMARY_COLUMNS: Tuple[str, ...] = (
    "human_model", "robot_policy", "n", "confidence",
    "successes", "success_rate", "success_low", "success_high",
    "human_successes", "robot_successes", "object_left_belt", "step_limit",
    "steps_mean", "steps_low", "steps_high",
    "sim_seconds_mean", "sim_seconds_low", "sim_seconds_high",
    "reward_mean", "reward_low", "reward_high",
    "intrusive_actions_mean", "intrusive_actions_low", "intrusive_actions_high",
    "warnings_mean", "warnings_low", "warnings_high",
    "zero_probability_observations", "observations", "zero_probability_rate",
    "mean_decision_ms")

# summary prefix -> EpisodeRow column, for the quantities given as mean + t interval
_MEAN_CI_QUANTITIES: Tuple[Tuple[str, str], ...] = (
    ("steps", "steps"), ("sim_seconds", "sim_seconds"), ("reward", "robot_discounted_reward"),
    ("intrusive_actions", "intrusive_actions"), ("warnings", "warnings"))


def summarize(rows: Iterable[Union[EpisodeRow, Mapping[str, Any]]],
              confidence: float = 0.95) -> List[Dict[str, Any]]:
    """One dict (keys :data:`SUMMARY_COLUMNS`) per (human_model, robot_policy), in order of
    first appearance.

    ``mean_decision_ms`` is the mean of the episodes' means over the episodes that have one
    (NaN if none): a plain number, no interval, since it measures the machine, not the policy.
    Rows may be EpisodeRows or dicts as :meth:`EpisodeRow.from_dict` takes them.
    """
    _check_confidence(confidence)
    groups: Dict[Tuple[str, str], List[EpisodeRow]] = {}
    for row in rows:
        if not isinstance(row, EpisodeRow):
            row = EpisodeRow.from_dict(row)
        groups.setdefault((row.human_model, row.robot_policy), []).append(row)
    summary = []
    for (human_model, robot_policy), group in groups.items():
        successes = sum(r.success for r in group)
        p, low, high = proportion_ci(successes, len(group), confidence)
        entry: Dict[str, Any] = {
            "human_model": human_model, "robot_policy": robot_policy, "n": len(group),
            "confidence": confidence, "successes": successes,
            "success_rate": p, "success_low": low, "success_high": high,
            "human_successes": sum(r.succeeded_by == "human" for r in group),
            "robot_successes": sum(r.succeeded_by == "robot" for r in group),
            "object_left_belt": sum(r.end_reason == "object_left_belt" for r in group),
            "step_limit": sum(r.end_reason == "step_limit" for r in group),
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
        summary.append(entry)
    return summary


def format_ci(mean: float, low: float, high: float, digits: int = 2) -> str:
    """``"0.85 [0.71, 0.93]"``; ``"3.00 [n/a]"`` without an interval; ``"n/a"`` without a mean."""
    if math.isnan(mean):
        return "n/a"
    if math.isnan(low) or math.isnan(high):
        return f"{mean:.{digits}f} [n/a]"
    return f"{mean:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


def _rate_text(count: int, total: int) -> str:
    """``"3 / 120 (2.5 %)"``."""
    return f"{count} / {total} ({100.0 * count / total:.1f} %)" if total else "n/a"


def _markdown_cell(text: str) -> str:
    return text.replace("|", "\\|")  # a pipe in a name would split the cell


def write_summary(summary: Sequence[Mapping[str, Any]], csv_path: Union[str, os.PathLike],
                  markdown_path: Union[str, os.PathLike]) -> Tuple[str, str]:
    """Write the :func:`summarize` output as a CSV (every number, full precision) and as a
    Markdown table of means with their intervals; returns both paths."""
    csv_path, markdown_path = os.fspath(csv_path), os.fspath(markdown_path)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(SUMMARY_COLUMNS)
    for entry in summary:
        writer.writerow(repr(v) if isinstance(v, float) else str(v)
                        for v in (entry[c] for c in SUMMARY_COLUMNS))

    levels = {entry["confidence"] for entry in summary} or {0.95}
    level = "/".join(f"{100 * c:g} %" for c in sorted(levels))
    headers = ["Human model", "Robot policy", "n", f"Success rate [{level} CI]",
               "Successes (human / robot)", "Steps", "Sim time (s)", "Discounted reward",
               "Intrusive actions", "Warnings", "Zero-probability observations",
               "Decision time (ms)"]
    lines = ["| " + " | ".join(headers) + " |",
             "|" + "|".join(["---", "---", "--:"] + ["--:"] * (len(headers) - 3)) + "|"]
    for e in summary:
        ms = e["mean_decision_ms"]
        cells = [_markdown_cell(str(e["human_model"])), _markdown_cell(str(e["robot_policy"])),
                 str(e["n"]),
                 format_ci(e["success_rate"], e["success_low"], e["success_high"]),
                 f"{e['human_successes']} / {e['robot_successes']}",
                 format_ci(e["steps_mean"], e["steps_low"], e["steps_high"], 1),
                 format_ci(e["sim_seconds_mean"], e["sim_seconds_low"], e["sim_seconds_high"]),
                 format_ci(e["reward_mean"], e["reward_low"], e["reward_high"]),
                 format_ci(e["intrusive_actions_mean"], e["intrusive_actions_low"],
                           e["intrusive_actions_high"]),
                 format_ci(e["warnings_mean"], e["warnings_low"], e["warnings_high"]),
                 _rate_text(e["zero_probability_observations"], e["observations"]),
                 "n/a" if math.isnan(ms) else f"{ms:.1f}"]
        lines.append("| " + " | ".join(cells) + " |")
    note = (f"Mean [{level} confidence interval] over episodes: Wilson score interval for the "
            "success rate, Student's t for the other quantities; [n/a] where an interval "
            "needs two episodes or more. Zero-probability observations: how many of the "
            "episodes' observations the robot's model gave probability 0, of all, and the rate.")
    # Each file whole or not at all: a full disk leaves the previous summary, never half of one.
    ensure_parent(csv_path)
    write_text_atomically(csv_path, buffer.getvalue())
    ensure_parent(markdown_path)
    write_text_atomically(markdown_path, "\n".join(lines) + "\n\n" + note + "\n")
    return csv_path, markdown_path
