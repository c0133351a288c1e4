#!/usr/bin/env python3
"""Benchmark of hrc_experiment: episodes per minute headless and the speed-up over real time.

Runs a fixed grid (2 human models x 2 robot policies x 1 seed x 20 episodes, step limit 10,
plus the human alone on each of those streams, which hrc_experiment runs itself for the
counterfactual: 120 episodes) through the real stack, one stack per core, into a fresh
directory, and prints episodes per minute with the pairs included (stack start-up and
shut-down included), the speed-up over real time (simulated
seconds / wall seconds, for the whole run and per stack while it steps), wall seconds per
episode (p50, p99) and each policy's mean decision time; writes bench/results/experiment.json.

Each cell starts a stack of its own (about 3.5 s of start-up on 2 cores), so episodes per
minute depend on episodes per cell: 20 is a small study's cell (an HRI study runs hundreds);
`--episodes 2` shows the start-up-bound case.

    python bench/bench_experiment.py [--jobs N] [--episodes 20]
"""
from __future__ import annotations

import argparse
import json
import statistics
import tempfile
from pathlib import Path

from common import percentile, write_result  # bench/common.py

from ros_hrc.experiment.cli import main as hrc_experiment
from ros_hrc.experiment.store import ResultsStore


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=0, help="stacks side by side (0: per core)")
    parser.add_argument("--episodes", type=int, default=20, help="episodes per cell")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).resolve().parent / "results" / "experiment.json")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench_experiment_") as work:
        # The policies named: the grid stays the one the recorded figures were measured on;
        # no_robot is not named, so its episodes are the counterfactual pairs (in work/alone).
        rc = hrc_experiment(["--human-models", "expert,distracted", "--seeds", "0",
                             "--policies", "pomdp,reactive",
                             "--episodes", str(args.episodes), "--step-limit", "10",
                             "--jobs", str(args.jobs), "--out", work, "--no-plots"])
        if rc != 0:
            print(f"hrc_experiment failed ({rc})")
            return 1
        run = json.loads((Path(work) / "run.json").read_text())
        rows = ResultsStore(work).episodes() + ResultsStore(Path(work) / "alone").episodes()
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
    write_result(args.out, result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
