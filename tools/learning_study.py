#!/usr/bin/env python3
"""The learning robot's study tables, curves and posterior-vs-this-human plots (issue #40;
docs/study/learning.md).

Reads the tasks of one or more finished ``hrc_experiment --sequence`` runs (their
``tasks.csv``), each holding some of the selectors on the same human streams: the learning
robot (``pomdp_learning``, ``pomdp_learning_mean``), its prior never learnt
(``pomdp_pooled``), the ceiling (``pomdp_ceiling``), every library policy (``fixed:*``) and
the other adaptive robots (``bpr``, ``pomdp_types``, ...). Per human (per-type schedule),
over tasks ``--from`` to the end (10..30 by default, the issue's window):

- success, pre-emptions and mean utility per task of each selector;
- the best fixed policy in hindsight (``sequence_statistics.best_fixed``: the library policy
  of the highest mean utility on these very tasks, which favours it);
- the learning robot against it and against each other robot, paired task by task on the
  same streams: McNemar's exact test for success, Wilcoxon's signed-rank test for utility
  and pre-emptions (``ros_hrc.experiment.paired``), q by Benjamini-Hochberg over the table's
  rows, one family per test and baseline (``scipy.stats.false_discovery_control``);
- the share of the gap closed: (learning - best fixed) / (ceiling - best fixed) and
  (learning - pooled) / (ceiling - pooled), of mean utility.

``--plots DIR`` writes ``learning_curves.png`` (mean utility per task index, pooled over the
humans, per selector) and ``learnt_figure.png`` (per human, the learning robot's figure after
each task, mean over sequences with its spread, against the same figure of the ceiling's
model: the human's own, fitted on other seeds of him; ``--ceiling-models DIR``).

    python tools/learning_study.py RUN [RUN ...] [--from 10] [--learner pomdp_learning]
        [--plots docs/img] [--ceiling-models DIR]
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
from collections import defaultdict
from pathlib import Path
from typing import Dict, List, Sequence

import numpy as np
from scipy import stats

from ros_hrc import tasks
from ros_hrc.agents.learning import LearntHuman
from ros_hrc.experiment import paired
from ros_hrc.experiment.sequence_rows import TaskRow
from ros_hrc.experiment.sequence_statistics import best_fixed, pair_key
from ros_hrc.models import load_robot_model
from ros_hrc.tasks.schedule import type_name

POOLED, CEILING = "pomdp_pooled", "pomdp_ceiling"
#: Tasks per point of the learning curves.
BLOCK = 5


def load(runs: Sequence[str]) -> List[TaskRow]:
    rows: List[TaskRow] = []
    for run in runs:
        with open(Path(run) / "tasks.csv", newline="") as f:
            # A run from before the learnt figure was recorded has no such column.
            # A human given as a file (a perturbed one) is named by the file's stem, as its
            # rows' human_model and its ceiling's model (DIR/<stem>.pomdp) are.
            rows += [TaskRow.from_dict({"learnt_figure": "", **d,
                                        "schedule": type_name(d["schedule"])})
                     for d in csv.DictReader(f)]
    return rows


def fmt_p(p: float) -> str:
    """Three decimals; below 0.001, one significant digit (2e-12), so that a claim can quote
    the figure the table gives."""
    return "-" if not math.isfinite(p) else (f"{p:.0e}" if p < 0.001 else f"{p:.3f}")


def compare(mine: Sequence[TaskRow], theirs: Sequence[TaskRow]) -> Dict[str, float]:
    """Paired tests of ``mine`` against ``theirs`` on the streams both played."""
    by_key = {pair_key(r): r for r in theirs}
    pairs = [(by_key[pair_key(r)], r) for r in mine if pair_key(r) in by_key]
    if not pairs:
        return {"pairs": 0, "success_p": math.nan, "utility_p": math.nan,
                "preemptions_p": math.nan, "utility_diff": math.nan}
    mc = paired.mcnemar_exact([bool(b.success) for b, _ in pairs],
                              [bool(r.success) for _, r in pairs])
    wu = paired.wilcoxon_paired([b.utility for b, _ in pairs], [r.utility for _, r in pairs])
    wp = paired.wilcoxon_paired([float(b.preemptions) for b, _ in pairs],
                                [float(r.preemptions) for _, r in pairs])
    return {"pairs": len(pairs), "success_p": mc.p_value, "utility_p": wu.p_value,
            "preemptions_p": wp.p_value,
            "utility_diff": float(np.mean([r.utility - b.utility for b, r in pairs]))}


def q_values(ps: Sequence[float]) -> List[float]:
    """Benjamini-Hochberg over the finite p-values (NaN stays NaN)."""
    finite = [i for i, p in enumerate(ps) if math.isfinite(p)]
    out = [math.nan] * len(ps)
    if finite:
        qs = stats.false_discovery_control([ps[i] for i in finite])
        for i, q in zip(finite, qs):
            out[i] = float(q)
    return out


def summary(group: Sequence[TaskRow]) -> Dict[str, float]:
    n = len(group)
    return {"n": n, "success": sum(r.success for r in group),
            "preemptions": sum(r.preemptions for r in group),
            "against_warning": sum(r.against_warning for r in group),
            "utility": float(np.mean([r.utility for r in group])) if n else math.nan}


def gap_share(learning: float, low: float, high: float) -> str:
    """The share of the gap from ``low`` to ``high`` that ``learning`` closes; none when
    ``high`` is not above ``low`` (the ceiling itself misses: judge against the ceiling)."""
    if not all(map(math.isfinite, (learning, low, high))):
        return "-"
    if high - low <= 0.005:
        return "none: the ceiling is not above it"
    return f"{100 * (learning - low) / (high - low):.0f} %"


def tables(rows: Sequence[TaskRow], first: int, learner: str) -> str:
    rows = [r for r in rows if r.task_index >= first]
    by = defaultdict(list)
    for r in rows:
        by[(r.schedule, r.selector)].append(r)
    humans = sorted({r.schedule for r in rows})
    selectors = sorted({r.selector for r in rows})
    out = [f"Tasks {first}..end of each sequence; success, pre-emptions and actions against "
           f"a warning (a.w.) as counts over the tasks, utility as the mean per task.\n"]
    head = "| human | " + " | ".join(f"`{s}`" for s in selectors) + " |"
    out += [head, "|---|" + "--:|" * len(selectors)]
    for h in humans + ["(pooled)"]:
        cells = []
        for s in selectors:
            group = [r for r in rows if r.selector == s and (h == "(pooled)" or r.schedule == h)]
            if not group:
                cells.append("-")
                continue
            m = summary(group)
            cells.append(f"{m['success']}/{m['n']}, {m['preemptions']} pre., "
                         f"{m['against_warning']} a.w., {m['utility']:.3f}")
        out.append(f"| {h} | " + " | ".join(cells) + " |")
    # The learner against the best fixed policy, per human, and every other robot.
    out.append("")
    out.append(f"`{learner}` against each baseline on the same streams (mean paired utility "
               f"difference; p and q: McNemar for success, Wilcoxon for utility and "
               f"pre-emptions; q by Benjamini-Hochberg over the rows of one baseline):\n")
    baselines = ["best fixed"] + [s for s in selectors if s != learner
                                  and not s.startswith("fixed:")]
    lines, tests = [], defaultdict(list)
    for b in baselines:
        for h in humans + ["(pooled)"]:
            mine = [r for r in rows if r.selector == learner and (h == "(pooled)"
                                                                 or r.schedule == h)]
            if b == "best fixed":
                if h == "(pooled)":
                    # The pool's best fixed: each human's own best, stream by stream.
                    theirs = []
                    for hh in humans:
                        name = best_fixed([r for r in rows if r.schedule == hh])
                        theirs += [r for r in by[(hh, name)]]
                    name = "each human's"
                else:
                    name = best_fixed([r for r in rows if r.schedule == h])
                    theirs = by[(h, name)] if name else []
            else:
                name, theirs = b, [r for r in rows if r.selector == b and (
                    h == "(pooled)" or r.schedule == h)]
            c = compare(mine, theirs)
            lines.append((b, h, name, summary(mine), summary(theirs), c))
            for t in ("success_p", "utility_p", "preemptions_p"):
                tests[(b, t)].append(c[t])
    qs = {key: iter(q_values(ps)) for key, ps in tests.items()}
    out += ["| baseline | human | its policy | success: ours / theirs | p (q) | pre-emptions: "
            "ours / theirs | p (q) | utility: ours / theirs (diff) | p (q) |",
            "|---|---|---|--:|--:|--:|--:|--:|--:|"]
    for b, h, name, mine, theirs, c in lines:
        q = {t: next(qs[(b, t)]) for t in ("success_p", "utility_p", "preemptions_p")}
        out.append(f"| {b} | {h} | {name or '-'} | {mine['success']}/{mine['n']} / "
                   f"{theirs['success']}/{theirs['n']} | {fmt_p(c['success_p'])} "
                   f"({fmt_p(q['success_p'])}) | {mine['preemptions']} / "
                   f"{theirs['preemptions']} | {fmt_p(c['preemptions_p'])} "
                   f"({fmt_p(q['preemptions_p'])}) | {mine['utility']:.3f} / "
                   f"{theirs['utility']:.3f} ({c['utility_diff']:+.3f}) | "
                   f"{fmt_p(c['utility_p'])} ({fmt_p(q['utility_p'])}) |")
    # The gap closed.
    out += ["", "The share of the gap closed (mean utility per task):\n",
            "| human | best fixed | pooled | learning | ceiling | of best fixed -> ceiling | "
            "of pooled -> ceiling |", "|---|--:|--:|--:|--:|--:|--:|"]
    def mean_utility(group):
        """Mean utility a task; nan when the runs hold no such robot."""
        return float(np.mean([r.utility for r in group])) if group else math.nan

    for h in humans + ["(pooled)"]:
        def mean_of(sel):
            return mean_utility([r for r in rows if r.selector == sel
                                 and (h == "(pooled)" or r.schedule == h)])
        if h == "(pooled)":
            bf = mean_utility([r for hh in humans
                               for r in by[(hh, best_fixed([x for x in rows
                                                            if x.schedule == hh]))]])
        else:
            bf = mean_of(best_fixed([r for r in rows if r.schedule == h]))
        pooled, lrn, ceil = mean_of(POOLED), mean_of(learner), mean_of(CEILING)
        out.append(f"| {h} | {bf:.3f} | {pooled:.3f} | {lrn:.3f} | {ceil:.3f} | "
                   f"{gap_share(lrn, bf, ceil)} | {gap_share(lrn, pooled, ceil)} |")
    return "\n".join(out)


def plots(rows: Sequence[TaskRow], folder: Path, learner: str, ceilings: str,
          prefix: str, task: tasks.Task) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    folder.mkdir(parents=True, exist_ok=True)
    # One line per robot that is not a library policy, and "each human's best fixed
    # policy" (chosen per human on the same tasks), in blocks of BLOCK tasks.
    humans = sorted({r.schedule for r in rows})
    best = {h: best_fixed([r for r in rows if r.schedule == h]) for h in humans}
    lines = {"best fixed policy in hindsight (each human's)":
             [r for r in rows if r.selector == best.get(r.schedule)]}
    for s in sorted({r.selector for r in rows if not r.selector.startswith("fixed:")}):
        lines[s] = [r for r in rows if r.selector == s]
    fig, ax = plt.subplots(figsize=(9, 5))
    for label, group in lines.items():
        by_block = defaultdict(list)
        for r in group:
            by_block[(r.task_index - 1) // BLOCK].append(r.utility)
        xs = sorted(by_block)
        mids = [BLOCK * x + (BLOCK + 1) / 2 for x in xs]
        width = 2.6 if label in (learner, CEILING) else 1.4
        style = "--" if label.startswith("best fixed") else "-"
        ax.plot(mids, [np.mean(by_block[x]) for x in xs], style, lw=width, marker="o", ms=3,
                label=label)
    ax.set_xlabel(f"task of the sequence (mean over blocks of {BLOCK} tasks)")
    ax.set_ylabel("mean utility a task (the humans and sequences pooled)")
    ax.set_title(f"Learning curves: {', '.join(humans) if len(humans) < 4 else f'{len(humans)} humans'}",
                 fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(folder / f"{prefix}learning_curves.png", dpi=110)
    plt.close(fig)
    # The learnt figure per human against the ceiling model's.
    humans = sorted({r.schedule for r in rows if r.selector == learner and r.learnt})
    if not humans:
        return
    cols = min(4, len(humans))
    rows_n = math.ceil(len(humans) / cols)
    fig, axes = plt.subplots(rows_n, cols, figsize=(3.4 * cols, 2.8 * rows_n), squeeze=False)
    for ax, h in zip(axes.flat, humans):
        by_index = defaultdict(list)
        for r in rows:
            if r.selector == learner and r.schedule == h and r.learnt:
                by_index[r.task_index].append(r.learnt)
        xs = sorted(by_index)
        mean = np.array([np.mean([v for v, _ in by_index[x]]) for x in xs])
        spread = np.array([np.mean([s for _, s in by_index[x]]) for x in xs])
        ax.plot(xs, mean, "-", color="tab:blue", label="learnt (posterior)")
        ax.fill_between(xs, mean - spread, mean + spread, color="tab:blue", alpha=0.2)
        path = Path(ceilings) / f"{h}.pomdp" if ceilings else None
        if path is not None and path.is_file():
            truth = LearntHuman.figure_of(load_robot_model(str(path), task), task)
            ax.axhline(truth, color="tab:red", ls="--", label="this human (fitted, other seeds)")
        ax.set_title(h, fontsize=9)
        ax.set_ylim(0, 1)
        ax.set_xlabel("task", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(humans):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=6, loc="upper right")
    fig.suptitle(f"P(recovers alone from {task.recovery_state} within {task.recovery_steps} "
                 f"steps of {task.robot_idle_action}): what {learner} learnt, after each task",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(folder / f"{prefix}learnt_figure.png", dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("runs", nargs="+")
    p.add_argument("--from", dest="first", type=int, default=10)
    p.add_argument("--learner", default="pomdp_learning")
    p.add_argument("--plots", default=None)
    p.add_argument("--ceiling-models", default="")
    p.add_argument("--prefix", default="", help="the plots' file names start with it")
    p.add_argument("--task", default=tasks.DEFAULT_TASK, choices=tasks.TASK_NAMES,
                   help="the task the runs played (the ceiling models' states are its)")
    args = p.parse_args(argv)
    rows = load(args.runs)
    print(tables(rows, args.first, args.learner))
    if args.plots:
        plots(rows, Path(args.plots), args.learner, args.ceiling_models, args.prefix,
              tasks.get(args.task))
    return 0


if __name__ == "__main__":
    sys.exit(main())
