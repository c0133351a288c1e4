"""The statistics of a sequence study: learning curves, identification, the best fixed policy
in hindsight and the paired tests, from ``tasks.csv``'s rows. No ROS.

Every (seed, sequence, task) is its own human stream (:mod:`ros_hrc.experiment.sequences`),
the same under every selector, so two selectors' tasks come in pairs, keyed by (schedule,
seed, episode, task_index), and the tests are the paired ones of
:mod:`ros_hrc.experiment.paired`: Wilcoxon's signed-rank test of the utility (it is
continuous, bounded and far from normal: a success is worth about 1 and a failure about
-0.5, so the differences are bimodal, which a t-test would assume away) and McNemar's exact
test of success. The q-values are the study's (:func:`statistics.adjust_for_many_tests`,
Benjamini and Hochberg, one family per test and baseline).

- :func:`learning_curve`: per (schedule, selector, task index), the success rate (Wilson)
  and the mean utility (bootstrap percentile interval) over the sequences;
- :func:`identification`: per block of a sequence (the tasks of one type, a switch starting
  the next), after how many tasks the selector's most likely type became the block's type
  and stayed it to the block's end (NaN: not by its end);
- :func:`best_fixed`: per schedule, the ``fixed:<policy>`` with the highest mean utility
  (in hindsight: it is chosen on the same tasks it is compared on, which favours it);
- :func:`summarize_sequences`: one entry per (schedule, selector), with the above and the
  paired tests against the best fixed policy and the oracle; per-type schedules are also
  pooled (``per-type (pooled)``), with the best fixed policy over all types.
"""
from __future__ import annotations

import math
import os
from collections import defaultdict
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

from ros_hrc.experiment import paired
from ros_hrc.experiment.sequence_rows import TaskRow
from ros_hrc.experiment.statistics import (adjust_for_many_tests, format_ci, format_p,
                                           markdown_table, mean_ci, median, proportion_ci,
                                           terminal_table,
                                           write_summary_files)
from ros_hrc.tasks.schedule import type_name

#: The baselines every selector is set against (summary prefixes): the best fixed policy in
#: hindsight, the oracle, and the authors' own policy (the library's first, ``base`` for
#: fabric): "better than the authors' base" is not "better than the best fixed policy".
BASELINES: Tuple[str, ...] = ("vs_best_fixed", "vs_oracle", "vs_base")
#: The paired tests against each.
SEQUENCE_TESTS: Tuple[str, ...] = ("utility", "success")
#: The schedule of the entries pooled over every per-type schedule.
POOLED_TYPES = "per-type (pooled)"
ORACLE = "oracle"
FIXED_PREFIX = "fixed:"

PairKey = Tuple[str, int, int, int]


def pair_key(row: TaskRow) -> PairKey:
    """(schedule, seed, episode, task_index): the human stream a task played."""
    return (row.schedule, row.seed, row.episode, row.task_index)


def _groups(rows: Iterable[TaskRow], *names: str) -> Dict[tuple, List[TaskRow]]:
    out: Dict[tuple, List[TaskRow]] = defaultdict(list)
    for row in rows:
        out[tuple(getattr(row, n) for n in names)].append(row)
    return dict(out)


def learning_curve(rows: Iterable[TaskRow], confidence: float = 0.95) -> List[Dict[str, Any]]:
    """Per (schedule, selector, task_index): ``n`` sequences, ``success`` with its Wilson
    interval (``success_low``, ``success_high``) and ``utility`` with its bootstrap interval."""
    out = []
    for (schedule, selector, index), group in sorted(
            _groups(rows, "schedule", "selector", "task_index").items()):
        p, low, high = proportion_ci(sum(r.success for r in group), len(group), confidence)
        u, ulow, uhigh = mean_ci([r.utility for r in group], confidence)
        out.append({"schedule": schedule, "selector": selector, "task_index": index,
                    "n": len(group), "success": p, "success_low": low, "success_high": high,
                    "utility": u, "utility_low": ulow, "utility_high": uhigh})
    return out


def identification(rows: Iterable[TaskRow]) -> List[Dict[str, Any]]:
    """Per block of each sequence of a selector with a type belief: (schedule, selector,
    seed, episode, ``block`` (its number from 1), ``true_type``, ``first_task``, ``tasks``
    (its length), ``tasks_to_identify``): the tasks from the block's start until the
    belief's most likely type is the block's type and stays it to the block's end (1: from
    its first task on); NaN when the last task of the block still names another type."""
    out = []
    for key, group in sorted(_groups(rows, "schedule", "selector", "seed", "episode").items()):
        group = sorted(group, key=lambda r: r.task_index)
        if not any(r.types for r in group):
            continue            # a selector without a type belief identifies nothing
        blocks: List[List[TaskRow]] = []
        for row in group:
            if blocks and blocks[-1][-1].block_type == row.block_type:
                blocks[-1].append(row)
            else:
                blocks.append([row])
        for number, block in enumerate(blocks, start=1):
            kept = 0            # the tasks at the block's end whose argmax is its type
            for row in reversed(block):
                if row.belief_argmax != row.block_type:
                    break
                kept += 1
            found = len(block) - kept + 1 if kept else math.nan
            out.append(dict(zip(("schedule", "selector", "seed", "episode"), key),
                            block=number, true_type=block[0].block_type,
                            first_task=block[0].task_index, tasks=len(block),
                            tasks_to_identify=found))
    return out


def best_fixed(rows: Iterable[TaskRow]) -> Optional[str]:
    """The ``fixed:<policy>`` selector of ``rows`` with the highest mean utility, then the
    highest success rate, then the first by name; None without fixed selectors."""
    groups = {sel: g for (sel,), g in _groups(rows, "selector").items()
              if sel.startswith(FIXED_PREFIX)}
    if not groups:
        return None
    def rank(item: Tuple[str, List[TaskRow]]) -> tuple:
        name, group = item
        return (-sum(r.utility for r in group) / len(group),
                -sum(r.success for r in group) / len(group), name)
    return min(groups.items(), key=rank)[0]


def paired_tests(rows: Sequence[TaskRow], baseline_rows: Sequence[TaskRow],
                 prefix: str) -> Dict[str, Any]:
    """The paired tests of ``rows`` against ``baseline_rows`` on the tasks both played (same
    schedule, seed, episode, task): ``<prefix>_pairs``, ``<prefix>_utility_diff`` (the median
    paired difference, the selector's minus the baseline's) and ``_p`` (Wilcoxon),
    ``<prefix>_utility_mean_diff`` (the mean paired difference: what a task gains on
    average), ``<prefix>_success_diff`` (the difference in success rate) and ``_p``
    (McNemar exact)."""
    theirs = {pair_key(r): r for r in baseline_rows}
    pairs = [(theirs[pair_key(r)], r) for r in rows if pair_key(r) in theirs]
    out: Dict[str, Any] = {f"{prefix}_pairs": len(pairs)}
    if not pairs:
        for test in SEQUENCE_TESTS:
            out[f"{prefix}_{test}_diff"] = out[f"{prefix}_{test}_p"] = math.nan
        out[f"{prefix}_utility_mean_diff"] = math.nan
        return out
    wilcoxon = paired.wilcoxon_paired([b.utility for b, _ in pairs],
                                      [r.utility for _, r in pairs])
    mcnemar = paired.mcnemar_exact([bool(b.success) for b, _ in pairs],
                                   [bool(r.success) for _, r in pairs])
    out.update({f"{prefix}_utility_diff": wilcoxon.median_difference,
                f"{prefix}_utility_mean_diff": float(sum(r.utility - b.utility
                                                         for b, r in pairs) / len(pairs)),
                f"{prefix}_utility_p": wilcoxon.p_value,
                f"{prefix}_success_diff": mcnemar.difference,
                f"{prefix}_success_p": mcnemar.p_value})
    return out


def per_type_schedules(rows: Iterable[TaskRow]) -> List[str]:
    """The schedules that are one type throughout (``--schedule per-type``'s cells: every
    task's true type is the schedule's name, or for a human given as a file, such as
    ``hrc_perturb_humans``' ``DIR/<type>.pomdpx``, the file's stem)."""
    by_schedule = _groups(rows, "schedule")
    return sorted(s for (s,), group in by_schedule.items()
                  if all(r.true_type == type_name(s) for r in group))


def _entry(schedule: str, selector: str, group: Sequence[TaskRow],
           blocks: Sequence[Mapping[str, Any]], confidence: float) -> Dict[str, Any]:
    p, low, high = proportion_ci(sum(r.success for r in group), len(group), confidence)
    entry: Dict[str, Any] = {
        "schedule": schedule, "selector": selector, "tasks": len(group),
        "sequences": len({(r.seed, r.episode, r.schedule) for r in group}),
        "success": p, "success_low": low, "success_high": high}
    for name in ("utility", "warnings", "preemptions", "duration"):
        mean, mlow, mhigh = mean_ci([float(getattr(r, name)) for r in group], confidence)
        entry.update({name: mean, f"{name}_low": mlow, f"{name}_high": mhigh})
    found = [b["tasks_to_identify"] for b in blocks]
    entry.update({"blocks": len(found),
                  "identified": sum(1 for f in found if math.isfinite(f)),
                  "tasks_to_identify_median": median(found)})
    return entry


#: The summary's columns, in order (summary.csv).
SEQUENCE_SUMMARY_COLUMNS: Tuple[str, ...] = (
    "schedule", "selector", "tasks", "sequences", "success", "success_low", "success_high",
    "utility", "utility_low", "utility_high", "warnings", "warnings_low", "warnings_high",
    "preemptions", "preemptions_low", "preemptions_high", "duration", "duration_low",
    "duration_high", "blocks", "identified", "tasks_to_identify_median", "best_fixed",
    "base") + tuple(
    f"{b}_{c}" for b in BASELINES for c in ("pairs", "utility_mean_diff", "utility_diff",
                                             "utility_p", "utility_q", "success_diff",
                                             "success_p", "success_q"))


def summarize_sequences(rows: Iterable[Union[TaskRow, Mapping[str, Any]]],
                        confidence: float = 0.95,
                        base: Optional[str] = None) -> List[Dict[str, Any]]:
    """One entry per (schedule, selector), then per selector pooled over the per-type
    schedules (:data:`POOLED_TYPES`): tasks, sequences, success (Wilson), utility, warnings,
    pre-emptions and duration per task (bootstrap percentile), the blocks identified and the median
    tasks to identify, the best fixed policy of the schedule (in hindsight) and the paired
    tests against it, against the oracle and against ``base`` (the authors' own policy as a
    selector, ``fixed:base``), with their q-values."""
    rows = [r if isinstance(r, TaskRow) else TaskRow.from_dict(r) for r in rows]
    blocks = _groups_of_dicts(identification(rows))
    scopes: List[Tuple[str, List[TaskRow]]] = [
        (schedule, group) for (schedule,), group in sorted(_groups(rows, "schedule").items())]
    types = per_type_schedules(rows)
    if len(types) > 1:
        scopes.append((POOLED_TYPES, [r for r in rows if r.schedule in types]))
    summary = []
    for schedule, scope in scopes:
        by_selector = {sel: g for (sel,), g in _groups(scope, "selector").items()}
        best = best_fixed(scope)
        for selector in sorted(by_selector, key=_selector_order):
            group = by_selector[selector]
            names = types if schedule == POOLED_TYPES else [schedule]
            entry = _entry(schedule, selector, group,
                           [b for s in names for b in blocks.get((s, selector), [])],
                           confidence)
            entry["best_fixed"] = best or ""
            entry["base"] = base or ""
            for prefix, baseline in (("vs_best_fixed", best), ("vs_oracle", ORACLE),
                                     ("vs_base", base)):
                if baseline is None or baseline == selector or baseline not in by_selector:
                    entry.update(paired_tests(group, [], prefix))
                else:
                    entry.update(paired_tests(group, by_selector[baseline], prefix))
            summary.append(entry)
    adjust_for_many_tests(summary, BASELINES, SEQUENCE_TESTS)
    return summary


def _groups_of_dicts(blocks: Iterable[Mapping[str, Any]]) -> Dict[tuple, List[Mapping]]:
    out: Dict[tuple, List[Mapping]] = defaultdict(list)
    for b in blocks:
        out[(b["schedule"], b["selector"])].append(b)
    return out


def _selector_order(name: str) -> tuple:
    """The adaptive selectors first, then the oracle, then the fixed policies."""
    return (name.startswith(FIXED_PREFIX), name == ORACLE, name)


def sequence_headline(summary: Sequence[Mapping[str, Any]]) -> str:
    """What the terminal shows of a sequence summary: per schedule and selector, the tasks,
    the success rate and the utility per task with their intervals."""
    return terminal_table(
        ["Schedule", "Selector", "Tasks", "Success", "Utility"],
        [[e["schedule"], e["selector"], str(e["tasks"]),
          format_ci(e["success"], e["success_low"], e["success_high"]),
          format_ci(e["utility"], e["utility_low"], e["utility_high"])] for e in summary])


def sequence_markdown(summary: Sequence[Mapping[str, Any]], confidence: float = 0.95) -> str:
    """The summary as Markdown tables: outcomes per task, identification, paired tests."""
    outcomes = markdown_table(
        ["Schedule", "Selector", "Tasks", "Success", "Utility", "Warnings", "Pre-emptions",
         "Duration (s)"],
        [[e["schedule"], e["selector"], str(e["tasks"]),
          format_ci(e["success"], e["success_low"], e["success_high"]),
          format_ci(e["utility"], e["utility_low"], e["utility_high"]),
          format_ci(e["warnings"], e["warnings_low"], e["warnings_high"]),
          format_ci(e["preemptions"], e["preemptions_low"], e["preemptions_high"]),
          format_ci(e["duration"], e["duration_low"], e["duration_high"], 1)]
         for e in summary])
    believing = [e for e in summary if e["blocks"]]
    identified = markdown_table(
        ["Schedule", "Selector", "Blocks", "Identified", "Median tasks to identify"],
        [[e["schedule"], e["selector"], str(e["blocks"]), str(e["identified"]),
          "n/a" if math.isnan(e["tasks_to_identify_median"])
          else f"{e['tasks_to_identify_median']:g}"]
         for e in believing]) if believing else \
        "No selector of this study holds a belief over the human's type."
    compared = markdown_table(
        ["Schedule", "Selector", "Against", "Pairs", "Δ utility (mean)", "Δ utility (median)",
         "p", "q", "Δ success", "p", "q"],
        [[e["schedule"], e["selector"], _against(e, prefix),
          str(e[f"{prefix}_pairs"]), _signed(e[f"{prefix}_utility_mean_diff"]),
          _signed(e[f"{prefix}_utility_diff"]),
          format_p(e[f"{prefix}_utility_p"]), format_p(e[f"{prefix}_utility_q"]),
          _signed(e[f"{prefix}_success_diff"]), format_p(e[f"{prefix}_success_p"]),
          format_p(e[f"{prefix}_success_q"])]
         for e in summary for prefix in BASELINES if e[f"{prefix}_pairs"]], text_columns=3)
    level = f"{100 * confidence:g} %"
    return "\n".join([
        "# Sequence study summary", "",
        "## Per task", "", outcomes, "",
        f"Success: rate [{level} Wilson interval]; utility, warnings, pre-emptions and "
        f"duration (simulated s): mean per task [{level} bootstrap percentile interval]. The utility "
        "is the one of every policy (docs/sequences.md). `per-type (pooled)`: every per-type "
        "schedule together.", "",
        "## Identifying the human", "", identified, "",
        "A block is a run of tasks of one type (a switch starts the next). Identified: blocks "
        "whose selector's most likely type became the block's type and stayed it to the "
        "block's end; the median counts the tasks from the block's start to that point (1: "
        "from its first task), over the identified blocks.", "",
        "## Paired tests", "", compared, "",
        "Pairs: the same (schedule, seed, sequence, task), hence the same human stream. "
        "Δ utility: the mean and the median paired difference, this selector's minus the "
        "other's (Wilcoxon's signed-rank test); Δ success: the difference in success rate "
        "(McNemar's exact test). q: Benjamini-Hochberg over the summary's rows, one family "
        "per test and baseline. The best fixed policy is chosen in hindsight on these same "
        "tasks, which favours it.", ""])


def _against(entry: Mapping[str, Any], prefix: str) -> str:
    if prefix == "vs_best_fixed":
        return entry["best_fixed"] + " (best fixed)"
    if prefix == "vs_base":
        return entry["base"] + " (the authors')"
    return ORACLE


def _signed(value: float) -> str:
    return "n/a" if math.isnan(value) else f"{value:+.2f}"


def write_sequence_summary(summary: Sequence[Mapping[str, Any]],
                           csv_path: Union[str, os.PathLike],
                           markdown_path: Union[str, os.PathLike]) -> Tuple[str, str]:
    """The summary as CSV (every number) and Markdown, each written whole or not at all."""
    return write_summary_files(summary, SEQUENCE_SUMMARY_COLUMNS, sequence_markdown(summary),
                               csv_path, markdown_path)
