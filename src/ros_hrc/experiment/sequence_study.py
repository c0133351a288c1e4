"""A sequence study run and reported: ``hrc_experiment --sequence L`` once its grid is checked
(:mod:`ros_hrc.experiment.cli`), and what ``hrc_train_selector`` runs its pairs through. No
ROS here.

The cells (:func:`ros_hrc.experiment.sequences.plan_sequence_cells`) run on the pool or the
cluster as an episode study's do (:func:`ros_hrc.experiment.pool.run_stoppable`: attempts,
SIGINT/SIGTERM, a full disk), each delivering whole sequences into ``sequences.csv`` and
``tasks.csv`` (:class:`ros_hrc.experiment.sequence_rows.SequenceStore`); the same command
resumes with the sequences not yet recorded. Then ``run.json`` (tasks per minute beside
sequences), ``summary.md``/``summary.csv``
(:mod:`ros_hrc.experiment.sequence_statistics`), ``learning_curve.csv`` and
``learning_curve.png``.
"""
from __future__ import annotations

import argparse
import csv
import io
from pathlib import Path
from typing import Dict, List, Optional, Sequence

from ros_hrc.command_line import counted
from ros_hrc.experiment.arguments import say_one_line
from ros_hrc.experiment.plots import NothingToPlot, plot_learning_curves
from ros_hrc.experiment.pool import finish_run, run_stoppable, say_written
from ros_hrc.experiment.sequence_rows import SequenceStore
from ros_hrc.experiment.sequence_statistics import (learning_curve, sequence_headline,
                                                    summarize_sequences,
                                                    write_sequence_summary)
from ros_hrc.experiment.sequences import cell_humans, plan_sequence_cells, tasks_of
from ros_hrc.pomdp.output import write_text_atomically


def grid_size(args: argparse.Namespace) -> int:
    """Sequences of the whole study: schedules' cells x selectors x seeds x episodes."""
    cells = sum(len(cell_humans(args, schedule)) for schedule in args.schedule)
    return cells * len(args.selectors) * len(args.seeds) * args.episodes


def run_sequences(args: argparse.Namespace, out: Path, words: Sequence[str], program: str,
                  report: bool = True) -> int:
    """Run what is missing of a checked sequence study into ``out`` (locked by the caller),
    then write ``run.json`` and, if ``report``, the summary and plots. The exit status."""
    try:
        store = SequenceStore(out)
    except (OSError, ValueError) as exc:
        say_one_line(program, exc)
        return 2
    cells = plan_sequence_cells(args, store.done())
    grid = grid_size(args)
    todo = sum(len(c.episodes) for c in cells)
    print(f"{program}: {counted(grid // (len(args.seeds) * args.episodes), 'cell')} "
          f"(schedules x selectors) x {counted(len(args.seeds), 'seed')} x "
          f"{counted(args.episodes, 'sequence')} of {counted(args.sequence, 'task')} = "
          f"{counted(grid, 'sequence')} ({counted(grid * args.sequence, 'task')}); "
          f"{grid - todo} already in {out}, {todo} to run ({tasks_of(cells)} tasks)"
          + (f", on {min(args.jobs, len(cells) or 1)} stacks side by side"
             if args.cluster is None else f", on the Ray cluster --cluster {args.cluster}"),
          flush=True)
    figures = None
    if cells:
        figures, stopped = run_stoppable(cells, store, args.jobs, words, out, program=program,
                                         cluster=args.cluster, cluster_wait=args.cluster_wait,
                                         fresh_stacks=args.fresh_stacks)
        if stopped is not None:
            return stopped
        figures = sequence_figures(figures, args.sequence)
        print(f"{program}: {figures['sequences']} sequences, {figures['tasks']} tasks in "
              f"{figures['wall_seconds']:.1f} s: {figures['tasks_per_minute']:.1f} tasks/min, "
              f"{figures['simulated_seconds']:.1f} simulated s, speed-up over real time "
              f"x{figures['speedup_over_real_time']:.1f}", flush=True)
    def write_report(written: List[Path]) -> None:
        if report:
            report_sequences(store, out, plots=not args.no_plots, program=program,
                             base=authors_base(args), written_before=written)
        elif written:
            say_written(program, out, written)
    return finish_run(program, figures, store, out, words, write_report)


def sequence_figures(figures: Dict, length: int) -> Dict:
    """The pool's run figures (which count sequences as its units) with the tasks: tasks and
    tasks per minute beside sequences."""
    out = dict(figures)
    out["sequences"] = out.pop("episodes")
    out["tasks"] = out["sequences"] * length
    out["tasks_per_sequence"] = length
    out["sequences_per_minute"] = out.pop("episodes_per_minute")
    out["tasks_per_minute"] = out["sequences_per_minute"] * length
    return out


def authors_base(args) -> Optional[str]:
    """The authors' own policy as a selector: ``fixed:`` and the library's first policy
    (models/README.md, "Policy libraries": fabric's ``base``, the seed's ``authors``)."""
    names = args.library_policies       # validate_sequences loaded the library
    return f"fixed:{names[0]}" if names else None


def report_sequences(store: SequenceStore, out: Path, plots: bool, program: str,
                     base: Optional[str] = None, written_before: Sequence[Path] = ()) -> None:
    """The summary (CSV and Markdown; every selector also against ``base``, the authors'
    policy), the learning curve (CSV, and its plot unless not ``plots``) of everything
    recorded in ``out``."""
    tasks = store.tasks()
    if not tasks:
        print(f"{program}: no sequences recorded yet in {out}")
        return
    summary = summarize_sequences(tasks, base=base)
    csv_path, md_path = write_sequence_summary(summary, out / "summary.csv", out / "summary.md")
    print(sequence_headline(summary))
    print(f"{program}: the whole summary (identification, paired tests): {md_path}")
    curve = learning_curve(tasks)
    curve_path = out / "learning_curve.csv"
    write_text_atomically(curve_path, _csv(curve))
    written = [store.episodes_path, store.steps_path, *written_before, csv_path, md_path,
               curve_path]
    if plots:
        best = {e["schedule"]: e["best_fixed"] for e in summary if e["best_fixed"]}
        try:
            written.append(plot_learning_curves(curve, out / "learning_curve.png", best))
        except NothingToPlot as why:
            print(f"{program}: learning_curve.png left out: {str(why).split(': ', 1)[-1]}")
    say_written(program, out, written)


def _csv(entries: List[Dict]) -> str:
    if not entries:
        return ""
    text = io.StringIO()
    writer = csv.DictWriter(text, list(entries[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows({k: repr(v) if isinstance(v, float) else v for k, v in e.items()}
                     for e in entries)
    return text.getvalue()

