#!/usr/bin/env python3
"""Benchmark of hrc_experiment: warm stacks against fresh ones, episodes per minute headless
and the speed-up over real time.

By default (issue #39) it plays the same study-shaped grid twice in one run, on fresh stacks
(`--fresh-stacks`: a stack per cell, as before) and on warm ones (each worker keeps its stack
and hands it cell after cell): 2 human models x 2 robot policies x `--seeds` seeds (10), plus
the human alone on each stream (60 cells, 30 per stack on 2 cores), at 20 and at 2 episodes a
cell (step limit 10), then sequence cells of 20 tasks (`--sequence 20`, each human x seed one
cell, `fixed:authors`), and prints each pair's wall time and the speed-up of warm stacks;
every pair's rows are checked equal but for the wall clock. Writes
bench/results/experiment_stacks.json.

    python bench/bench_experiment.py [--jobs N] [--seeds 10]

`--grid` plays the small fixed grid once instead (2 human models x 2 robot policies x 1 seed
x `--episodes` 20, plus the human alone: 120 episodes) and prints episodes per minute with the
pairs included (stack start-up and shut-down included), the speed-up over real time
(simulated seconds / wall seconds, for the whole run and per stack while it steps), wall
seconds per episode (p50, p99) and each policy's mean decision time; writes
bench/results/experiment.json.

    python bench/bench_experiment.py --grid [--jobs N] [--episodes 20] [--fresh-stacks]

On fresh stacks each cell starts a stack of its own (about 8 s of start-up and stop on 2
cores), so episodes per minute depend on episodes per cell; on warm stacks only each worker's
first cell does.

`--cluster local` (or an address, docs/cluster.md) runs the same grid twice, on the local pool
and on the cluster, the cluster with as many cells in flight as the pool has stacks, and prints
both runs' episodes per minute and the cluster's overhead per cell (its extra wall seconds times
the stacks side by side, over the cells; joining the cluster, a one-off, apart); writes
bench/results/experiment_cluster.json.

    python bench/bench_experiment.py --cluster local [--jobs 2] [--episodes 20]

`--sequence` runs the same small grid twice, as episodes (`--policies pomdp`, the human alone
on each stream run too, as always) and as sequences (`--sequence N --episodes 1 --selectors
fixed:<the library's policy of the same robot model>`: each human's N tasks on one stack that
stays up between them), and prints the sequence mode's tasks per minute beside the episode
mode's episodes per minute; writes bench/results/experiment_sequence.json. A sequence keeps
its stack up between tasks, so it should be at least as fast (issue #30). The unit a task
stands beside is the robot's episode: an episode cell's human-alone counterfactual is a
second cell on a stack of its own that plans nothing, which a sequence does not need (its
utility takes no counterfactual run). Both counts are printed: episodes per minute with the
human-alone ones (the run's own figure) and the robot's episodes per minute.

    python bench/bench_experiment.py --sequence [--jobs 2] [--episodes 20]
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import json
import os
import statistics
import tempfile
from pathlib import Path

from common import percentile, write_result  # bench/common.py

from ros_hrc.experiment.cli import main as experiment_main
from ros_hrc.experiment.store import ResultsStore


HUMANS = ("expert", "distracted")


def hrc_experiment(words: list) -> int:
    """hrc_experiment in this process, its summary (stdout) kept out of the bench's figures;
    its progress and its lines on stderr still show."""
    with contextlib.redirect_stdout(io.StringIO()):
        return experiment_main(words)
POLICIES = ("pomdp", "reactive")


def run_grid(episodes: int, jobs: int, extra=(), seeds: str = "0") -> tuple:
    """The bench's grid through hrc_experiment, its policies in ``extra`` (``--policies``):
    (run.json's figures, every episode row), or None when it failed."""
    with tempfile.TemporaryDirectory(prefix="bench_experiment_") as work:
        # The policies are always named: the grid stays the one the recorded figures were
        # measured on; no_robot is not named, so its episodes are the counterfactual pairs
        # (in work/alone).
        rc = hrc_experiment(["--human-models", ",".join(HUMANS), "--seeds", seeds,
                             "--episodes", str(episodes), "--step-limit", "10",
                             "--jobs", str(jobs), "--out", work, "--no-plots", *extra])
        if rc != 0:
            print(f"hrc_experiment failed ({rc})")
            return None
        run = json.loads((Path(work) / "run.json").read_text())
        rows = ResultsStore(work).episodes() + ResultsStore(Path(work) / "alone").episodes()
    return run, rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=0, help="stacks side by side (0: per core)")
    parser.add_argument("--episodes", type=int, default=20, help="episodes per cell")
    parser.add_argument("--cluster", default=None, metavar="ADDRESS|auto|local",
                        help="also run the grid on this Ray cluster and compare")
    parser.add_argument("--out", type=Path, default=None,
                        help="result file (bench/results/experiment.json, with --cluster "
                             "experiment_cluster.json)")
    parser.add_argument("--sequence", action="store_true",
                        help="compare the sequence mode's tasks per minute with the episode "
                             "mode's episodes per minute on the same grid")
    parser.add_argument("--grid", action="store_true",
                        help="play the small fixed grid once (experiment.json) instead of "
                             "warm stacks against fresh ones")
    parser.add_argument("--fresh-stacks", action="store_true",
                        help="with --grid: a stack per cell")
    parser.add_argument("--seeds", type=int, default=10,
                        help="seeds of the warm-against-fresh grid (2 x 3 cells each)")
    args = parser.parse_args(argv)
    results = Path(__file__).resolve().parent / "results"
    if args.sequence:
        return compare_sequences(args, args.out or results / "experiment_sequence.json")
    if args.cluster is not None:
        return compare_cluster(args, args.out or results / "experiment_cluster.json")
    if not args.grid:
        return compare_stacks(args, args.out or results / "experiment_stacks.json")
    done = run_grid(args.episodes, args.jobs, ["--policies", ",".join(POLICIES)] +
                    (["--fresh-stacks"] if args.fresh_stacks else []))
    if done is None:
        return 1
    run, rows = done
    walls = [r.wall_seconds for r in rows]
    per_stack = sum(r.sim_seconds for r in rows) / sum(walls)
    decisions = {}
    for row in rows:
        decisions.setdefault(row.robot_policy, []).append(row.mean_decision_ms)
    result = {
        "episodes_per_cell": args.episodes,
        "episodes": run["episodes"], "jobs": run["jobs"], "wall_seconds": run["wall_seconds"],
        "episodes_per_minute": run["episodes_per_minute"],
        "speedup_over_real_time": run["speedup_over_real_time"],
        "speedup_per_stack": per_stack,
        "episode_wall_p50_s": percentile(walls, 50), "episode_wall_p99_s": percentile(walls, 99),
        "mean_decision_ms": {p: statistics.fmean(v) for p, v in decisions.items()},
    }
    print(f"  {result['episodes']} episodes ({args.episodes} per cell) on {result['jobs']} stacks in "
          f"{result['wall_seconds']:.1f} s (stack start-up included)")
    print(f"  episodes per minute headless: {result['episodes_per_minute']:.1f}")
    print(f"  speed-up over real time: x{result['speedup_over_real_time']:.2f} for the run, "
          f"x{per_stack:.2f} per stack while stepping")
    print(f"  wall seconds per episode: p50 {result['episode_wall_p50_s']:.2f}, "
          f"p99 {result['episode_wall_p99_s']:.2f}")
    print("  mean decision time: " + ", ".join(f"{p} {ms:.1f} ms" for p, ms in
                                                result["mean_decision_ms"].items()))
    write_result(args.out or results / "experiment.json", result)
    return 0


#: What the wall clock sets in a row, and so differs between any two runs of it.
WALL_FIELDS = ("wall_seconds", "mean_decision_ms")


def same_rows(a: list, b: list) -> bool:
    """Whether two runs wrote the same rows, the wall clock's fields apart."""
    def plain(rows):
        return sorted(repr(sorted((k, v) for k, v in dataclasses.asdict(r).items()
                                  if k not in WALL_FIELDS)) for r in rows)
    return plain(a) == plain(b)


def compare_stacks(args, out: Path) -> int:
    """The study-shaped grid on fresh stacks, then on warm ones, at 20 and at 2 episodes a
    cell, then sequence cells of 20 tasks both ways: each pair's wall time, pace and the
    warm stacks' speed-up; the rows of each pair checked equal but for the wall clock."""
    jobs = args.jobs or os.cpu_count() or 1
    seeds = ",".join(str(s) for s in range(args.seeds))
    policies = ["--policies", ",".join(POLICIES)]
    runs = [("episodes", 20, lambda extra: run_grid(20, jobs, policies + extra, seeds)),
            ("episodes", 2, lambda extra: run_grid(2, jobs, policies + extra, seeds)),
            ("tasks", 20, lambda extra: run_sequences(20, jobs, extra, seeds, parts=True))]
    result = {"jobs": jobs, "humans": list(HUMANS), "policies": list(POLICIES),
              "seeds": args.seeds, "cells_per_episode_grid": len(HUMANS) * (len(POLICIES) + 1)
              * args.seeds, "sequence_cells": len(HUMANS) * args.seeds, "pairs": []}
    failed = False
    for unit, per_cell, run in runs:
        fresh, warm = run(["--fresh-stacks"]), run([])
        if fresh is None or warm is None:
            failed = True
            continue
        (fresh_run, fresh_rows), (warm_run, warm_rows) = fresh, warm
        speedup = fresh_run["wall_seconds"] / warm_run["wall_seconds"]
        same = same_rows(fresh_rows, warm_rows)
        failed = failed or not same
        count = warm_run["episodes"] if unit == "episodes" else warm_run["tasks"]
        pace = f"{unit}_per_minute"
        result["pairs"].append({
            "unit": unit, "per_cell": per_cell, unit: count,
            "fresh_wall_seconds": fresh_run["wall_seconds"],
            "warm_wall_seconds": warm_run["wall_seconds"],
            f"fresh_{pace}": fresh_run[pace], f"warm_{pace}": warm_run[pace],
            "speedup": speedup, "same_rows": same})
        print(f"  {per_cell} {unit} a cell, {count} {unit}: fresh stacks "
              f"{fresh_run['wall_seconds']:.1f} s ({fresh_run[pace]:.1f} {unit}/min), warm "
              f"stacks {warm_run['wall_seconds']:.1f} s ({warm_run[pace]:.1f} {unit}/min): "
              f"x{speedup:.2f}; rows {'the same' if same else 'DIFFER'} but the wall clock",
              flush=True)
    write_result(out, result)
    return 1 if failed else 0


#: The library policy that is the episode grid's ``pomdp`` (the seed authors' robot model,
#: planned with DESPOT): the sequence mode runs it as ``fixed:<it>``.
SEQUENCE_POLICY = "authors"


def run_sequences(tasks: int, jobs: int, extra=(), seeds: str = "0", parts: bool = False
                  ) -> tuple:
    """The bench's grid as sequences of ``tasks`` tasks (one per human and seed): (run.json's
    figures, every sequence row, and with ``parts`` every task row too), or None when it
    failed."""
    from ros_hrc.experiment.sequence_rows import SequenceStore
    with tempfile.TemporaryDirectory(prefix="bench_sequence_") as work:
        rc = hrc_experiment(["--sequence", str(tasks), "--episodes", "1",
                             "--human-models", ",".join(HUMANS), "--seeds", seeds,
                             "--selectors", f"fixed:{SEQUENCE_POLICY}", "--step-limit", "10",
                             "--jobs", str(jobs), "--out", work, "--no-plots", *extra])
        if rc != 0:
            print(f"hrc_experiment --sequence failed ({rc})")
            return None
        run = json.loads((Path(work) / "run.json").read_text())
        store = SequenceStore(work)
        rows = store.sequences() + (store.tasks() if parts else [])
    return run, rows


def compare_sequences(args, out: Path) -> int:
    """The grid as episodes (``pomdp``), then as sequences of as many tasks: episodes per
    minute against tasks per minute, stack start-up and shut-down included in both."""
    jobs = args.jobs or os.cpu_count() or 1
    episodes = run_grid(args.episodes, jobs, ["--policies", "pomdp"])
    sequences = run_sequences(args.episodes, jobs)
    if episodes is None or sequences is None:
        return 1
    (by_episode, episode_rows), (by_sequence, sequence_rows) = episodes, sequences
    # The pace while a stack steps, start-up apart: the robot's episodes (not the human
    # alone's, which plan nothing) against the sequences' tasks.
    robot = [r.wall_seconds for r in episode_rows if r.robot_policy == "pomdp"]
    per_episode = statistics.fmean(robot)
    per_task = sum(r.wall_seconds for r in sequence_rows) / sum(r.tasks for r in sequence_rows)
    # The robot's episodes of the run (the same wall: the human-alone cells are its cost).
    robot_per_minute = len(robot) * 60.0 / by_episode["wall_seconds"]
    result = {
        "episodes_per_cell": args.episodes, "jobs": jobs, "humans": list(HUMANS),
        "episode_mode": {"policy": "pomdp", "episodes": by_episode["episodes"],
                         "robot_episodes": len(robot),
                         "wall_seconds": by_episode["wall_seconds"],
                         "episodes_per_minute": by_episode["episodes_per_minute"],
                         "robot_episodes_per_minute": robot_per_minute,
                         "robot_episode_wall_s": per_episode},
        "sequence_mode": {"selector": f"fixed:{SEQUENCE_POLICY}",
                          "tasks": by_sequence["tasks"],
                          "wall_seconds": by_sequence["wall_seconds"],
                          "tasks_per_minute": by_sequence["tasks_per_minute"],
                          "task_wall_s": per_task},
    }
    print(f"  episode mode (pomdp, the human alone on each stream included): "
          f"{by_episode['episodes']} episodes in {by_episode['wall_seconds']:.1f} s: "
          f"{by_episode['episodes_per_minute']:.1f} episodes/min; the robot's "
          f"{len(robot)}: {robot_per_minute:.1f} robot episodes/min")
    print(f"  sequence mode (fixed:{SEQUENCE_POLICY}, {args.episodes} tasks per sequence): "
          f"{by_sequence['tasks']} tasks in {by_sequence['wall_seconds']:.1f} s: "
          f"{by_sequence['tasks_per_minute']:.1f} tasks/min "
          f"(x{by_sequence['tasks_per_minute'] / robot_per_minute:.2f} the robot episodes' pace)")
    print(f"  while a stack steps: {per_episode:.2f} s per robot episode, {per_task:.2f} s per "
          "task of a sequence")
    write_result(out, result)
    return 0


def compare_cluster(args, out: Path) -> int:
    """The grid on the local pool, then on the cluster with as many cells in flight."""
    jobs = args.jobs or os.cpu_count() or 1
    local = run_grid(args.episodes, jobs, ["--policies", ",".join(POLICIES)])
    remote = run_grid(args.episodes, jobs, ["--policies", ",".join(POLICIES),
                                            "--cluster", args.cluster])
    if local is None or remote is None:
        return 1
    (pool, _), (cluster, _) = local, remote
    cells = len(HUMANS) * (len(POLICIES) + 1)      # and the human alone on each stream
    overhead = (cluster["wall_seconds"] - pool["wall_seconds"]) * jobs / cells
    result = {
        "cluster": args.cluster, "episodes_per_cell": args.episodes, "cells": cells,
        "episodes": cluster["episodes"], "jobs": jobs,
        "local_wall_seconds": pool["wall_seconds"],
        "cluster_wall_seconds": cluster["wall_seconds"],
        "local_episodes_per_minute": pool["episodes_per_minute"],
        "cluster_episodes_per_minute": cluster["episodes_per_minute"],
        "overhead_per_cell_s": overhead,
        "connect_seconds": cluster["cluster"]["connect_seconds"],
        "nodes": [{k: n[k] for k in ("ip", "cells", "episodes")}
                  for n in cluster["cluster"]["nodes"]],
    }
    print(f"  {result['episodes']} episodes ({args.episodes} per cell, {cells} cells), "
          f"{jobs} at a time")
    print(f"  episodes per minute: local pool {result['local_episodes_per_minute']:.1f}, "
          f"cluster {args.cluster} {result['cluster_episodes_per_minute']:.1f}")
    print(f"  overhead per cell on the cluster: {overhead:+.2f} s "
          f"({pool['wall_seconds']:.1f} s local, {cluster['wall_seconds']:.1f} s on the "
          f"cluster; joining it {result['connect_seconds']:.1f} s more, once)")
    write_result(out, result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
