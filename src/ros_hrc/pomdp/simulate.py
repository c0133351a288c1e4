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

Two estimators of the same mean (``estimator``): ``"realised"`` sums the rewards R(s,a,s') the
runs collect; ``"expected"`` sums the expected rewards R(s,a) = Σ_s' T(s'|s,a) R(s,a,s') at the
states the runs visit, as SARSOP's ``pomdpsim`` does. The second has no variance from the draw
of s' inside a step's reward, so its interval is narrower. The result names the one it used.

:func:`simulate_batch` runs a planner that needs no search, a choice of action from the belief
(a saved policy, with or without one-step lookahead, or an MDP's Q), on all runs at once: the
beliefs of many runs are one array, updated together. Its runs draw from one stream per block of
runs (:data:`BATCH_NUMBERS`), so its totals differ from :func:`simulate`'s for the same seed,
while their distribution is the same.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, List, Optional, Tuple

import numpy as np

from ros_hrc.errors import SolverError
from ros_hrc.pomdp import sampling
from ros_hrc.pomdp.belief import ZERO_PROBABILITY
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.planner import Planner
from ros_hrc.pomdp.policy import Policy
from ros_hrc.pomdp.sampling import ModelSampler

#: z value of a two-sided 95 % normal interval.
Z95 = 1.96

#: The reward estimators (see the module docstring).
ESTIMATORS = ("realised", "expected")

#: Numbers of the largest belief array a batched simulation holds at once (runs x states, and
#: runs x actions x observations x states for a lookahead): 32 MB. Runs go in blocks that fit.
BATCH_NUMBERS = 4_000_000


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
    estimator: str = "realised"            # which rewards were summed (module docstring)
    batched: bool = False                  # runs simulated together (simulate_batch)

    def as_dict(self) -> dict:
        """JSON-friendly fields (without the per-run returns)."""
        return {"mean": self.mean, "ci95_low": self.ci95_low, "ci95_high": self.ci95_high,
                "std": self.std, "runs": self.runs, "steps": self.steps,
                "ms_per_step": self.ms_per_step, "ms_act_p50": self.ms_act_p50,
                "ms_act_p99": self.ms_act_p99, "undiscounted_mean": self.undiscounted_mean,
                "zero_probability_events": self.zero_probability_events,
                "estimator": self.estimator, "batched": self.batched}


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


def batch_memory_needed(model: Model, sim_num: int, lookahead: bool = False) -> int:
    """Bytes :func:`simulate_batch` needs besides the policy: the sampler and a block of
    beliefs with its updates (three arrays of runs x states), and a lookahead's chunk."""
    S = model.n_states
    block = max(1, min(sim_num, BATCH_NUMBERS // max(S, 1)))
    extra = 8 * 2 * BATCH_NUMBERS if lookahead else 0
    return sampling.memory_needed(model) + 8 * 3 * block * S + 8 * 4 * sim_num + extra


def _check_arguments(sim_len: int, sim_num: int, seed, estimator: str) -> None:
    if sim_len < 1 or sim_num < 1:
        raise SolverError(f"sim_len and sim_num must be positive (got {sim_len}, {sim_num})")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise SolverError(f"the seed must be an integer >= 0, got {seed!r}")
    if estimator not in ESTIMATORS:
        raise SolverError(f"the estimator must be one of {', '.join(ESTIMATORS)}, "
                          f"got {estimator!r}")


def simulate(model: Model, planner_factory: Callable[[int], Planner], sim_len: int,
             sim_num: int, seed: int = 0,
             progress: Optional[Callable[[int, float], None]] = None,
             estimator: str = "realised") -> SimulationResult:
    """Run ``sim_num`` simulations of ``sim_len`` steps; see the module docstring.

    ``planner_factory(run_seed)`` returns a planner for one run (it may share precomputed
    tables between runs); ``progress(runs_done, mean_so_far)`` is called after each run.
    ``estimator``: ``"realised"`` or ``"expected"`` rewards (module docstring).
    """
    _check_arguments(sim_len, sim_num, seed, estimator)
    expected = estimator == "expected"
    R_sa = np.asarray(model.R_sa, dtype=float).tolist() if expected else None
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
            if expected:
                reward = R_sa[action][state]
                state, obs, _ = sampler.step1(state, action, u[t][0], u[t][1])
            else:
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
                            zero_probability_events=zero_events, returns=returns,
                            estimator=estimator)


# --------------------------------------------------------------------------------------------
# Many runs at once
# --------------------------------------------------------------------------------------------
#: A batch chooser: beliefs (n, S) to actions (n,).
Chooser = Callable[[np.ndarray], np.ndarray]


def policy_chooser(model: Model, policy: Policy, lookahead: bool = False) -> Chooser:
    """Actions of a saved policy at many beliefs at once: the action of the best vector, or
    with ``lookahead`` SARSOP's one-step lookahead R(b,a) + γ Σ_o max_i α_i·(b T_a O_ao)
    (small models only, as :class:`~ros_hrc.pomdp.planner.PolicyPlanner`'s)."""
    policy.check(model)
    alphas, actions = policy.alphas, policy.actions
    if not lookahead:
        return lambda B: actions[np.argmax(B @ alphas.T, axis=1)]
    if not model.dense_tables_fit:
        raise SolverError("one-step lookahead is only for small models (dense T and O)")
    T = model.dense_T                                                 # (A, S, S')
    OT = np.transpose(model.dense_O, (0, 2, 1))                       # (A, Z, S')
    R, gamma = np.asarray(model.R_sa, dtype=float), float(model.discount)
    A, Z, S = OT.shape
    rows = max(1, BATCH_NUMBERS // (A * Z * S))

    def choose(B: np.ndarray) -> np.ndarray:
        out = np.empty(B.shape[0], dtype=np.int64)
        for lo in range(0, B.shape[0], rows):
            x = B[lo:lo + rows]
            joint = np.einsum("ns,ast->nat", x, T)[:, :, None, :] * OT[None]   # (n, A, Z, S')
            future = (joint @ alphas.T).max(axis=3).sum(axis=2)
            out[lo:lo + rows] = np.argmax(x @ R.T + gamma * future, axis=1)
        return out

    return choose


def q_chooser(Q: np.ndarray) -> Chooser:
    """The action maximising b·Q[a] at many beliefs (an MDP's Q: the greedy action at a point
    mass), as :class:`~ros_hrc.pomdp.planner.MdpPlanner` chooses."""
    return lambda B: np.argmax(B @ Q.T, axis=1)


class _BatchFilter:
    """Bayes updates of many beliefs at once, each with its own action and observation."""

    def __init__(self, model: Model) -> None:
        self.dense = model.dense_tables_fit
        if self.dense:
            self.T = model.dense_T                                      # (A, S, S')
            self.OT = np.transpose(model.dense_O, (0, 2, 1)).copy()     # (A, Z, S')
        else:
            self.T = model.T
            self.OT = [o.T.tocsr() for o in model.O]                    # (Z, S') each

    def update(self, B: np.ndarray, actions: np.ndarray, obs: np.ndarray) -> int:
        """B (n, S) becomes the beliefs after (actions, obs), in place. A run whose
        observation has probability zero under its belief keeps the prediction through T (as
        the planners do); returns how many did."""
        out = np.empty_like(B)
        zero = 0
        for a in np.unique(actions):
            rows = np.flatnonzero(actions == a)
            if self.dense:
                pred = B[rows] @ self.T[a]
                like = self.OT[a][obs[rows]]
            else:
                pred = np.asarray((self.T[a].T @ B[rows].T).T)
                like = self.OT[a][obs[rows]].toarray()
            joint = pred * like
            mass = joint.sum(axis=1)
            ok = mass > ZERO_PROBABILITY
            zero += int((~ok).sum())
            out[rows] = np.where(ok[:, None], joint / np.where(ok, mass, 1.0)[:, None], pred)
        B[:] = out
        return zero


def simulate_batch(model: Model, choose: Chooser, sim_len: int, sim_num: int, seed: int = 0,
                   progress: Optional[Callable[[int, float], None]] = None,
                   estimator: str = "realised") -> SimulationResult:
    """Like :func:`simulate` for a planner that only chooses from the belief (``choose``: see
    :func:`policy_chooser`, :func:`q_chooser`), with all runs' beliefs as one array.

    Runs go in blocks of at most :data:`BATCH_NUMBERS` belief numbers; block k draws its start
    states and every step's uniforms from child k of ``SeedSequence(seed)``, so the result is
    reproducible from ``seed``. Time per step is the choice and the belief update of a block
    divided by its runs; ``ms_act_p50``/``p99`` are over steps of the mean choice time per run.
    ``progress(runs_done, mean_so_far)`` is called after each block.
    """
    _check_arguments(sim_len, sim_num, seed, estimator)
    sampler = ModelSampler(model)
    belief_filter = _BatchFilter(model)
    gamma = float(model.discount)
    R_sa = np.asarray(model.R_sa, dtype=float)
    S = model.n_states
    block = max(1, min(sim_num, BATCH_NUMBERS // max(S, 1)))
    starts = list(range(0, sim_num, block))
    children = np.random.SeedSequence(seed).spawn(len(starts))
    returns = np.empty(sim_num)
    undiscounted = np.empty(sim_num)
    act_ms: List[float] = []
    planner_time = 0.0
    zero_events = 0
    for lo, child in zip(starts, children):
        n = min(block, sim_num - lo)
        world = np.random.default_rng(child)
        states = sampler.sample_initial(world, n)
        B = np.array([model.start_belief(int(s)) for s in states]).reshape(n, S)
        total = np.zeros(n)
        plain = np.zeros(n)
        disc = 1.0
        for _ in range(sim_len):
            u = world.random((2, n))
            t0 = time.perf_counter()
            actions = np.asarray(choose(B), dtype=np.int64)
            t1 = time.perf_counter()
            nxt, obs, realised = sampler.step(states, actions, u[0], u[1])
            reward = R_sa[actions, states] if estimator == "expected" else realised
            t2 = time.perf_counter()
            zero_events += belief_filter.update(B, actions, obs)
            t3 = time.perf_counter()
            act_ms.append(1000.0 * (t1 - t0) / n)
            planner_time += (t1 - t0) + (t3 - t2)
            total += disc * reward
            plain += reward
            disc *= gamma
            states = nxt
        returns[lo:lo + n] = total
        undiscounted[lo:lo + n] = plain
        if progress is not None:
            progress(lo + n, float(returns[:lo + n].mean()))
    mean, low, high, sd = confidence_interval(returns)
    steps = sim_num * sim_len
    return SimulationResult(mean=mean, ci95_low=low, ci95_high=high, std=sd, runs=sim_num,
                            steps=steps, ms_per_step=1000.0 * planner_time / steps,
                            ms_act_p50=float(np.percentile(act_ms, 50)),
                            ms_act_p99=float(np.percentile(act_ms, 99)),
                            undiscounted_mean=float(undiscounted.mean()),
                            zero_probability_events=zero_events, returns=returns,
                            estimator=estimator, batched=True)
