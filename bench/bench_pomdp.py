#!/usr/bin/env python3
"""Benchmark of the POMDP toolkit: parsing, offline solving, DESPOT's decision time and score.

For Tiger (test/fixtures/tiger.95.pomdp), the robot model (models/robot/robot.pomdp) and every
human model (models/human/*.pomdpx):
  * parse time (best of 3);
  * offline solve (HSVI2, or value iteration for an MDP): seconds and the bounds at b0;
  * DESPOT's milliseconds per decision (p50, p99), along simulated runs, two ways: with a
    0.01 s budget per step (what the planner is given in the loop), and with a cap of 100
    trials per search (the cost of a fixed amount of search on this machine).
Then Tiger's DESPOT score at 0.01 s per step, 100 steps x 100 runs (mean and 95 % CI, to set
against the C++ DESPOT's ~17.6 and the optimum 19.37, and a low-variance estimate of its
expected value from its loss to the optimal policy along the same runs), and RockSample_7_8
(generated with bench/make_rocksample_pomdpx.py): parse time and a few DESPOT steps on a
particle belief.

Prints the figures and writes bench/results/pomdp.json.

    source env.sh
    python bench/bench_pomdp.py            # a few minutes
    python bench/bench_pomdp.py --quick    # well under a minute: fewer runs, looser solves
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import List, Optional, Sequence

import numpy as np

from ros_hrc.pomdp import hsvi
from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner, DespotTables
from ros_hrc.pomdp.io import load_model
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.simulate import simulate

ROOT = Path(__file__).resolve().parents[1]

TIGER_OPTIMUM = 19.37
CPP_DESPOT_TIGER = 17.6


def best_parse(path: Path, repeat: int = 3):
    """(model, best-of-``repeat`` parse seconds)."""
    best = float("inf")
    model = None
    for _ in range(repeat):
        start = time.perf_counter()
        model = load_model(path)
        best = min(best, time.perf_counter() - start)
    return model, best


def despot_decisions(model: Model, tables: DespotTables, config: DespotConfig, steps: int,
                     runs: int, seed: int) -> dict:
    """p50/p99 ms of act() and mean trials per decision along simulated runs."""
    trials: List[int] = []

    class Recording(DespotPlanner):
        def act(self) -> int:
            a = super().act()
            trials.append(self.last_stats.trials)
            return a

    result = simulate(model, lambda s: Recording(model, config, s, tables=tables), steps, runs,
                      seed)
    return {"ms_p50": round(result.ms_act_p50, 3), "ms_p99": round(result.ms_act_p99, 3),
            "trials_mean": round(float(np.mean(trials)), 1), "decisions": len(trials)}


def bench_model(path: Path, quick: bool) -> dict:
    model, parse_s = best_parse(path)
    row = {"model": str(path.relative_to(ROOT)), "states": model.n_states,
           "actions": model.n_actions, "observations": model.n_observations,
           "parse_s": round(parse_s, 4)}
    precision = 1e-2 if quick else 1e-3
    start = time.perf_counter()
    policy = hsvi.solve(model, timeout=5.0 if quick else 30.0, precision=precision)
    row.update({"solver": policy.stats["solver"], "solve_s": round(time.perf_counter() - start, 3),
                "lower": round(policy.lower, 6), "upper": round(policy.upper, 6),
                "precision": precision})
    tables = DespotTables(model)
    steps, runs = (10, 2) if quick else (25, 4)
    row["despot_0.01s"] = despot_decisions(model, tables, DespotConfig(time_per_step=0.01),
                                           steps, runs, seed=1)
    row["despot_100_trials"] = despot_decisions(
        model, tables, DespotConfig(time_per_step=60.0, max_trials=100), steps, runs, seed=1)
    return row


def tiger_score(runs: int) -> dict:
    """DESPOT's Tiger score, plus a low-variance estimate of its expected value.

    The estimate uses the performance-difference identity V*(b0) - V^π(b0) =
    E[Σ_t γ^t (V*(b_t) - Q*(b_t, a_t))] along DESPOT's own runs, with V* and Q* (by one-step
    lookahead) from a solved policy: it removes the noise of the tiger's position and of the
    observations, which dominates the plain mean over 100 runs (sd ≈ 20 per run).
    """
    model = load_model(ROOT / "test" / "fixtures" / "tiger.95.pomdp")
    optimal = hsvi.solve(model, timeout=30.0, precision=1e-4)
    config = DespotConfig(time_per_step=0.01)
    tables = DespotTables(model)
    visits: List[tuple] = []

    class Recording(DespotPlanner):
        def act(self) -> int:
            b = self.belief.copy()
            a = super().act()
            visits.append((b, a))
            return a

    result = simulate(model, lambda s: Recording(model, config, s, tables=tables),
                      sim_len=100, sim_num=runs, seed=0)
    T, O, R, gamma = model.dense_T, model.dense_O, model.R_sa, model.discount
    regret = 0.0
    for i, (b, a) in enumerate(visits):
        joint = (b @ T)[:, :, None] * O                                  # (A, S', Z)
        q = R @ b + gamma * np.einsum("asz,ks->azk", joint, optimal.alphas).max(2).sum(1)
        regret += gamma ** (i % 100) * (q.max() - q[a])
    regret /= runs
    return {"time_per_step_s": 0.01, "sim_len": 100, "sim_num": runs,
            "mean": round(result.mean, 3), "ci95_low": round(result.ci95_low, 3),
            "ci95_high": round(result.ci95_high, 3), "ms_per_step": round(result.ms_per_step, 3),
            "ms_act_p50": round(result.ms_act_p50, 3), "ms_act_p99": round(result.ms_act_p99, 3),
            "regret_per_run": round(regret, 3),
            "expected_value_estimate": round(optimal.lower - regret, 3),
            "optimum": TIGER_OPTIMUM, "cpp_despot": CPP_DESPOT_TIGER}


def rocksample(steps: int) -> dict:
    spec = importlib.util.spec_from_file_location("make_rocksample_pomdpx",
                                                  ROOT / "bench" / "make_rocksample_pomdpx.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "RockSample_7_8.pomdpx"
        path.write_text(module.rocksample_pomdpx(7, 8))
        model, parse_s = best_parse(path, repeat=1)
    start = time.perf_counter()
    tables = DespotTables(model)
    tables_s = time.perf_counter() - start
    config = DespotConfig(time_per_step=1.0)
    result = simulate(model, lambda s: DespotPlanner(model, config, s, tables=tables),
                      sim_len=steps, sim_num=1, seed=0)
    planner = DespotPlanner(model, config, 0, tables=tables)
    return {"states": model.n_states, "actions": model.n_actions,
            "observations": model.n_observations, "parse_s": round(parse_s, 3),
            "despot_tables_s": round(tables_s, 3), "particles": planner.particles,
            "steps": steps, "time_per_step_s": 1.0,
            "ms_p50": round(result.ms_act_p50, 1), "ms_p99": round(result.ms_act_p99, 1),
            "discounted_reward": round(result.mean, 3)}


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description="POMDP toolkit benchmark.")
    parser.add_argument("--quick", action="store_true",
                        help="fewer runs and looser solves (well under a minute)")
    parser.add_argument("--tiger-runs", type=int, default=None,
                        help="runs of the Tiger DESPOT score (default 100, 20 with --quick)")
    parser.add_argument("--no-rocksample", action="store_true", help="skip RockSample_7_8")
    args = parser.parse_args(argv)

    paths = [ROOT / "test" / "fixtures" / "tiger.95.pomdp",
             ROOT / "models" / "robot" / "robot.pomdp"]
    paths += sorted((ROOT / "models" / "human").glob("*.pomdpx"))
    rows = []
    print(f"{'model':<34} {'S':>4} {'A':>2} {'Z':>3} {'parse s':>8} {'solve s':>8} "
          f"{'lower':>11} {'upper':>11}  DESPOT ms p50/p99 @0.01s   @100 trials")
    for path in paths:
        row = bench_model(path, args.quick)
        rows.append(row)
        d1, d2 = row["despot_0.01s"], row["despot_100_trials"]
        print(f"{row['model']:<34} {row['states']:>4} {row['actions']:>2} "
              f"{row['observations']:>3} {row['parse_s']:>8.4f} {row['solve_s']:>8.3f} "
              f"{row['lower']:>11.4f} {row['upper']:>11.4f}  "
              f"{d1['ms_p50']:>6.1f}/{d1['ms_p99']:<6.1f} ({d1['trials_mean']:>5.1f} tr)  "
              f"{d2['ms_p50']:>6.1f}/{d2['ms_p99']:<6.1f}", flush=True)

    runs = args.tiger_runs or (20 if args.quick else 100)
    print(f"Tiger DESPOT at 0.01 s per step, 100 steps x {runs} runs ...", flush=True)
    score = tiger_score(runs)
    print(f"  mean {score['mean']:.2f}, 95% CI ({score['ci95_low']:.2f}, {score['ci95_high']:.2f})"
          f"; C++ DESPOT ~{CPP_DESPOT_TIGER}, optimum {TIGER_OPTIMUM}")
    print(f"  loss to the optimal policy along these runs {score['regret_per_run']:.2f}: "
          f"expected value about {score['expected_value_estimate']:.2f}; act p50 "
          f"{score['ms_act_p50']:.1f} ms, p99 {score['ms_act_p99']:.1f} ms")

    rock = None
    if not args.no_rocksample:
        steps = 3 if args.quick else 8
        print(f"RockSample_7_8: DESPOT, 1 s per step, {steps} steps ...", flush=True)
        rock = rocksample(steps)
        print(f"  {rock['states']} states, parse {rock['parse_s']:.2f} s, bounds "
              f"{rock['despot_tables_s']:.2f} s, {rock['particles']} particles, ms per decision "
              f"p50 {rock['ms_p50']:.0f} / p99 {rock['ms_p99']:.0f}, "
              f"discounted reward {rock['discounted_reward']:.2f}")

    out = {"benchmark": "pomdp", "when": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
           "quick": args.quick, "models": rows, "tiger_despot": score, "rocksample_7_8": rock,
           "environment": {"python": platform.python_version(), "numpy": np.__version__,
                           "cpus": os.cpu_count(), "machine": platform.machine()}}
    results = ROOT / "bench" / "results"
    results.mkdir(parents=True, exist_ok=True)
    (results / "pomdp.json").write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {results / 'pomdp.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
