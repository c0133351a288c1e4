"""Policy evaluation by simulation, like SARSOP's ``pomdpsim``.

Each run draws a true start state from the initial belief and resets the planner to
``model.start_belief(state)``: with mixed observability (POMDPX ``fullyObs`` variables) the fully
observed part of the state is known from the first step, as in SARSOP, so the planner starts from
the initial belief conditioned on it (an MDP: a point mass on the start state); a plain POMDP
starts from the initial belief itself. Then for ``sim_len`` steps it asks the planner for an
action, draws s' ~ T(.|s,a) and o ~ O(.|s',a), collects the realised reward R(s,a,s')
discounted by γ^t, and tells the planner (a, o). The result is the mean discounted total over
``sim_num`` runs with its 95 % confidence interval, mean ± 1.96·sd/√n (sd the sample standard
deviation), and the time the planner took per step.

Seeds: one ``numpy.random.SeedSequence(seed)`` is split into one child per run; a run's child
seeds both the world's random stream and the planner (``planner_factory(run_seed)``), so a run is
reproducible on its own and the whole simulation is reproducible from ``seed`` (up to planners
whose search is cut by wall-clock time).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Optional, Tuple

import numpy as np

from ros_hrc.errors import SolverError
from ros_hrc.pomdp import sampling
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.planner import Planner
from ros_hrc.pomdp.sampling import ModelSampler

#: z value of a two-sided 95 % normal interval.
Z95 = 1.96


@dataclass
class SimulationResult:
    """Summary of a simulation (rewards; for a cost model, costs are these negated)."""

    mean: float
    ci95_low: float
    ci95_high: float
    std: float
    runs: int
    steps: int
    ms_per_step: float                     # planner time (act + update) per step, mean
    ms_act_p50: float                      # act() alone, median
    ms_act_p99: float                      # act() alone, 99th percentile
    undiscounted_mean: float
    zero_probability_events: int
    returns: np.ndarray = field(repr=False)

    def as_dict(self) -> dict:
        """JSON-friendly fields (without the per-run returns)."""
        return {"mean": self.mean, "ci95_low": self.ci95_low, "ci95_high": self.ci95_high,
                "std": self.std, "runs": self.runs, "steps": self.steps,
                "ms_per_step": self.ms_per_step, "ms_act_p50": self.ms_act_p50,
                "ms_act_p99": self.ms_act_p99, "undiscounted_mean": self.undiscounted_mean,
                "zero_probability_events": self.zero_probability_events}


def confidence_interval(values: np.ndarray) -> Tuple[float, float, float, float]:
    """(mean, low, high, sd): mean ± 1.96·sd/√n with the sample (n-1) standard deviation."""
    x = np.asarray(values, dtype=float)
    n = x.size
    if n == 0:
        raise SolverError("no values to summarise")
    mean = float(x.mean())
    sd = float(x.std(ddof=1)) if n > 1 else 0.0
    half = Z95 * sd / math.sqrt(n)
    return mean, mean - half, mean + half, sd


def memory_needed(model: Model, sim_len: int, sim_num: int) -> int:
    """Bytes a simulation needs besides its planner: the world's sampler, every step's act()
    time (for the percentiles) and one run's uniforms as Python floats."""
    return sampling.memory_needed(model) + 8 * sim_len * sim_num + 160 * sim_len


def simulate(model: Model, planner_factory: Callable[[int], Planner], sim_len: int,
             sim_num: int, seed: int = 0,
             progress: Optional[Callable[[int, float], None]] = None) -> SimulationResult:
    """Run ``sim_num`` simulations of ``sim_len`` steps; see the module docstring.

    ``planner_factory(run_seed)`` returns a planner for one run (it may share precomputed
    tables between runs); ``progress(runs_done, mean_so_far)`` is called after each run.
    """
    if sim_len < 1 or sim_num < 1:
        raise SolverError(f"sim_len and sim_num must be positive (got {sim_len}, {sim_num})")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SolverError(f"the seed must be an integer >= 0, got {seed!r}")
    sampler = ModelSampler(model)
    gamma = float(model.discount)
    children = np.random.SeedSequence(seed).spawn(sim_num)
    returns = np.empty(sim_num)
    undiscounted = np.empty(sim_num)
    act_times = np.empty(sim_num * sim_len)
    planner_time = 0.0
    zero_events = 0
    k = 0
    for run, child in enumerate(children):
        world = np.random.default_rng(child)
        planner = planner_factory(int(child.generate_state(1)[0]))
        state = int(sampler.sample_initial(world, 1)[0])
        # The fully observed variables are seen before the first action (mixed observability).
        planner.reset(model.start_belief(state))
        u = world.random((sim_len, 2)).tolist()
        total = 0.0
        plain = 0.0
        disc = 1.0
        for t in range(sim_len):
            t0 = time.perf_counter()
            action = planner.act()
            t1 = time.perf_counter()
            state, obs, reward = sampler.step1(state, action, u[t][0], u[t][1])
            t2 = time.perf_counter()
            planner.update(action, obs)
            t3 = time.perf_counter()
            act_times[k] = t1 - t0
            k += 1
            planner_time += (t1 - t0) + (t3 - t2)
            total += disc * reward
            plain += reward
            disc *= gamma
        returns[run] = total
        undiscounted[run] = plain
        zero_events += getattr(planner, "zero_probability_events", 0)
        if progress is not None:
            progress(run + 1, float(returns[:run + 1].mean()))
    mean, lo, hi, sd = confidence_interval(returns)
    steps = sim_num * sim_len
    return SimulationResult(mean=mean, ci95_low=lo, ci95_high=hi, std=sd, runs=sim_num,
                            steps=steps, ms_per_step=1000.0 * planner_time / steps,
                            ms_act_p50=1000.0 * float(np.percentile(act_times, 50)),
                            ms_act_p99=1000.0 * float(np.percentile(act_times, 99)),
                            undiscounted_mean=float(undiscounted.mean()),
                            zero_probability_events=zero_events, returns=returns)
