#!/usr/bin/env python3
"""The learning robot's speed (issue #40): writes bench/results/learning.json.

1. **A task's update**: forward-backward and the counts (``LearntHuman.learn``) on tasks of
   5, 15 and 30 steps simulated from the prior (``robot_utility_fitted``) under random
   actions; then the learnt figure and the next task's model apart. Target: the update
   <= 50 ms.
2. **A decision**: DESPOT as the live launch runs it (0.1 s a step, K=500, D=90) on the model
   root sampling plans on (8 posterior draws composed), the belief update included, over
   observation streams simulated from the prior; p50/p99/max against the budget, and the
   pooled robot's on the same streams. Target: p99 within the budget.
3. **A sequence study's pace**: ``hrc_experiment --sequence 30`` on the same grid (two fit
   humans, two sequences each, seed 5) with ``--selectors bpr`` and with
   ``--selectors pomdp_learning``, warm stacks, both cores: tasks per minute as the study
   reports it (run.json), and their ratio; steps per minute beside it, since the learning
   robot's tasks can be longer. Target: within 10 % of BPR's. ``--no-study`` leaves it out.

    source env.sh && python bench/bench_learning.py [--no-study]
"""
import argparse
import csv
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from common import percentile, write_result
from ros_hrc import tasks
from ros_hrc.agents.learning import LearntHuman
from ros_hrc.models import load_robot_model, model_path
from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner

SEED_TASK = tasks.get("seed")
UPDATE_TARGET_MS = 50.0
BUDGET_S = 0.1
PACE_TOLERANCE = 0.10
STUDY_HUMANS = "tired,beginner"
SEQUENCE_LENGTH = 30
SEQUENCES = 2


def simulated_task(model, rng, steps):
    """(action, observation) pairs of one task simulated from ``model`` under random actions
    (the first action the idle one, as the robot starts)."""
    s = int(rng.choice(model.n_states, p=np.asarray(model.initial_belief)))
    a = model.index("action", SEED_TASK.robot_idle_action)
    out = []
    for _ in range(steps):
        s = int(rng.choice(model.n_states, p=model.dense_T[a, s]))
        o = int(rng.choice(model.n_observations, p=model.dense_O[a, s]))
        out.append((a, o))
        a = int(rng.integers(model.n_actions))
    return out


def bench_update(prior):
    rng = np.random.default_rng(0)
    result = {}
    for steps in (5, 15, 30):
        learner = LearntHuman(prior, SEED_TASK, 20.0, 0.1, "sampled", 8, seed=1)
        times, figure, model = [], [], []
        for _ in range(60):
            task = simulated_task(prior, rng, steps)
            t0 = time.perf_counter()
            learner.learn(task)
            t1 = time.perf_counter()
            learner.figure()
            t2 = time.perf_counter()
            learner.model_for_task()
            t3 = time.perf_counter()
            times.append((t1 - t0) * 1000)
            figure.append((t2 - t1) * 1000)
            model.append((t3 - t2) * 1000)
        result[steps] = {"update_ms_p50": percentile(times, 50),
                         "update_ms_p99": percentile(times, 99),
                         "update_ms_max": max(times),
                         "figure_ms_p50": percentile(figure, 50),
                         "next_model_ms_p50": percentile(model, 50)}
        r = result[steps]
        print(f"  update, tasks of {steps:2d} steps: p50 {r['update_ms_p50']:.2f} ms, p99 "
              f"{r['update_ms_p99']:.2f} ms, max {r['update_ms_max']:.2f} ms (target <= "
              f"{UPDATE_TARGET_MS:g} ms: {'met' if r['update_ms_max'] <= UPDATE_TARGET_MS else 'MISSED'}); "
              f"the figure {r['figure_ms_p50']:.1f} ms, the next task's model "
              f"{r['next_model_ms_p50']:.1f} ms (p50)", flush=True)
    return result


def bench_decisions(prior, decisions=300):
    rng = np.random.default_rng(2)
    learner = LearntHuman(prior, SEED_TASK, 20.0, 0.1, "sampled", 8, seed=3)
    config = DespotConfig(time_per_step=BUDGET_S)
    out = {}
    for label, model in (("root sampling (8 draws)", learner.model_for_task()),
                         ("pooled (no learning)", prior)):
        planner = DespotPlanner(model, config, seed=4)
        walls, a = [], model.index("action", SEED_TASK.robot_idle_action)
        streams = [simulated_task(prior, rng, 10) for _ in range(decisions // 10)]
        for task in streams:
            planner.reset()
            a = model.index("action", SEED_TASK.robot_idle_action)
            for _, o in task:
                t0 = time.perf_counter()
                planner.update(a, o)
                a = planner.act()
                walls.append(time.perf_counter() - t0)
        out[label] = {"p50_s": percentile(walls, 50), "p99_s": percentile(walls, 99),
                      "max_s": max(walls), "decisions": len(walls), "states": model.n_states}
        r = out[label]
        print(f"  decision, {label}, {model.n_states} states, budget {BUDGET_S} s: p50 "
              f"{r['p50_s']:.4f} s, p99 {r['p99_s']:.4f} s, max {r['max_s']:.4f} s over "
              f"{r['decisions']} decisions (p99 within the budget: "
              f"{'met' if r['p99_s'] <= BUDGET_S * 1.05 else 'MISSED'})", flush=True)
    return out


def run_study(selector, out_dir):
    """One study of SEQUENCES sequences of SEQUENCE_LENGTH tasks a human: the study's own
    figures (run.json: its wall time and tasks a minute) and the steps its tasks took, since
    a robot that watches longer plays longer tasks at the same speed."""
    words = ["rosrun", "ros_hrc", "hrc_experiment", "--sequence", str(SEQUENCE_LENGTH),
             "--episodes", str(SEQUENCES), "--seeds", "5", "--human-models", STUDY_HUMANS,
             "--selectors", selector, "--jobs", "2", "--no-plots", "--out", str(out_dir)]
    done = subprocess.run(words, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True)
    if done.returncode != 0:
        print(done.stdout[-2000:])
        raise SystemExit(f"bench_learning: {' '.join(words)} failed")
    run = json.loads((out_dir / "run.json").read_text())
    with open(out_dir / "tasks.csv", newline="") as f:
        steps = sum(int(row["steps"]) for row in csv.DictReader(f))
    wall = run["wall_seconds"]
    return {"wall_s": wall, "tasks": run["tasks"], "tasks_per_min": run["tasks_per_minute"],
            "steps": steps, "steps_per_min": 60 * steps / wall}


def bench_study():
    folder = Path(tempfile.mkdtemp(prefix="bench_learning_"))
    try:
        out = {}
        for selector in ("bpr", "pomdp_learning"):
            r = out[selector] = run_study(selector, folder / selector)
            print(f"  study, --selectors {selector}: {r['tasks']} tasks ({r['steps']} steps) in "
                  f"{r['wall_s']:.1f} s = {r['tasks_per_min']:.1f} tasks/min, "
                  f"{r['steps_per_min']:.0f} steps/min", flush=True)
        ratio = out["pomdp_learning"]["tasks_per_min"] / out["bpr"]["tasks_per_min"]
        out["ratio"] = ratio
        out["steps_ratio"] = (out["pomdp_learning"]["steps_per_min"]
                              / out["bpr"]["steps_per_min"])
        print(f"  pace of pomdp_learning / bpr: {ratio:.3f} in tasks a minute (target >= "
              f"{1 - PACE_TOLERANCE:.2f}: {'met' if ratio >= 1 - PACE_TOLERANCE else 'MISSED'}); "
              f"{out['steps_ratio']:.3f} in steps a minute", flush=True)
        return out
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--no-study", action="store_true", help="leave the study's pace out")
    p.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results"
                   / "learning.json")
    args = p.parse_args(argv)
    prior = load_robot_model(str(model_path(SEED_TASK.learning_prior, "robot", SEED_TASK)),
                             SEED_TASK)
    result = {"update": bench_update(prior), "decision": bench_decisions(prior)}
    if not args.no_study:
        result["study"] = bench_study()
    write_result(args.out, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
