#!/usr/bin/env python3
"""How many DESPOT trials make the decisions of the 0.1 s planner (issue #21).

Experiments bound the robot's DESPOT by work (a fixed number of trials per decision, no time
budget), so a table does not depend on the machine or its load; live runs keep the 0.1 s
budget. This benchmark picks the number of trials: along belief sequences of each robot model
(the model's own dynamics, the robot acting as the 0.1 s planner decides), it asks at every
belief

* the 0.1 s planner twice, from two seeds: the trials its budget achieves (median, p10, p90)
  and how often two runs of it agree with each other (its own noise floor);
* the planner capped at N trials, no time budget, for each N of ``--trials``: how often it
  agrees with the 0.1 s planner.

The choice is the N nearest the median trials of the 0.1 s budget whose agreement with the
0.1 s planner is at least its agreement with itself (within ``--slack``); it is printed and
written to bench/results/trials.json with the machine's load average. docs/performance.md
("Work-bounded planner") records the figures and the choice.

    source env.sh
    python bench/bench_trials.py               # a few minutes
    python bench/bench_trials.py --quick       # a minute: fewer beliefs
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path
from typing import Dict, List, Sequence

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import percentile, write_result  # noqa: E402

from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner, DespotTables  # noqa: E402
from ros_hrc.pomdp.io import load_model  # noqa: E402
from ros_hrc.pomdp.model import Model  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MODELS = ("robot.pomdp", "robot_fitted.pomdp", "robot_considerate.pomdp")
TIME_PER_STEP = 0.1
TRIALS = (100, 200, 300, 400, 500, 600, 700, 800, 1000)


def beliefs_along_runs(model: Model, tables: DespotTables, count: int, steps: int,
                       seed: int) -> List[np.ndarray]:
    """``count`` beliefs met along runs of ``steps`` steps: states and observations drawn
    from the model, actions from the 0.1 s planner (as the robot acts online)."""
    rng = np.random.default_rng(seed)
    planner = DespotPlanner(model, DespotConfig(time_per_step=TIME_PER_STEP), seed=seed,
                            tables=tables)
    T, O = model.dense_T, model.dense_O
    out: List[np.ndarray] = []
    while len(out) < count:
        planner.reset()
        state = int(rng.choice(model.n_states, p=model.initial_belief))
        for _ in range(steps):
            out.append(np.array(planner.belief, dtype=float))
            if len(out) >= count:
                break
            action = planner.act()
            state = int(rng.choice(model.n_states, p=T[action, state]))
            observation = int(rng.choice(model.n_observations, p=O[action, state]))
            planner.update(action, observation)
    return out


def decide(model: Model, tables: DespotTables, config: DespotConfig, belief: np.ndarray,
           seed: int):
    """(action, trials, whether the search was cut short: its root's bounds still apart) of
    a fresh planner at ``belief``."""
    planner = DespotPlanner(model, config, seed=seed, tables=tables)
    planner.reset(belief)
    action = planner.act()
    stats = planner.last_stats
    return action, stats.trials, stats.upper - stats.lower > config.gap_tolerance


def measure(name: str, beliefs: int, steps: int, trials: Sequence[int]) -> Dict[str, object]:
    model = load_model(ROOT / "models" / "robot" / name)
    tables = DespotTables(model)
    points = beliefs_along_runs(model, tables, beliefs, steps, seed=7)
    timed = DespotConfig(time_per_step=TIME_PER_STEP)
    a_time, b_time, achieved, hard = [], [], [], []
    capped: Dict[int, List[int]] = {n: [] for n in trials}
    for i, belief in enumerate(points):
        a, t, a_cut = decide(model, tables, timed, belief, seed=1000 + i)
        b, u, b_cut = decide(model, tables, timed, belief, seed=2000 + i)
        a_time.append(a)
        b_time.append(b)
        hard.append(a_cut)
        # Only searches the budget cut short say what it achieves: at many beliefs (the human
        # holds the object) a trial or two close the root's bounds and the search ends.
        achieved += [n for n, cut in ((t, a_cut), (u, b_cut)) if cut]
        for n in trials:
            config = DespotConfig(time_per_step=float("inf"), max_trials=n)
            capped[n].append(decide(model, tables, config, belief, seed=3000 + i)[0])
    a_time, b_time, hard = np.array(a_time), np.array(b_time), np.array(hard, dtype=bool)
    row: Dict[str, object] = {
        "model": name, "beliefs": len(points),
        "searches_cut_by_time": len(achieved),
        "trials_cut_by_time": achieved,
        "trials_in_0.1s": {"p10": percentile(achieved or [0], 10),
                           "median": percentile(achieved or [0], 50),
                           "p90": percentile(achieved or [0], 90)},
        "agreement_0.1s_with_itself": round(float(np.mean(a_time == b_time)), 3),
        "agreement_with_0.1s_first_seed": {str(n): round(float(np.mean(
            np.array(capped[n]) == a_time)), 3) for n in trials},
        # Where the budget binds (the first seed's search was cut short): where N matters.
        "hard_beliefs": int(hard.sum()),
        "hard_agreement_0.1s_with_itself": _share(a_time[hard] == b_time[hard]),
        "hard_agreement_with_0.1s": {str(n): _share(np.array(capped[n])[hard] == a_time[hard])
                                     for n in trials},
    }
    return row


def _share(hits: np.ndarray):
    return round(float(np.mean(hits)), 3) if hits.size else None


def choose(rows: List[Dict[str, object]], trials: Sequence[int], slack: float) -> int:
    """The N nearest the median trials of the 0.1 s budget (the searches it cut short, of all
    models together) whose agreement with the 0.1 s planner (first seed) is, on every model,
    at least the 0.1 s planner's agreement with itself less ``slack``."""
    pooled = [n for r in rows for n in r["trials_cut_by_time"]]
    median = float(np.median(pooled)) if pooled else 1.0
    good = [n for n in trials if all(
        r["agreement_with_0.1s_first_seed"][str(n)] >= r["agreement_0.1s_with_itself"] - slack
        for r in rows)]
    pool = good or list(trials)
    return min(pool, key=lambda n: (abs(np.log(n / max(median, 1.0))), n))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--quick", action="store_true", help="fewer beliefs (a minute)")
    p.add_argument("--beliefs", type=int, default=150, help="beliefs per model (150)")
    p.add_argument("--trials", type=int, nargs="+", default=list(TRIALS))
    p.add_argument("--slack", type=float, default=0.02,
                   help="agreement a trial cap may lack against the 0.1 s planner's own (0.02)")
    p.add_argument("--out", default=str(ROOT / "bench" / "results" / "trials.json"))
    args = p.parse_args(argv)
    beliefs = 30 if args.quick else args.beliefs
    load = os.getloadavg()
    started = time.perf_counter()
    rows = []
    for name in MODELS:
        row = measure(name, beliefs, steps=15, trials=args.trials)
        rows.append(row)
        q = row["trials_in_0.1s"]
        print(f"{name}: {row['beliefs']} beliefs, {row['searches_cut_by_time']} of "
              f"{2 * row['beliefs']} searches cut by the budget; trials in 0.1 s p10 {q['p10']} median "
              f"{q['median']} p90 {q['p90']}; 0.1 s vs itself {row['agreement_0.1s_with_itself']}"
              "; N trials vs 0.1 s: " + ", ".join(
                  f"{n}: {v}" for n, v in row["agreement_with_0.1s_first_seed"].items())
              + f"; where the budget binds ({row['hard_beliefs']} beliefs): 0.1 s vs itself "
              f"{row['hard_agreement_0.1s_with_itself']}, N trials vs 0.1 s: " + ", ".join(
                  f"{n}: {v}" for n, v in row["hard_agreement_with_0.1s"].items()),
              flush=True)
    chosen = choose(rows, args.trials, args.slack)
    pooled = [n for r in rows for n in r.pop("trials_cut_by_time")]
    pooled_q = {"p10": percentile(pooled or [0], 10), "median": percentile(pooled or [0], 50),
                "p90": percentile(pooled or [0], 90), "searches": len(pooled)}
    print(f"all models, searches the 0.1 s budget cut short: {pooled_q}")
    print(f"chosen: {chosen} trials per decision (load average before: "
          f"{load[0]:.2f} on {os.cpu_count()} cores; {time.perf_counter() - started:.0f} s)")
    write_result(Path(args.out), {
        "time_per_step_s": TIME_PER_STEP, "models": rows, "chosen_trials": chosen,
        "trials_in_0.1s_all_models": pooled_q,
        "slack": args.slack, "load_average_1min_before": round(load[0], 2),
        "cpus": os.cpu_count(), "machine": platform.processor() or platform.machine(),
        "python": platform.python_version()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
