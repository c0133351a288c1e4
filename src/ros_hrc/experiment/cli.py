"""hrc_experiment: the anticipatory robot against baselines, across kinds of human, in one command.

Runs a grid of human models x robot policies x seeds x episodes through the real stack (one
``hrc.launch`` per cell, headless, on simulated time, as fast as the machine goes; cells run in
parallel, one per core by default), writes one CSV row per episode and per step as each
episode ends, and at the end a summary with 95 % confidence intervals and PNG plots.
Running the same command again resumes: recorded episodes are kept and skipped.

    hrc_experiment --human-models beginner,tired --policies pomdp,reactive,no_robot \\
                   --seeds 0,1 --episodes 5 --out results/experiment
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import List, Optional

from ros_hrc.command_line import own_arguments
from ros_hrc.experiment.episode import ROBOT_POLICIES
from ros_hrc.experiment.results import (ResultsStore, plot_belief, plot_outcomes, summarize,
                                        write_summary)
from ros_hrc.experiment.stack import CellSpec, decode_episode, worker_command

NAME = "hrc_experiment"
DEFAULT_HUMANS = "beginner,tired,distracted"
DEFAULT_POLICIES = ",".join(ROBOT_POLICIES)


def _names(text: str) -> List[str]:
    names = [part.strip() for part in text.split(",") if part.strip()]
    if not names:
        raise argparse.ArgumentTypeError("give at least one name (comma-separated)")
    return names


def _seeds(text: str) -> List[int]:
    try:
        return [int(part) for part in _names(text)]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"seeds are integers, comma-separated: {exc}") from exc


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=NAME, description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--human-models", type=_names, default=_names(DEFAULT_HUMANS),
                   help=f"human scenarios or .pomdpx files, comma-separated ({DEFAULT_HUMANS})")
    p.add_argument("--policies", type=_names, default=_names(DEFAULT_POLICIES),
                   help=f"robot policies, comma-separated, of {', '.join(ROBOT_POLICIES)}")
    p.add_argument("--seeds", type=_seeds, default=[0, 1], help="seeds, comma-separated (0,1)")
    p.add_argument("--episodes", type=int, default=3, help="episodes per cell (3)")
    p.add_argument("--step-limit", type=int, default=15, help="steps before an episode ends (15)")
    p.add_argument("--jobs", type=int, default=0,
                   help="stacks run side by side (0: one per core)")
    p.add_argument("--out", default="results/experiment", help="results directory")
    p.add_argument("--robot-model", default="robot", help="robot POMDP for the pomdp policy")
    p.add_argument("--human-choice", default="optimal", choices=("optimal", "softmax", "random"),
                   help="how the simulated human picks actions")
    p.add_argument("--time-per-step", type=float, default=0.05, help="DESPOT's budget, s")
    p.add_argument("--max-trials", type=int, default=0,
                   help="cap on DESPOT trials per decision (0: time only; set for exact repeats)")
    p.add_argument("--reactive-budget", type=int, default=8,
                   help="steps the reactive robot waits for success before it helps")
    p.add_argument("--bag", action="store_true", help="also record /hrc/status as a rosbag")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    return p


def plan_cells(args: argparse.Namespace, done: set) -> List[CellSpec]:
    """The cells with episodes still to record, in grid order."""
    cells = []
    log_dir = str(Path(args.out) / "logs")
    for human in args.human_models:
        for policy in args.policies:
            for seed in args.seeds:
                missing = [e for e in range(args.episodes)
                           if (human, policy, seed, e) not in done]
                if missing:
                    cells.append(CellSpec(
                        human_model=human, robot_policy=policy, seed=seed, episodes=missing,
                        step_limit=args.step_limit, log_dir=log_dir,
                        robot_model=args.robot_model, human_choice=args.human_choice,
                        time_per_step=args.time_per_step, max_trials=args.max_trials,
                        reactive_budget=args.reactive_budget, record_bag=args.bag))
    return cells


def _run_worker(cell: CellSpec, deliver, log) -> None:
    """Run one cell in its own process; ``deliver(row, steps)`` per episode as it ends."""
    proc = subprocess.Popen(worker_command(cell), stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    errors = []
    reader = threading.Thread(target=lambda: errors.extend(proc.stderr), daemon=True)
    reader.start()
    for line in proc.stdout:
        episode = decode_episode(line)
        if episode is not None:
            deliver(*episode)
    proc.wait()
    reader.join(5.0)
    if errors:
        log.write("".join(errors))
    if proc.returncode != 0:
        last = errors[-1].strip() if errors else f"exit code {proc.returncode}"
        raise RuntimeError(last)


def run_grid(cells: List[CellSpec], store: ResultsStore, jobs: int) -> dict:
    """Run the cells side by side; record episodes as they come. Returns run figures."""
    from tqdm import tqdm

    total = sum(len(c.episodes) for c in cells)
    started = time.monotonic()
    figures = {"episodes": 0, "simulated_seconds": 0.0}
    failures: List[str] = []
    lock = threading.Lock()   # the store and the bar, from every worker's thread
    logs = Path(cells[0].log_dir)
    logs.mkdir(parents=True, exist_ok=True)
    with tqdm(total=total, unit="episode", desc=NAME, dynamic_ncols=True,
              mininterval=0.5 if sys.stderr.isatty() else 10.0) as bar:

        def deliver(row, steps) -> None:
            with lock:
                store.add(row, steps)
                figures["episodes"] += 1
                figures["simulated_seconds"] += row.sim_seconds
                bar.set_postfix_str(f"{row.human_model}/{row.robot_policy} seed {row.seed}: "
                                    f"{row.end_reason} in {row.steps} steps")
                bar.update(1)

        def run(cell: CellSpec) -> None:
            name = f"{cell.human_model}-{cell.robot_policy}-seed{cell.seed}"
            with open(logs / f"{name}.worker.log", "a") as log:
                try:
                    _run_worker(cell, deliver, log)
                except (RuntimeError, OSError) as exc:
                    with lock:
                        failures.append(f"{name}: {exc}")
                        bar.write(f"{NAME}: cell failed: {failures[-1]}")

        with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
            list(pool.map(run, cells))
    wall = time.monotonic() - started
    episodes, sim = figures["episodes"], figures["simulated_seconds"]
    return {"episodes": episodes, "planned": total, "wall_seconds": wall,
            "simulated_seconds": sim, "failed_cells": failures, "jobs": jobs,
            "episodes_per_minute": episodes / wall * 60.0 if wall > 0 else 0.0,
            "speedup_over_real_time": sim / wall if wall > 0 else 0.0}


def report(store: ResultsStore, out: Path, plots: bool) -> None:
    """Summary (CSV and Markdown) and plots from everything recorded so far."""
    rows = store.episodes()
    if not rows:
        print(f"{NAME}: no episodes recorded yet in {out}")
        return
    summary = summarize(rows)
    csv_path, md_path = write_summary(summary, out / "summary.csv", out / "summary.md")
    print(Path(md_path).read_text())
    written = [str(store.episodes_path), str(store.steps_path), str(csv_path), str(md_path)]
    if plots:
        written.append(plot_outcomes(summary, out / "outcomes.png"))
        written.append(plot_belief(store.steps(), out / "belief.png"))
    print(f"{NAME}: written " + ", ".join(str(p) for p in written))


def main(argv: Optional[list] = None) -> int:
    args = build_parser().parse_args(own_arguments(argv))
    unknown = [p for p in args.policies if p not in ROBOT_POLICIES]
    if unknown:
        print(f"{NAME}: unknown robot policies {', '.join(unknown)}; known: "
              f"{', '.join(ROBOT_POLICIES)}", file=sys.stderr)
        return 2
    if args.episodes < 1 or args.step_limit < 1:
        print(f"{NAME}: --episodes and --step-limit must be at least 1", file=sys.stderr)
        return 2
    out = Path(args.out).expanduser()
    args.jobs = args.jobs or os.cpu_count() or 1
    try:
        store = ResultsStore(out)
    except (OSError, ValueError) as exc:
        print(f"{NAME}: {exc}", file=sys.stderr)
        return 2
    cells = plan_cells(args, store.done())
    total = sum(len(c.episodes) for c in cells)
    grid = len(args.human_models) * len(args.policies) * len(args.seeds) * args.episodes
    print(f"{NAME}: {len(args.human_models)} human models x {len(args.policies)} robot policies "
          f"x {len(args.seeds)} seeds x {args.episodes} episodes = {grid} episodes; "
          f"{grid - total} already in {out}, {total} to run on {min(args.jobs, len(cells) or 1)} "
          "stacks side by side", flush=True)
    figures = None
    if cells:
        try:
            figures = run_grid(cells, store, args.jobs)
        except KeyboardInterrupt:
            print(f"\n{NAME}: interrupted; {len(store.done())} episodes are kept in {out}: "
                  "run the same command again to resume", file=sys.stderr)
            return 130
        print(f"{NAME}: {figures['episodes']} episodes in {figures['wall_seconds']:.1f} s: "
              f"{figures['episodes_per_minute']:.1f} episodes/min, "
              f"{figures['simulated_seconds']:.1f} simulated s, "
              f"speed-up over real time x{figures['speedup_over_real_time']:.1f}")
        (out / "run.json").write_text(json.dumps(figures, indent=2) + "\n")
    report(store, out, plots=not args.no_plots)
    if figures and figures["failed_cells"]:
        print(f"{NAME}: {len(figures['failed_cells'])} cells failed (logs in {out / 'logs'}); "
              "run again to retry them", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
