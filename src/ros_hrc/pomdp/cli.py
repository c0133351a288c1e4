"""``hrc_pomdp``: look at, convert, solve and simulate (PO)MDP model files.

::

    hrc_pomdp info MODEL [--json]      sizes, discount, MDP or POMDP, the checks that passed
    hrc_pomdp convert IN OUT           .pomdp <-> .pomdpx (by extension), round-trip exact
    hrc_pomdp solve MODEL [--timeout S] [--precision E] [-o POLICY] [--json]
    hrc_pomdp simulate MODEL (--policy POLICY | --planner despot|mdp [--time-per-step S])
                       --sim-len N --sim-num M [--seed K] [--json]

Exit status: 0 done; 2 the command line is wrong, or a model file is malformed or
inconsistent -- then one line on standard error, ``hrc_pomdp: <file>:<line>: <what>``, never
a traceback; 1 any other failure the user can act on (a file that cannot be written).
Progress goes to standard error, and only when it is a terminal.

Adding a subcommand (``solve``, ``simulate``): write ``_register_<name>(subparsers)`` that
adds the subparser and ``set_defaults(func=<handler>)``, a handler ``(args) -> int`` (the exit
status), and append the register function to :data:`SUBCOMMANDS`. Errors of the package
(:class:`~ros_hrc.errors.HrcError`) raised by a handler are reported by :func:`run`.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Callable, List, Optional, Sequence, TextIO, Tuple

import numpy as np

from ros_hrc.errors import HrcError, ModelError, ModelFormatError, SolverError
from ros_hrc.pomdp import io
from ros_hrc.pomdp.model import PROBABILITY_TOLERANCE, Model

PROG = "hrc_pomdp"

#: What every model that loads has passed (the parsers and Model.validate check them).
CHECKS = ["names known and unique", "table sizes agree", "discount in [0, 1)",
          f"no negative probability; rows of T and O sum to 1 (within {PROBABILITY_TOLERANCE:g})",
          "initial belief sums to 1"]


def progress(message: str, stream: Optional[TextIO] = None) -> None:
    """Show a progress line on a terminal only, so pipes, logs and --json output stay clean."""
    stream = stream if stream is not None else sys.stderr
    if stream.isatty():
        print(f"{PROG}: {message}", file=stream, flush=True)


def load_with_progress(path: str) -> Model:
    """Load a model file, saying so on a terminal (large models take a moment)."""
    progress(f"reading {path} ...")
    return io.load_model(path)


def model_kind(model: Model) -> str:
    """``MDP``, ``MOMDP`` (POMDPX with fully and partially observable variables) or ``POMDP``."""
    if model.fully_observable:
        return "MDP"
    variables = (model.meta or {}).get("pomdpx", {}).get("state_variables", [])
    if any(v.get("fully_observable") for v in variables):
        return "MOMDP"
    return "POMDP"


def describe(model: Model, path: str, seconds: float) -> dict:
    """The facts ``info`` prints, as a JSON-ready dict."""
    b = np.asarray(model.initial_belief)
    support = np.flatnonzero(b)
    r = model.R_sa
    return {
        "file": path, "format": io.format_of(path), "name": model.name, "kind": model_kind(model),
        "states": model.n_states, "actions": model.n_actions,
        "observations": model.n_observations, "discount": model.discount,
        "values": "cost" if model.minimise else "reward",
        "fully_observable": bool(model.fully_observable), "minimise": bool(model.minimise),
        "nonzeros": {"T": int(sum(t.nnz for t in model.T)), "O": int(sum(o.nnz for o in model.O)),
                     "R": int(sum(x.nnz for x in model.R))},
        "initial_support": int(support.size),
        "initial_states": [model.states[i] for i in support[:10]],
        "reward_range": [float(r.min()), float(r.max())] if r.size else [0.0, 0.0],
        "action_names": list(model.actions),
        "checks": list(CHECKS), "checks_passed": True, "seconds": round(seconds, 4),
    }


def _print_info(facts: dict, out: TextIO) -> None:
    kind = {"MDP": "MDP (fully observable)", "MOMDP": "POMDP (mixed observability)",
            "POMDP": "POMDP"}[facts["kind"]]
    start = ", ".join(facts["initial_states"][:3])
    if facts["initial_support"] > 3:
        start += ", ..."
    nz = facts["nonzeros"]
    rows = [("format", facts["format"]), ("kind", kind), ("states", facts["states"]),
            ("actions", f"{facts['actions']}: {' '.join(facts['action_names'][:12])}"
                        + (" ..." if facts["actions"] > 12 else "")),
            ("observations", facts["observations"]), ("discount", facts["discount"]),
            ("values", facts["values"]),
            ("start", f"{facts['initial_support']} state(s): {start}"),
            ("R(s,a) range", f"{facts['reward_range'][0]:g} .. {facts['reward_range'][1]:g}"),
            ("nonzeros", f"T {nz['T']}, O {nz['O']}, R {nz['R']}"),
            ("read in", f"{facts['seconds']:.3f} s")]
    print(facts["file"], file=out)
    for key, value in rows:
        print(f"  {key:<13} {value}", file=out)
    print("  checks passed:", file=out)
    for check in facts["checks"]:
        print(f"    - {check}", file=out)


# --------------------------------------------------------------------------------------------
# Subcommands
# --------------------------------------------------------------------------------------------
def _register_info(subparsers) -> None:
    p = subparsers.add_parser("info", help="sizes, discount, kind and checks of a model file",
                              description="Read a .pomdp or .pomdpx file, check it and "
                                          "describe it.")
    p.add_argument("model", help="a .pomdp (Cassandra) or .pomdpx (POMDPX) file")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_info)


def cmd_info(args: argparse.Namespace) -> int:
    """``hrc_pomdp info MODEL [--json]``."""
    start = time.perf_counter()
    model = load_with_progress(args.model)
    facts = describe(model, args.model, time.perf_counter() - start)
    if args.json:
        print(json.dumps(facts))
    else:
        _print_info(facts, sys.stdout)
    return 0


def _register_convert(subparsers) -> None:
    p = subparsers.add_parser("convert", help="convert between .pomdp and .pomdpx",
                              description="Read IN and write it to OUT in the format of OUT's "
                                          "extension (.pomdp or .pomdpx). Tables are kept exactly.")
    p.add_argument("input", metavar="IN")
    p.add_argument("output", metavar="OUT")
    p.set_defaults(func=cmd_convert)


def cmd_convert(args: argparse.Namespace) -> int:
    """``hrc_pomdp convert IN OUT``."""
    io.format_of(args.output)           # a bad target is refused before any work
    model = load_with_progress(args.input)
    progress(f"writing {args.output} ...")
    io.save_model(model, args.output)
    print(f"{args.input} -> {args.output} ({io.format_of(args.output)}: {model.n_states} states, "
          f"{model.n_actions} actions, {model.n_observations} observations)")
    return 0


# --------------------------------------------------------------------------------------------
# solve and simulate (the solvers' subcommands)
# --------------------------------------------------------------------------------------------
def _number(kind: type, low: float, strict: bool) -> Callable[[str], float]:
    """An argparse type: a ``kind`` above ``low`` (or at least ``low`` when not strict)."""
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if value < low or (strict and value == low):
            raise argparse.ArgumentTypeError(f"must be {'>' if strict else '>='} {low:g}: {text}")
        return value
    return parse


_positive = _number(float, 0.0, True)
_non_negative = _number(float, 0.0, False)
_count = _number(int, 1, False)
_non_negative_count = _number(int, 0, False)


def _in_model_terms(model: Model, lower: float, upper: float) -> Tuple[float, float]:
    """Reward bounds as the model states its values: a cost model ("values: cost") gets costs,
    so the lower cost bound is minus the upper reward bound."""
    return (-upper, -lower) if model.minimise else (lower, upper)


def _register_solve(subparsers) -> None:
    p = subparsers.add_parser(
        "solve", help="solve offline: bounds at the initial belief, optional policy file",
        description="Solve MODEL offline: HSVI2 (a point-based solver with lower and upper "
                    "bounds) for a POMDP, value iteration for an MDP. Prints the bounds on the "
                    "optimal value from the initial belief and the time taken; stops when the "
                    "bounds are within PRECISION or after the timeout. With fully observable "
                    "state variables (POMDPX fullyObs, mixed observability) their values are "
                    "known from the first step, as in SARSOP: the value from the initial belief "
                    "is the average, over the start values of those variables, of the value "
                    "given them (an MDP: the average over start states of their values).")
    p.add_argument("model", help="a .pomdp or .pomdpx file")
    p.add_argument("--timeout", type=_non_negative, default=60.0, metavar="S",
                   help="stop after S seconds (default 60)")
    p.add_argument("--precision", type=_positive, default=1e-3, metavar="E",
                   help="stop when upper - lower <= E (default 0.001)")
    p.add_argument("-o", "--output", metavar="POLICY",
                   help="write the policy to this file (numpy .npz format, any file name)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object (lower, upper, seconds, ...)")
    p.set_defaults(func=cmd_solve)


def _solver_errors_exit_2(handler: Callable[[argparse.Namespace], int]):
    """Report a SolverError (a bad policy file, a planner that does not fit the model) in one
    line with exit status 2, like a bad model file: both are the user's input to fix."""
    def wrapped(args: argparse.Namespace) -> int:
        try:
            return handler(args)
        except SolverError as exc:
            print(f"{PROG}: {_one_line(exc)}", file=sys.stderr)
            return 2
    wrapped.__doc__ = handler.__doc__
    wrapped.__name__ = handler.__name__
    return wrapped


@_solver_errors_exit_2
def cmd_solve(args: argparse.Namespace) -> int:
    """``hrc_pomdp solve MODEL [--timeout S] [--precision E] [-o POLICY] [--json]``."""
    from ros_hrc.pomdp import hsvi

    model = load_with_progress(args.model)
    shown = [0.0]

    def show(p) -> None:
        if p.seconds - shown[0] >= 1.0:
            shown[0] = p.seconds
            lo, up = _in_model_terms(model, p.lower, p.upper)
            progress(f"{p.seconds:.0f} s: lower {lo:.6g}, upper {up:.6g} ({p.trials} trials)")

    start = time.perf_counter()
    policy = hsvi.solve(model, timeout=args.timeout, precision=args.precision, progress=show)
    seconds = time.perf_counter() - start
    if args.output:
        policy.save(args.output)
    lower, upper = _in_model_terms(model, policy.lower, policy.upper)
    stats = {k: v for k, v in policy.stats.items() if k not in ("seconds", "state_policy")}
    facts = {"model": args.model, "kind": model_kind(model), "solver": stats.pop("solver"),
             "values": "cost" if model.minimise else "reward", "lower": lower, "upper": upper,
             "gap": upper - lower, "precision": args.precision,
             "converged": bool(upper - lower <= args.precision), "seconds": round(seconds, 4),
             "policy": args.output, "vectors": int(policy.actions.size), "stats": stats}
    if args.json:
        print(json.dumps(facts))
        return 0
    how = "converged" if facts["converged"] else f"stopped after {args.timeout:g} s"
    print(f"{args.model}: {facts['kind']} solved by {facts['solver']} in {seconds:.3f} s ({how})")
    print(f"  lower bound   {lower:.6f}")
    print(f"  upper bound   {upper:.6f}")
    print(f"  gap           {upper - lower:.3g} (target {args.precision:g})")
    print(f"  {facts['values']}s at the initial belief; {facts['vectors']} vectors"
          + (f", policy written to {args.output}" if args.output else ""))
    return 0


def _register_simulate(subparsers) -> None:
    p = subparsers.add_parser(
        "simulate", help="expected total discounted reward of a policy or of DESPOT",
        description="Simulate MODEL like SARSOP's pomdpsim: SIM-NUM runs of SIM-LEN steps from "
                    "the initial belief, true states drawn from T, observations from O, rewards "
                    "R(s,a,s') discounted. With fully observable state variables (POMDPX "
                    "fullyObs, mixed observability) the planner knows their values from the "
                    "first step, as in SARSOP: it starts from the initial belief conditioned on "
                    "the start state's fully observable values (an MDP: on the start state). "
                    "Prints the mean total with its 95 % confidence interval "
                    "(mean +/- 1.96 sd / sqrt(runs)) and the planner's time per step.")
    p.add_argument("model", help="a .pomdp or .pomdpx file")
    how = p.add_mutually_exclusive_group(required=True)
    how.add_argument("--policy", metavar="POLICY", help="a policy file written by 'solve -o'")
    how.add_argument("--planner", choices=["despot", "mdp"],
                     help="plan online: DESPOT, or value iteration for a fully observable model")
    p.add_argument("--sim-len", type=_count, required=True, metavar="N", help="steps per run")
    p.add_argument("--sim-num", type=_count, required=True, metavar="M", help="number of runs")
    p.add_argument("--seed", type=int, default=0, metavar="K", help="random seed (default 0)")
    p.add_argument("--lookahead", action="store_true",
                   help="policy: choose by one-step lookahead over the policy's values")
    d = p.add_argument_group("DESPOT (--planner despot)")
    d.add_argument("--time-per-step", type=_non_negative, default=1.0, metavar="S",
                   help="search time per decision (default 1)")
    d.add_argument("--scenarios", type=_count, default=500, metavar="K", help="default 500")
    d.add_argument("--depth", type=_non_negative_count, default=90, metavar="D",
                   help="default 90")
    d.add_argument("--lambda", dest="pruning", type=_non_negative, default=0.1, metavar="L",
                   help="regularization per policy node (default 0.1)")
    d.add_argument("--xi", type=_non_negative, default=0.95, metavar="X", help="default 0.95")
    d.add_argument("--max-trials", type=_non_negative_count, default=None, metavar="N",
                   help="also stop each search after N trials (reproducible runs)")
    d.add_argument("--upper", choices=["mdp", "fib", "trivial"], default="mdp",
                   help="upper bound (default mdp)")
    d.add_argument("--lower", choices=["blind", "policy", "rollout"], default="blind",
                   help="default policy (default blind: the best fixed action)")
    d.add_argument("--particles", type=_count, default=None, metavar="N",
                   help="particle belief of N particles (default: exact belief for models "
                        "of up to 5000 states)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object (mean, ci95_low, ci95_high, ms_per_step, ...)")
    p.set_defaults(func=cmd_simulate)


def _planner_factory(model: Model, args: argparse.Namespace):
    """A function run_seed -> planner, with the expensive tables built once; and its label."""
    from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner, DespotTables
    from ros_hrc.pomdp.planner import MdpPlanner, PolicyPlanner
    from ros_hrc.pomdp.policy import load as load_policy

    if args.policy:
        policy = load_policy(args.policy, model)
        if policy.kind == "mdp":
            return (lambda seed: MdpPlanner.from_policy(model, policy, seed)), \
                f"policy {args.policy} (MDP)"
        label = f"policy {args.policy}" + (" (one-step lookahead)" if args.lookahead else "")
        return (lambda seed: PolicyPlanner(model, policy, seed, args.lookahead)), label
    if args.planner == "mdp":
        if not model.fully_observable:
            raise SolverError("--planner mdp is for fully observable models; use despot or "
                              "a policy from 'solve'")
        solution = MdpPlanner(model).solution
        return (lambda seed: MdpPlanner(model, solution, seed)), "value iteration (MDP)"
    config = DespotConfig(scenarios=args.scenarios, depth=args.depth, pruning=args.pruning,
                          xi=args.xi, time_per_step=args.time_per_step,
                          max_trials=args.max_trials, upper=args.upper, lower=args.lower,
                          particles=args.particles)
    config.validate()
    progress("precomputing DESPOT's bounds ...")
    tables = DespotTables(model, config.upper, config.lower)
    label = (f"DESPOT ({args.time_per_step:g} s per step, K={args.scenarios}, D={args.depth}, "
             f"lambda={args.pruning:g}"
             + (f", at most {args.max_trials} trials" if args.max_trials is not None else "")
             + ")")
    return (lambda seed: DespotPlanner(model, config, seed, tables=tables)), label


@_solver_errors_exit_2
def cmd_simulate(args: argparse.Namespace) -> int:
    """``hrc_pomdp simulate MODEL (--policy P | --planner despot|mdp) --sim-len N --sim-num M``."""
    from ros_hrc.pomdp.simulate import simulate

    model = load_with_progress(args.model)
    factory, label = _planner_factory(model, args)
    shown = [time.perf_counter()]

    def show(done: int, mean: float) -> None:
        now = time.perf_counter()
        if now - shown[0] >= 1.0 or done == args.sim_num:
            shown[0] = now
            value = -mean if model.minimise else mean
            progress(f"run {done}/{args.sim_num}: mean {value:.6g}")

    result = simulate(model, factory, args.sim_len, args.sim_num, args.seed, progress=show)
    facts = result.as_dict()
    if model.minimise:
        facts["mean"], facts["ci95_low"], facts["ci95_high"] = (
            -result.mean, -result.ci95_high, -result.ci95_low)
        facts["undiscounted_mean"] = -result.undiscounted_mean
    facts.update({"model": args.model, "planner": label, "sim_len": args.sim_len,
                  "sim_num": args.sim_num, "seed": args.seed,
                  "values": "cost" if model.minimise else "reward"})
    if args.json:
        print(json.dumps(facts))
        return 0
    print(f"{args.model}: {label}, {args.sim_num} runs x {args.sim_len} steps, seed {args.seed}")
    print(f"  expected total discounted {facts['values']}  {facts['mean']:.6g}   95% CI "
          f"({facts['ci95_low']:.6g}, {facts['ci95_high']:.6g})")
    print(f"  time per step  {result.ms_per_step:.3f} ms (act p50 {result.ms_act_p50:.3f} ms, "
          f"p99 {result.ms_act_p99:.3f} ms)")
    if result.zero_probability_events:
        print(f"  {result.zero_probability_events} observation(s) of probability zero: the "
              "belief kept its prediction")
    return 0


#: Every subcommand's register function, in the order ``--help`` lists them.
SUBCOMMANDS: List[Callable[[argparse._SubParsersAction], None]] = [_register_info,
                                                                  _register_convert,
                                                                  _register_solve,
                                                                  _register_simulate]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every registered subcommand."""
    parser = argparse.ArgumentParser(prog=PROG, description="Inspect, convert, solve and simulate "
                                     "POMDP and MDP model files (.pomdp, .pomdpx).")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    subparsers.required = True
    for register in SUBCOMMANDS:
        register(subparsers)
    return parser


def run(argv: Optional[Sequence[str]] = None) -> int:
    """Run the command line ``argv`` and return the exit status (for tests and ``main``)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:           # argparse has printed its usage message
        return int(exc.code or 0)
    try:
        return int(args.func(args))
    except (ModelFormatError, ModelError) as exc:
        print(f"{PROG}: {_one_line(exc)}", file=sys.stderr)
        return 2
    except HrcError as exc:
        print(f"{PROG}: {_one_line(exc)}", file=sys.stderr)
        return 1
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"{PROG}: {where}{exc.strerror or exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split())


def main(argv: Optional[Sequence[str]] = None) -> None:
    """Entry point of ``scripts/hrc_pomdp``: run and exit with the status."""
    sys.exit(run(argv))


if __name__ == "__main__":
    main()
