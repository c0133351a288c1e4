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
particle belief. Last, whether DESPOT's decision honours its budget (issue #11): act() p50/p99
at time_per_step 0.1 s on Tiger, the robot model and RockSample_7_8, and p99 / time_per_step
(the target is <= 1.2), one line per model.

First, our solvers side by side with the reference solvers, run live on the same files
(issue #39; ``bench/peers.py``): SARSOP's ``pomdpsol`` and ``pomdpsim`` from ``$SARSOP_BIN``
and C++ DESPOT's ``despot_pomdpx`` from ``$DESPOT_BIN`` (``../shared/peers/build.sh`` builds
them outside the repository and prints both variables; without one, its figures are "no
figure"). The ratios come from this run alone, interleaved, every process timed whole:
  * the start-up floor: a bare Python, importing numpy, importing numpy and scipy.sparse;
  * precision 1e-3 on the robot models and a few human MDPs: our solver in this process,
    the whole ``hrc_pomdp solve`` process and the whole ``pomdpsol`` process (medians), the
    ratios whole/whole and solve/whole, and both solvers' bounds;
  * ``hrc_pomdp simulate --policy`` against ``pomdpsim`` on robot.pomdp (each its own
    policy), and ``hrc_pomdp simulate --planner despot`` against ``despot_pomdpx`` on Tiger;
  * RockSample_7_8 (bench/make_rocksample_pomdpx.py, SARSOP's encoding) after 30 s: both
    processes' bounds, gap ratio and peak memory (issue #24's targets: gap <= 1.5x, memory
    <= 2x);
  * the robot models of human types (issue #31, ``hrc_fit --types``: the seed's, 8 types x 7
    states, and fabric's, 10 x 11): each solver for a budget (120 s; 20 with --quick), when its
    gap first fell under 1, 0.1, 0.01 and 1e-3 and both solvers' bounds at matched times --
    ours in wall seconds after loading, SARSOP's in its table's CPU seconds after loading
    (what its --timeout counts), each process's wall time beside.
The load average is printed beside the figures: on a shared machine wall time follows it.

Prints the figures and writes bench/results/pomdp.json.

    source env.sh
    python bench/bench_pomdp.py                 # a few minutes
    python bench/bench_pomdp.py --quick         # well under a minute: fewer runs, looser solves
    python bench/bench_pomdp.py --peers-only    # only the side by side with the peers (~10 min)
    python bench/bench_pomdp.py --types-only    # only the models of human types (about 8 min)

with the peers: ``eval "$(../shared/peers/build.sh)" && export SARSOP_BIN DESPOT_BIN`` first.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib.util
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Iterator, List, Optional, Sequence

import numpy as np

from ros_hrc.pomdp import offline
from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner, DespotTables
from ros_hrc.pomdp.io import convert, load_model
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.simulate import simulate
from ros_hrc.pomdp.typed import TypeLayout

import peers

ROOT = Path(__file__).resolve().parents[1]

TIGER_OPTIMUM = 19.37
CPP_DESPOT_TIGER = 17.6

#: The budget of the decision-time check (issue #11: p99 <= 1.2 x time_per_step).
BUDGET_TIME_PER_STEP = 0.1

#: The robot models of issue #24's target (time to precision 1e-3 within 2x SARSOP's), then
#: the small models whose whole run is mostly start-up (issue #39: hrc_pomdp within 2x of
#: pomdpsol's wall time). ``robot_fitted_9a32e6f`` is the file issue #24 measured SARSOP on;
#: ``robot_fitted.pomdp`` was refitted since.
SOLVER_MODELS = ["models/robot/robot.pomdp", "models/robot/robot_completed.pomdp",
                 "bench/models/robot_fitted_9a32e6f.pomdp", "models/robot/robot_fitted.pomdp",
                 "models/robot/robot_considerate.pomdp", "models/human/humanModel.pomdpx",
                 "models/human/tired.pomdpx", "models/human/expert.pomdpx"]
#: Issue #24's targets: time <= 2x SARSOP's; RockSample gap <= 1.5x, memory <= 2x.
TIME_FACTOR, GAP_FACTOR, MEMORY_FACTOR = 2.0, 1.5, 2.0
#: The robot models of human types (issue #31, ``make fit-types``): the seed's and fabric's.
TYPES_MODELS = ["models/robot/robot_types.pomdp", "models/fabric/robot/robot_types.pomdp"]
#: The gaps at which each solver's time on a types model is recorded, and the times at which
#: both solvers' bounds are set side by side (those within the budget).
TYPES_GAPS = (1.0, 0.1, 0.01, 1e-3)
TYPES_TIMES = (1.0, 10.0, 30.0, 60.0, 120.0, 300.0, 600.0)


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


def despot_budget(label: str, model: Model, tables: DespotTables, time_per_step: float,
                  decisions: int, seed: int = 7) -> dict:
    """act() p50/p99 ms at ``time_per_step`` over ``decisions`` decisions (runs of 5 steps, so
    most decisions are made on beliefs worth searching), and p99 as a multiple of the budget."""
    steps = 5
    config = DespotConfig(time_per_step=time_per_step)
    result = simulate(model, lambda s: DespotPlanner(model, config, s, tables=tables),
                      sim_len=steps, sim_num=max(1, -(-decisions // steps)), seed=seed)
    return {"model": label, "time_per_step_s": time_per_step, "decisions": result.steps,
            "ms_p50": round(result.ms_act_p50, 2), "ms_p99": round(result.ms_act_p99, 2),
            "p99_over_budget": round(result.ms_act_p99 / (1000.0 * time_per_step), 3)}


def budget_line(row: dict) -> str:
    return (f"DESPOT decision at time_per_step {row['time_per_step_s']:.3f} s: {row['model']} "
            f"p50 {row['ms_p50']:.1f} ms, p99 {row['ms_p99']:.1f} ms "
            f"({row['p99_over_budget']:.2f} x budget)")


@contextlib.contextmanager
def rocksample_7_8_file() -> Iterator[Path]:
    """RockSample_7_8, written by make_rocksample_pomdpx.py to a file that lasts the block."""
    spec = importlib.util.spec_from_file_location("make_rocksample_pomdpx",
                                                  ROOT / "bench" / "make_rocksample_pomdpx.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "RockSample_7_8.pomdpx"
        path.write_text(module.rocksample_pomdpx(7, 8))
        yield path


def load_rocksample_7_8():
    """(RockSample_7_8 generated by make_rocksample_pomdpx.py, its parse seconds)."""
    with rocksample_7_8_file() as path:
        return best_parse(path, repeat=1)


def bench_model(path: Path, quick: bool) -> dict:
    model, parse_s = best_parse(path)
    row = {"model": str(path.relative_to(ROOT)), "states": model.n_states,
           "actions": model.n_actions, "observations": model.n_observations,
           "parse_s": round(parse_s, 4)}
    precision = 1e-2 if quick else 1e-3
    start = time.perf_counter()
    policy = offline.solve(model, timeout=5.0 if quick else 30.0, precision=precision)
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
    optimal = offline.solve(model, timeout=30.0, precision=1e-4)
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


def rocksample(steps: int, budget_decisions: int = 0):
    """The RockSample_7_8 figures, and its budget row (``despot_budget``) when asked for."""
    model, parse_s = load_rocksample_7_8()
    start = time.perf_counter()
    tables = DespotTables(model)
    tables_s = time.perf_counter() - start
    config = DespotConfig(time_per_step=1.0)
    result = simulate(model, lambda s: DespotPlanner(model, config, s, tables=tables),
                      sim_len=steps, sim_num=1, seed=0)
    planner = DespotPlanner(model, config, 0, tables=tables)
    budget = (despot_budget("RockSample_7_8", model, tables, BUDGET_TIME_PER_STEP,
                            budget_decisions) if budget_decisions else None)
    return {"states": model.n_states, "actions": model.n_actions,
            "observations": model.n_observations, "parse_s": round(parse_s, 3),
            "despot_tables_s": round(tables_s, 3), "particles": planner.particles,
            "steps": steps, "time_per_step_s": 1.0,
            "ms_p50": round(result.ms_act_p50, 1), "ms_p99": round(result.ms_act_p99, 1),
            "discounted_reward": round(result.mean, 3)}, budget


def load_average() -> str:
    """The 1, 5 and 15 minute load averages, as uptime prints them."""
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


def median(values: Sequence[float]) -> float:
    return statistics.median(values) if values else float("nan")


def ratio_text(ours: Optional[float], theirs: Optional[float], unit: str = "x") -> str:
    """``ours / theirs`` as text, or "no figure" when the peer did not run."""
    if ours is None or theirs is None or theirs <= 0:
        return peers.NO_FIGURE
    return f"{ours / theirs:.2f}{unit}"


def start_up_floor(runs: int) -> dict:
    """Median wall seconds of a bare Python, of importing numpy and of importing numpy and
    scipy.sparse (what any verb reading a model needs): the floor under hrc_pomdp's time."""
    probes = {"python": "pass", "numpy": "import numpy",
              "numpy + scipy.sparse": "import numpy, scipy.sparse"}
    return {name: round(median([peers.run([sys.executable, "-c", code]).wall_s
                                for _ in range(runs)]), 4) for name, code in probes.items()}


def solver_times(runs: int, work: Path) -> List[dict]:
    """SOLVER_MODELS to precision 1e-3: our solver in this process (median wall and CPU of
    ``runs``), and side by side the whole ``hrc_pomdp solve`` process against the whole
    ``pomdpsol`` process on the same file, interleaved ``runs`` times (pomdpsol: no figure
    without SARSOP_BIN)."""
    pomdpsol = peers.sarsop("pomdpsol")
    rows = []
    for p in SOLVER_MODELS:
        model = load_model(ROOT / p)
        wall, cpu, ours_proc, theirs_proc = [], [], [], []
        theirs_bounds = None
        for i in range(runs):
            start, start_cpu = time.perf_counter(), time.process_time()
            policy = offline.solve(model, timeout=120.0, precision=1e-3)
            wall.append(time.perf_counter() - start)
            cpu.append(time.process_time() - start_cpu)
            done = peers.run(peers.HRC_POMDP + ["solve", ROOT / p, "--precision", "1e-3",
                                                "-o", work / "ours.npz"])
            if done.returncode == 0:
                ours_proc.append(done.wall_s)
            if pomdpsol:
                done = peers.run([pomdpsol, ROOT / p, "--precision", "1e-3", "-o",
                                  work / "theirs.policy"], cwd=work)
                if done.returncode == 0:
                    theirs_proc.append(done.wall_s)
                    table = peers.sarsop_table(done.stdout)
                    theirs_bounds = table[-1][1:] if table else None
        ours_s, theirs_s = median(ours_proc), (median(theirs_proc) if theirs_proc else None)
        rows.append({"model": p, "states": model.n_states, "solver": policy.stats["solver"],
                     "solve_wall_s": round(median(wall), 4), "solve_cpu_s": round(median(cpu), 4),
                     "lower": policy.lower, "upper": policy.upper,
                     "hrc_pomdp_wall_s": round(ours_s, 4),
                     "pomdpsol_wall_s": round(theirs_s, 4) if theirs_s else None,
                     "pomdpsol_bounds": theirs_bounds,
                     "process_ratio": round(ours_s / theirs_s, 2) if theirs_s else None,
                     "solve_over_pomdpsol": round(median(wall) / theirs_s, 2) if theirs_s
                     else None})
    return rows


def solver_line(row: dict) -> str:
    theirs = (f"{row['pomdpsol_wall_s']:>9.3f}" if row["pomdpsol_wall_s"] is not None
              else f"{peers.NO_FIGURE:>9}")
    bounds = row["pomdpsol_bounds"]
    theirs_bounds = f"[{bounds[0]:.4f}, {bounds[1]:.4f}]" if bounds else "-"
    return (f"  {row['model']:<42} {row['solve_wall_s']:>7.3f} {row['hrc_pomdp_wall_s']:>9.3f} "
            f"{theirs} {ratio_text(row['hrc_pomdp_wall_s'], row['pomdpsol_wall_s']):>9} "
            f"{ratio_text(row['solve_wall_s'], row['pomdpsol_wall_s']):>9}   "
            f"[{row['lower']:.4f}, {row['upper']:.4f}] vs {theirs_bounds}")


def rocksample_solve(seconds: float) -> dict:
    """RockSample_7_8 (make_rocksample_pomdpx.py, SARSOP's encoding) for ``seconds``: ours in
    a process of its own (``hrc_pomdp solve --timeout``, which counts from the command's start,
    the model's reading included) and ``pomdpsol --timeout`` (CPU seconds after loading) on the
    same file; each process's bounds, wall and CPU seconds and peak memory."""
    pomdpsol = peers.sarsop("pomdpsol")
    with rocksample_7_8_file() as path:
        done = peers.run(peers.HRC_POMDP + ["solve", path, "--timeout", str(seconds), "--json"])
        if done.returncode != 0:
            return {"error": (done.stderr.strip().splitlines() or ["failed"])[-1]}
        out = json.loads(done.stdout)
        ours = {"lower": out["lower"], "upper": out["upper"], "gap": out["upper"] - out["lower"],
                "trials": out["stats"].get("trials"), "solver": out["solver"],
                "wall_s": round(done.wall_s, 2), "cpu_s": round(done.cpu_s, 2),
                "memory_mb": round(done.peak_mb, 1)}
        theirs = None
        if pomdpsol:
            done = peers.run([pomdpsol, path, "--timeout", str(seconds), "-o",
                              path.with_suffix(".policy")], cwd=path.parent)
            table = peers.sarsop_table(done.stdout)
            if table:
                t, lo, up = table[-1]
                theirs = {"lower": lo, "upper": up, "gap": up - lo, "table_s": t,
                          "wall_s": round(done.wall_s, 2), "cpu_s": round(done.cpu_s, 2),
                          "memory_mb": round(done.peak_mb, 1)}
    row = {"seconds": seconds, "ours": ours, "pomdpsol": theirs}
    if theirs:
        row["gap_ratio"] = round(ours["gap"] / theirs["gap"], 2)
        row["memory_ratio"] = round(ours["memory_mb"] / theirs["memory_mb"], 2)
        row["target_met"] = bool(row["gap_ratio"] <= GAP_FACTOR
                                 and row["memory_ratio"] <= MEMORY_FACTOR)
    return row


def rocksample_line(row: dict) -> str:
    if "error" in row:
        return f"  RockSample_7_8: {row['error']}"
    o, s = row["ours"], row["pomdpsol"]
    ours = (f"ours [{o['lower']:.2f}, {o['upper']:.2f}] gap {o['gap']:.2f} ({o['solver']}, "
            f"{o['trials']} trials), {o['memory_mb']:.0f} MB, {o['wall_s']:.1f} s wall / "
            f"{o['cpu_s']:.1f} s CPU")
    if s is None:
        return f"  RockSample_7_8, {row['seconds']:g} s: {ours}; pomdpsol: {peers.NO_FIGURE}"
    return (f"  RockSample_7_8, {row['seconds']:g} s: {ours}; pomdpsol [{s['lower']:.2f}, "
            f"{s['upper']:.2f}] gap {s['gap']:.2f}, {s['memory_mb']:.0f} MB, {s['wall_s']:.1f} s "
            f"wall / {s['cpu_s']:.1f} s CPU: gap {row['gap_ratio']:.2f}x (target <= "
            f"{GAP_FACTOR:g}x), memory {row['memory_ratio']:.2f}x (target <= {MEMORY_FACTOR:g}x)"
            f": {'met' if row['target_met'] else 'NOT met'}")


def types_solve(path: str, seconds: float) -> dict:
    """A model of human types solved to precision 1e-3 or for ``seconds`` of wall time: our
    bounds along the way (seconds after loading, wall), CPU seconds, vectors, and beside it
    ``pomdpsol --timeout seconds`` on the same file (its table's seconds are CPU after
    loading; its process's wall seconds too)."""
    model = load_model(ROOT / path)
    history: List[tuple] = []

    def progress(p) -> None:
        history.append((p.seconds, p.lower, p.upper))

    start, start_cpu = time.perf_counter(), time.process_time()
    policy = offline.solve(model, timeout=seconds, precision=1e-3, progress=progress)
    wall, cpu = time.perf_counter() - start, time.process_time() - start_cpu
    history.append((wall, policy.lower, policy.upper))
    row = {"model": path, "states": model.n_states, "types": len(TypeLayout.of(model).types),
           "budget_s": seconds, "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
           "lower": policy.lower, "upper": policy.upper, "gap": policy.upper - policy.lower,
           "converged": policy.upper - policy.lower <= 1e-3,
           "vectors": int(len(policy.alphas)), "trials": policy.stats.get("trials"),
           "seconds_to_gap": {f"{g:g}": peers.first_time_at_gap(history, g) for g in TYPES_GAPS},
           "bounds_at": {f"{s:g}": peers.bounds_at(history, s) for s in TYPES_TIMES
                         if s <= seconds}, "pomdpsol": None}
    pomdpsol = peers.sarsop("pomdpsol")
    if pomdpsol:
        with tempfile.TemporaryDirectory() as tmp:
            done = peers.run([pomdpsol, ROOT / path, "--timeout", str(seconds), "--precision",
                              "1e-3", "-o", Path(tmp) / "types.policy"], cwd=tmp)
        table = peers.sarsop_table(done.stdout)
        if table:
            t, lo, up = table[-1]
            row["pomdpsol"] = {
                "lower": lo, "upper": up, "gap": up - lo, "table_s": t,
                "wall_s": round(done.wall_s, 2), "cpu_s": round(done.cpu_s, 2),
                "seconds_to_gap": {f"{g:g}": peers.first_time_at_gap(table, g)
                                   for g in TYPES_GAPS},
                "bounds_at": {f"{s:g}": peers.bounds_at(table, s) for s in TYPES_TIMES
                              if s <= seconds}}
    return row


def types_lines(row: dict) -> List[str]:
    def reached(d: dict) -> str:
        return ", ".join(f"{g} at {s:.1f} s" if s is not None else f"{g} not reached"
                         for g, s in d.items())

    def at(d: dict) -> str:
        return "; ".join(f"{s} s [{b[0]:.4f}, {b[1]:.4f}]" if b else f"{s} s -"
                         for s, b in d.items())
    s = row["pomdpsol"]
    lines = [f"  {row['model']} ({row['states']} states, {row['types']} types), budget "
             f"{row['budget_s']:g} s",
             f"    ours:     [{row['lower']:.4f}, {row['upper']:.4f}] gap {row['gap']:.4f} "
             f"({'converged' if row['converged'] else 'NOT converged'}) in {row['wall_s']:.1f} s "
             f"wall after loading, {row['cpu_s']:.1f} s CPU, {row['vectors']} vectors; gap "
             f"{reached(row['seconds_to_gap'])}",
             f"              bounds at (wall s) {at(row['bounds_at'])}"]
    if s is None:
        lines.append(f"    pomdpsol: {peers.NO_FIGURE}")
    else:
        lines += [f"    pomdpsol: [{s['lower']:.4f}, {s['upper']:.4f}] gap {s['gap']:.4f} at "
                  f"{s['table_s']:.1f} s of its CPU after loading, process {s['wall_s']:.1f} s "
                  f"wall / {s['cpu_s']:.1f} s CPU; gap {reached(s['seconds_to_gap'])}",
                  f"              bounds at (CPU s) {at(s['bounds_at'])}"]
    return lines


def simulators(work: Path, sim_num: int, despot_runs: int) -> dict:
    """The simulators side by side, each process whole: ``hrc_pomdp simulate --policy`` (our
    policy of robot.pomdp, the expected-reward estimator as pomdpsim's) against ``pomdpsim``
    (SARSOP's policy of the same file), 100 steps x ``sim_num`` runs; and ``hrc_pomdp
    simulate --planner despot`` against C++ DESPOT's ``despot_pomdpx`` on Tiger as POMDPX,
    0.01 s per step, 100 steps x ``despot_runs`` runs (Tiger: its discount, 0.95, is also
    DESPOT's default)."""
    robot = ROOT / "models" / "robot" / "robot.pomdp"
    out: dict = {}
    peers.run(peers.HRC_POMDP + ["solve", robot, "-o", work / "robot.npz"])
    done = peers.run(peers.HRC_POMDP + ["simulate", robot, "--policy", work / "robot.npz",
                                        "--sim-len", "100", "--sim-num", str(sim_num),
                                        "--estimator", "expected", "--json"])
    facts = json.loads(done.stdout)
    out["simulate_policy"] = {"ours": {"mean": facts["mean"], "ci95": [facts["ci95_low"],
                                                                     facts["ci95_high"]],
                                       "wall_s": round(done.wall_s, 3)}, "pomdpsim": None}
    pomdpsol, pomdpsim = peers.sarsop("pomdpsol"), peers.sarsop("pomdpsim")
    if pomdpsol and pomdpsim:
        peers.run([pomdpsol, robot, "-o", work / "robot.policy"], cwd=work)
        done = peers.run([pomdpsim, robot, "--policy-file", work / "robot.policy", "--simLen",
                          "100", "--simNum", str(sim_num), "--srand", "1"], cwd=work)
        value = peers.pomdpsim_value(done.stdout)
        if value:
            out["simulate_policy"]["pomdpsim"] = {"mean": value[0], "ci95": list(value[1:]),
                                                  "wall_s": round(done.wall_s, 3)}
    tiger = work / "tiger.pomdpx"
    convert(ROOT / "test" / "fixtures" / "tiger.95.pomdp", tiger)
    done = peers.run(peers.HRC_POMDP + ["simulate", tiger, "--planner", "despot",
                                        "--time-per-step", "0.01", "--sim-len", "100",
                                        "--sim-num", str(despot_runs), "--json"])
    facts = json.loads(done.stdout)
    half = (facts["ci95_high"] - facts["ci95_low"]) / 2
    out["despot_tiger"] = {"ours": {"mean": facts["mean"], "stderr": half / 1.96,
                                    "wall_s": round(done.wall_s, 2)}, "cpp_despot": None}
    despot = peers.despot_pomdpx()
    if despot:
        done = peers.run([despot, "-m", tiger, "-t", "0.01", "-s", "100", "--runs",
                          str(despot_runs), "-r", "0", "--silence"], cwd=work)
        value = peers.despot_value(done.stdout)
        if value:
            out["despot_tiger"]["cpp_despot"] = {"mean": value[0], "stderr": value[1],
                                                 "wall_s": round(done.wall_s, 2)}
    return out


def simulator_lines(row: dict, sim_num: int, despot_runs: int) -> List[str]:
    p, d = row["simulate_policy"], row["despot_tiger"]
    o, s = p["ours"], p["pomdpsim"]
    theirs = (f"pomdpsim {s['mean']:.4f} ({s['ci95'][0]:.4f}, {s['ci95'][1]:.4f}) in "
              f"{s['wall_s']:.3f} s; wall {ratio_text(o['wall_s'], s['wall_s'])}"
              if s else f"pomdpsim: {peers.NO_FIGURE}")
    o2, c = d["ours"], d["cpp_despot"]
    cpp = (f"C++ DESPOT {c['mean']:.2f} (stderr {c['stderr']:.2f}) in {c['wall_s']:.1f} s; wall "
           f"{ratio_text(o2['wall_s'], c['wall_s'])}" if c else f"C++ DESPOT: {peers.NO_FIGURE}")
    return [f"  robot.pomdp, its policy simulated 100 steps x {sim_num}: ours {o['mean']:.4f} "
            f"({o['ci95'][0]:.4f}, {o['ci95'][1]:.4f}) in {o['wall_s']:.3f} s; {theirs}",
            f"  Tiger, DESPOT at 0.01 s a step, 100 steps x {despot_runs}: ours {o2['mean']:.2f} "
            f"(stderr {o2['stderr']:.2f}) in {o2['wall_s']:.1f} s; {cpp}"]


def against_peers(runs: int, rocksample_seconds: Optional[float],
                  types_seconds: Optional[float], sim_num: int = 1000,
                  despot_runs: int = 20) -> dict:
    """Print and return our solvers side by side with the live peers (module docstring)."""
    where = ", ".join(f"{name}={os.environ.get(name) or '(not set: no figure)'}"
                      for name in ("SARSOP_BIN", "DESPOT_BIN"))
    print(f"Against the reference solvers, run here and now ({where}; load average "
          f"{load_average()}):", flush=True)
    floor = start_up_floor(max(runs, 3))
    print("  start-up floor (median wall s): " + ", ".join(f"{k} {v:.3f}" for k, v in
                                                          floor.items()), flush=True)
    print(f"  {'model, precision 1e-3 (wall s, medians)':<42} {'solve':>7} {'hrc_pomdp':>9} "
          f"{'pomdpsol':>9} {'whole/':>9} {'solve/':>9}   bounds: ours vs pomdpsol",
          flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        rows = solver_times(runs, work)
        for row in rows:
            print(solver_line(row), flush=True)
        sims = simulators(work, sim_num, despot_runs)
        for line in simulator_lines(sims, sim_num, despot_runs):
            print(line, flush=True)
    rock = None
    if rocksample_seconds:
        rock = rocksample_solve(rocksample_seconds)
        print(rocksample_line(rock), flush=True)
    types = []
    if types_seconds:
        for path in TYPES_MODELS:
            types.append(types_solve(path, types_seconds))
            for line in types_lines(types[-1]):
                print(line, flush=True)
    print(f"  load average after: {load_average()}", flush=True)
    return {"load_average_after": load_average(), "start_up_floor_s": floor,
            "solver_models": rows, "simulators": sims, "rocksample_7_8": rock,
            "robot_types": types}


def types_only(seconds: float, results: Path) -> int:
    """The models of human types alone, beside pomdpsol: prints them, writes
    pomdp_types.json."""
    print(f"Offline solvers on the robot models of human types (precision 1e-3; SARSOP_BIN="
          f"{os.environ.get('SARSOP_BIN') or '(not set: no figure)'}; load average "
          f"{load_average()}):", flush=True)
    rows = []
    for path in TYPES_MODELS:
        rows.append(types_solve(path, seconds))
        for line in types_lines(rows[-1]):
            print(line, flush=True)
    print(f"  load average after: {load_average()}", flush=True)
    results.mkdir(parents=True, exist_ok=True)
    (results / "pomdp_types.json").write_text(json.dumps(
        {"benchmark": "pomdp: the robot models of human types beside pomdpsol",
         "when": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "load_average_after": load_average(),
         "models": rows}, indent=2) + "\n")
    print(f"wrote {results / 'pomdp_types.json'}")
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description="POMDP toolkit benchmark.")
    parser.add_argument("--quick", action="store_true",
                        help="fewer runs and looser solves (well under a minute)")
    parser.add_argument("--tiger-runs", type=int, default=None,
                        help="runs of the Tiger DESPOT score (default 100, 20 with --quick)")
    parser.add_argument("--no-rocksample", action="store_true", help="skip RockSample_7_8")
    parser.add_argument("--peers-only", action="store_true",
                        help="only our solvers and simulators side by side with the live "
                             "peers (SARSOP_BIN, DESPOT_BIN: issue #39)")
    parser.add_argument("--solver-runs", type=int, default=3,
                        help="interleaved runs per model of the solvers' timing (default 3)")
    parser.add_argument("--types-only", action="store_true",
                        help="only the solvers on the models of human types (issue #31)")
    parser.add_argument("--types-seconds", type=float, default=None,
                        help="each solver's budget on a model of human types (default 120, "
                             "20 with --quick)")
    args = parser.parse_args(argv)
    results = ROOT / "bench" / "results"
    types_seconds = args.types_seconds or (20.0 if args.quick else 120.0)
    if args.types_only:
        return types_only(types_seconds, results)
    against = against_peers(1 if args.quick else args.solver_runs,
                            None if args.no_rocksample else (5.0 if args.quick else 30.0),
                            types_seconds, sim_num=100 if args.quick else 1000,
                            despot_runs=5 if args.quick else 20)
    if args.peers_only:
        results.mkdir(parents=True, exist_ok=True)
        (results / "pomdp_peers.json").write_text(json.dumps(
            {"benchmark": "pomdp beside the live peers",
             "when": time.strftime("%Y-%m-%dT%H:%M:%S%z"), **against}, indent=2) + "\n")
        print(f"wrote {results / 'pomdp_peers.json'}")
        return 0

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

    budget_decisions = 20 if args.quick else 40
    budget = []
    for label, path in (("Tiger", ROOT / "test" / "fixtures" / "tiger.95.pomdp"),
                        ("robot.pomdp", ROOT / "models" / "robot" / "robot.pomdp")):
        model = load_model(path)
        budget.append(despot_budget(label, model, DespotTables(model), BUDGET_TIME_PER_STEP,
                                    budget_decisions))

    rock = None
    if not args.no_rocksample:
        steps = 3 if args.quick else 8
        print(f"RockSample_7_8: DESPOT, 1 s per step, {steps} steps ...", flush=True)
        rock, rock_budget = rocksample(steps, budget_decisions)
        budget.append(rock_budget)
        print(f"  {rock['states']} states, parse {rock['parse_s']:.2f} s, bounds "
              f"{rock['despot_tables_s']:.2f} s, {rock['particles']} particles, ms per decision "
              f"p50 {rock['ms_p50']:.0f} / p99 {rock['ms_p99']:.0f}, "
              f"discounted reward {rock['discounted_reward']:.2f}")
    for row in budget:
        print(budget_line(row), flush=True)

    out = {"benchmark": "pomdp", "when": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
           "quick": args.quick, "against_peers": against, "models": rows,
           "tiger_despot": score, "rocksample_7_8": rock,
           "despot_decision_budget": budget,
           "environment": {"python": platform.python_version(), "numpy": np.__version__,
                           "cpus": os.cpu_count(), "machine": platform.machine()}}
    results.mkdir(parents=True, exist_ok=True)
    (results / "pomdp.json").write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {results / 'pomdp.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
