"""``hrc_pomdp simulate``: the expected total discounted reward of a saved policy, of value
iteration or of DESPOT, over runs from the initial belief, as SARSOP's pomdpsim measures it.
Registered by :mod:`ros_hrc.commands.pomdp`.
"""
from __future__ import annotations

import argparse
import math
import time
from typing import TYPE_CHECKING, Optional, Tuple

from ros_hrc.streams import MAX_SEED
from ros_hrc.commands.pomdp_common import (MAX_RUNS, MODEL_HELP, add_memory_limit,
                                           despot_option, emit, load_with_progress, progress,
                                           run_count_arg, seed_arg, solver_errors_exit_2)
from ros_hrc.errors import SolverError
from ros_hrc.pomdp import memory

if TYPE_CHECKING:
    from ros_hrc.pomdp.model import Model


def register_simulate(subparsers) -> None:
    p = subparsers.add_parser(
        "simulate", help="expected total discounted reward of a policy or of DESPOT",
        description="Simulate MODEL like SARSOP's pomdpsim: SIM-NUM runs of SIM-LEN steps from "
                    "the initial belief, true states drawn from T, observations from O, rewards "
                    "R(s,a,s') discounted. With fully observable state variables (POMDPX "
                    "fullyObs, mixed observability) the planner knows their values from the "
                    "first step, as in SARSOP: it starts from the initial belief conditioned on "
                    "the start state's fully observable values (an MDP: on the start state). "
                    "Prints the mean total with its 95 % confidence interval "
                    "(mean +/- 1.96 sd / sqrt(runs)), the reward estimator it used, and the "
                    "planner's time per step. A saved policy and --planner mdp run all runs "
                    "at once (their beliefs as one array); DESPOT runs them one by one.")
    p.add_argument("model", help=MODEL_HELP)
    how = p.add_mutually_exclusive_group(required=True)
    how.add_argument("--policy", metavar="POLICY", help="a policy file written by 'solve -o'")
    how.add_argument("--planner", choices=["despot", "mdp"],
                     help="plan online: DESPOT, or value iteration for a fully observable model")
    p.add_argument("--sim-len", type=run_count_arg, required=True, metavar="N",
                   help=f"steps per run (1 to {MAX_RUNS}; N x M at most {MAX_RUNS})")
    p.add_argument("--sim-num", type=run_count_arg, required=True, metavar="M",
                   help=f"number of runs (1 to {MAX_RUNS})")
    p.add_argument("--seed", type=seed_arg, default=0, metavar="K",
                   help=f"random seed, 0 to {MAX_SEED} (default 0)")
    p.add_argument("--lookahead", action="store_true",
                   help="policy: choose by one-step lookahead over the policy's values")
    p.add_argument("--estimator", choices=["realised", "expected"], default="realised",
                   help="sum the realised rewards R(s,a,s') (default), or the expected "
                        "rewards R(s,a) at the visited states, as SARSOP's pomdpsim does: "
                        "the same mean, a narrower interval when rewards depend on s'")
    d = p.add_argument_group("DESPOT (--planner despot)", "its parameters, as the launch "
                             "arguments of the same names take them")
    for name, metavar in (("time_per_step", "S"), ("scenarios", "K"), ("depth", "D"),
                          ("lambda", "L"), ("xi", "X"), ("max_trials", "N"), ("upper", None),
                          ("lower", None), ("particles", "N")):
        despot_option(d, name, metavar)
    p.add_argument("--json", action="store_true",
                   help="print one JSON object (mean, ci95_low, ci95_high, ms_per_step, ...)")
    add_memory_limit(p)
    p.set_defaults(func=cmd_simulate, check=_check_simulate)


def _check_simulate(args: argparse.Namespace) -> Optional[Tuple[str, str]]:
    """What the options of ``simulate`` cannot be together: (option, message) or None."""
    if args.sim_len * args.sim_num > MAX_RUNS:
        return "--sim-num", (f"SIM-LEN x SIM-NUM must be at most {MAX_RUNS} steps, got "
                             f"{args.sim_len} x {args.sim_num}")
    return None


def duration(ms: float) -> str:
    """A duration of ``ms`` milliseconds in the unit that shows three significant digits
    (``12.3 ms``, ``845 µs``, ``90.2 ns``); 0 is ``0 ms``."""
    for unit, scale in (("s", 1e-3), ("ms", 1.0), ("µs", 1e3), ("ns", 1e6)):
        value = ms * scale
        if value >= 1.0 or unit == "ns":
            break
    if value == 0:
        return "0 ms"
    return f"{value:.3g} {unit}"


def _batch_chooser(model: Model, args: argparse.Namespace, used: int):
    """(chooser, label) for the planners that only choose from the belief (a saved policy,
    --planner mdp), whose runs go all at once; (None, None) for DESPOT."""
    from ros_hrc.pomdp.planner import MdpPlanner
    from ros_hrc.pomdp.policy import load as load_policy
    from ros_hrc.pomdp.simulate import batch_memory_needed, policy_chooser, q_chooser

    source, limit = args.model, args.memory_limit
    used += batch_memory_needed(model, args.sim_num, lookahead=bool(args.lookahead))
    memory.require(used, limit, source, f"simulating {args.sim_num} runs at once")
    if args.policy:
        policy = load_policy(args.policy, model, memory_limit=limit, memory_in_use=used)
        if policy.kind == "mdp":
            return q_chooser(MdpPlanner.from_policy(model, policy).Q), \
                f"policy {args.policy} (MDP)"
        label = f"policy {args.policy}" + (" (one-step lookahead)" if args.lookahead else "")
        return policy_chooser(model, policy, args.lookahead), label
    if args.planner == "mdp":
        return q_chooser(_mdp_solution(model, used, limit, source).Q), "value iteration (MDP)"
    return None, None


def _mdp_solution(model: Model, used: int, limit: Optional[int], source: str):
    """Value iteration for ``--planner mdp``: refused for a POMDP and beyond the memory limit
    (``used`` bytes taken already)."""
    from ros_hrc.pomdp.offline import mdp_memory_needed
    from ros_hrc.pomdp.planner import MdpPlanner
    if not model.fully_observable:
        raise SolverError("--planner mdp is for fully observable models; use despot or "
                          "a policy from 'solve'")
    memory.require(used + mdp_memory_needed(model), limit, source,
                   "simulating with value iteration")
    return MdpPlanner(model).solution


#: What each reward estimator sums, as the output names it.
_ESTIMATOR_WORDS = {"realised": "realised rewards R(s,a,s')",
                    "expected": "expected rewards R(s,a), as pomdpsim"}


def _planner_factory(model: Model, args: argparse.Namespace, used: int):
    """A function run_seed -> planner, with the expensive tables built once; and its label.
    ``used``: bytes the model and the simulation take already, out of ``--memory-limit``."""
    from ros_hrc.pomdp import despot
    from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner, DespotTables
    from ros_hrc.pomdp.despot_parameters import DESPOT_PARAMETERS, config_value
    from ros_hrc.pomdp.planner import MdpPlanner, PolicyPlanner
    from ros_hrc.pomdp.policy import load as load_policy

    source, limit = args.model, args.memory_limit
    if args.policy:
        policy = load_policy(args.policy, model, memory_limit=limit, memory_in_use=used)
        if policy.kind == "mdp":
            return (lambda seed: MdpPlanner.from_policy(model, policy, seed)), \
                f"policy {args.policy} (MDP)"
        label = f"policy {args.policy}" + (" (one-step lookahead)" if args.lookahead else "")
        return (lambda seed: PolicyPlanner(model, policy, seed, args.lookahead)), label
    if args.planner == "mdp":
        solution = _mdp_solution(model, used, limit, source)
        return (lambda seed: MdpPlanner(model, solution, seed)), "value iteration (MDP)"
    config = DespotConfig(**{p.field: config_value(p.name, getattr(args, p.field))
                             for p in DESPOT_PARAMETERS})
    config.validate()
    fixed = used + despot.memory_needed(model, config)
    memory.require(fixed + 1000 * despot.BYTES_PER_NODE, limit, source,
                   f"simulating with DESPOT ({config.scenarios} scenarios, depth "
                   f"{config.depth})")
    # What is left is the tree's: a search stops growing it there.
    config.max_nodes = int((limit - fixed) // despot.BYTES_PER_NODE)
    progress("precomputing DESPOT's bounds ...")
    tables = DespotTables(model, config.upper, config.lower)
    budget = (f"{config.time_per_step:g} s per step" if math.isfinite(config.time_per_step)
              else "no time budget")
    label = (f"DESPOT ({budget}, K={config.scenarios}, D={config.depth}, "
             f"lambda={config.pruning:g}"
             + (f", at most {config.max_trials} trials" if config.max_trials is not None
                else "")
             + ")")
    return (lambda seed: DespotPlanner(model, config, seed, tables=tables)), label


@solver_errors_exit_2
def cmd_simulate(args: argparse.Namespace) -> int:
    """``hrc_pomdp simulate MODEL (--policy P | --planner despot|mdp) --sim-len N --sim-num M``."""
    from ros_hrc.pomdp.simulate import memory_needed, simulate, simulate_batch

    model = load_with_progress(args.model, args.memory_limit)
    used = memory.model_bytes(model) + memory_needed(model, args.sim_len, args.sim_num)
    memory.require(used, args.memory_limit, args.model,
                   f"simulating {args.sim_num} runs of {args.sim_len} steps")
    chooser, label = _batch_chooser(model, args, used)
    if chooser is None:
        factory, label = _planner_factory(model, args, used)
    shown = [time.perf_counter()]

    def show(done: int, mean: float) -> None:
        now = time.perf_counter()
        if now - shown[0] >= 1.0 or done == args.sim_num:
            shown[0] = now
            value = -mean if model.minimise else mean
            progress(f"run {done}/{args.sim_num}: mean {value:.6g}")

    if chooser is not None:
        result = simulate_batch(model, chooser, args.sim_len, args.sim_num, args.seed,
                                progress=show, estimator=args.estimator)
    else:
        result = simulate(model, factory, args.sim_len, args.sim_num, args.seed,
                          progress=show, estimator=args.estimator)
    facts = result.as_dict()
    if model.minimise:
        facts["mean"], facts["ci95_low"], facts["ci95_high"] = (
            -result.mean, -result.ci95_high, -result.ci95_low)
        facts["undiscounted_mean"] = -result.undiscounted_mean
    facts.update({"model": args.model, "planner": label, "sim_len": args.sim_len,
                  "sim_num": args.sim_num, "seed": args.seed,
                  "values": "cost" if model.minimise else "reward"})

    def print_text(facts: dict) -> None:
        print(f"{args.model}: {label}, {args.sim_num} runs x {args.sim_len} steps, "
              f"seed {args.seed}")
        print(f"  expected total discounted {facts['values']}  {facts['mean']:.6g}   95% CI "
              f"({facts['ci95_low']:.6g}, {facts['ci95_high']:.6g})")
        print(f"  estimator      {args.estimator}: the mean of the runs' discounted sums of "
              f"{_ESTIMATOR_WORDS[args.estimator]}")
        # A saved policy's choice takes microseconds: a fixed "ms" with 3 decimals printed 0.000.
        batch = "; the runs step together, each step's time shared among them" \
            if result.batched else ""
        print(f"  time per step  {duration(result.ms_per_step)} (act p50 "
              f"{duration(result.ms_act_p50)}, p99 {duration(result.ms_act_p99)}{batch})")
        if result.zero_probability_events:
            print(f"  {result.zero_probability_events} observation(s) of probability zero: the "
                  "belief kept its prediction")

    return emit(facts, args.json, print_text)
