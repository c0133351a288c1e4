"""``hrc_pomdp``: look at, convert, solve and simulate (PO)MDP model files.

::

    hrc_pomdp info MODEL [--json]      sizes, discount, MDP or POMDP, the checks that passed
    hrc_pomdp convert IN OUT           .pomdp <-> .pomdpx (by extension), round-trip exact
    hrc_pomdp solve MODEL [--timeout S] [--precision E] [-o POLICY] [--json]
    hrc_pomdp simulate MODEL (--policy POLICY | --planner despot|mdp [--time-per-step S])
                       --sim-len N --sim-num M [--seed K] [--json]
    hrc_pomdp policy ROBOT_MODEL [--trials N] [--seed K] [--json]
                                       the robot's DESPOT actions after typical observations

Every subcommand takes ``--memory-limit SIZE`` (default 4G): reading, solving or simulating a
model that would need more, estimated before it is allocated, is refused in one line naming the
file, the estimate and the option.

Exit status: 0 done; 2 the command line is wrong (argparse's usage line and
``hrc_pomdp <command>: error: argument ...``; numbers must be finite and in range), or a model
file is malformed or inconsistent -- then one line on standard error,
``hrc_pomdp: <file>:<line>: <what>``, never a traceback; 1 any other failure the user can act
on (a file that cannot be written, the memory limit, a result that is not a finite number).
``--json`` prints strict JSON (no NaN or Infinity). An output file (``convert``'s, ``solve -o``)
is written whole or not at all. Progress goes to standard error, and only when it is a terminal.

Adding a subcommand (``solve``, ``simulate``): write ``_register_<name>(subparsers)`` (or, for
a large one, a module of its own as ``simulate``'s :mod:`ros_hrc.commands.pomdp_simulate`) that
adds the subparser and ``set_defaults(func=<handler>)``, a handler ``(args) -> int`` (the exit
status), and append the register function to :data:`SUBCOMMANDS`. Errors of the package
(:class:`~ros_hrc.errors.HrcError`) raised by a handler are reported by :func:`run`.
"""
from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING, Callable, List, Optional, Sequence, TextIO, Tuple

from ros_hrc.command_line import ranged_number
from ros_hrc.streams import MAX_SEED
from ros_hrc.commands.pomdp_common import (MAX_SECONDS, MODEL_HELP, PROG,
                                           add_memory_limit, emit, load_with_progress, model_file,
                                           one_line, precision_arg, progress, require_finite,
                                           seconds_arg, seed_arg, solver_errors_exit_2)
from ros_hrc.commands.pomdp_simulate import register_simulate
from ros_hrc.errors import HrcError, ModelError, ModelFormatError
from ros_hrc.pomdp.despot_parameters import parameter
from ros_hrc.pomdp.memory import MemoryLimitError

if TYPE_CHECKING:
    from ros_hrc.pomdp.model import Model

def checks() -> List[str]:
    """What every model that loads has passed (the parsers and Model.validate check them)."""
    from ros_hrc.pomdp.model import MAX_VALUE, PROBABILITY_TOLERANCE
    return ["names known and unique", "table sizes agree", "discount in [0, 1)",
            f"no negative probability; rows of T and O sum to 1 (within "
            f"{PROBABILITY_TOLERANCE:g})", "initial belief sums to 1",
            f"every number finite; |R| / (1 - discount) <= {MAX_VALUE:g}"]


def model_kind(model: "Model") -> str:
    """``MDP``, ``MOMDP`` (POMDPX with fully and partially observable variables) or ``POMDP``."""
    if model.fully_observable:
        return "MDP"
    variables = (model.meta or {}).get("pomdpx", {}).get("state_variables", [])
    if any(v.get("fully_observable") for v in variables):
        return "MOMDP"
    return "POMDP"


def describe(model: "Model", path: str, seconds: float) -> dict:
    """The facts ``info`` prints, as a JSON-ready dict."""
    import numpy as np
    from ros_hrc.pomdp import io
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
        "checks": checks(), "checks_passed": True, "seconds": round(seconds, 4),
    }


def _print_info(facts: dict, out: TextIO = None) -> None:
    out = out if out is not None else sys.stdout
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
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    add_memory_limit(p)
    p.set_defaults(func=cmd_info)


def cmd_info(args: argparse.Namespace) -> int:
    """``hrc_pomdp info MODEL [--json]``."""
    start = time.perf_counter()
    path = model_file(args.model)
    model = load_with_progress(path, args.memory_limit)
    facts = describe(model, path, time.perf_counter() - start)
    return emit(facts, args.json, _print_info)


def _register_convert(subparsers) -> None:
    p = subparsers.add_parser("convert", help="convert between .pomdp and .pomdpx",
                              description="Read IN and write it to OUT in the format of OUT's "
                                          "extension (.pomdp or .pomdpx). Tables are kept exactly.")
    p.add_argument("input", metavar="IN")
    p.add_argument("output", metavar="OUT")
    add_memory_limit(p)
    p.set_defaults(func=cmd_convert)


#: Bytes the text of a written model costs per non-zero: the line (about 40 characters), its
#: list slot, the joined text and its UTF-8 copy.
WRITE_BYTES_PER_NONZERO = 200


def cmd_convert(args: argparse.Namespace) -> int:
    """``hrc_pomdp convert IN OUT``."""
    from ros_hrc.pomdp import io, memory
    from ros_hrc.pomdp.output import check_writable
    io.format_of(args.output)           # a bad target is refused before any work
    check_writable(args.output)
    model = load_with_progress(args.input, args.memory_limit)
    nonzeros = sum(m.nnz for table in (model.T, model.O, model.R) for m in table)
    memory.require(memory.model_bytes(model) + WRITE_BYTES_PER_NONZERO * nonzeros,
                   args.memory_limit, args.input, f"writing {args.output}")
    progress(f"writing {args.output} ...")
    io.save_model(model, args.output)
    print(f"{args.input} -> {args.output} ({io.format_of(args.output)}: {model.n_states} states, "
          f"{model.n_actions} actions, {model.n_observations} observations)")
    return 0


# --------------------------------------------------------------------------------------------
# solve and simulate (the solvers' subcommands)
# --------------------------------------------------------------------------------------------


def _in_model_terms(model: "Model", lower: float, upper: float) -> Tuple[float, float]:
    """Reward bounds as the model states its values: a cost model ("values: cost") gets costs,
    so the lower cost bound is minus the upper reward bound."""
    return (-upper, -lower) if model.minimise else (lower, upper)


def _register_solve(subparsers) -> None:
    p = subparsers.add_parser(
        "solve", help="solve offline: bounds at the initial belief, optional policy file",
        description="Solve MODEL offline: HSVI2 (a point-based solver with lower and upper "
                    "bounds) for a POMDP, value iteration for an MDP. Prints the bounds on the "
                    "optimal value from the initial belief and the time taken; stops when the "
                    "bounds are within PRECISION or after the timeout, which counts from the "
                    "start of the command (reading the model and building the solver's tables "
                    "included), or when the solver's vectors would outgrow the memory limit. "
                    "With fully observable "
                    "state variables (POMDPX fullyObs, mixed observability) their values are "
                    "known from the first step, as in SARSOP: the value from the initial belief "
                    "is the average, over the start values of those variables, of the value "
                    "given them (an MDP: the average over start states of their values).")
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("--timeout", type=seconds_arg, default=60.0, metavar="S",
                   help=f"stop after S seconds, 0 to {MAX_SECONDS:g} (default 60)")
    p.add_argument("--precision", type=precision_arg, default=1e-3, metavar="E",
                   help="stop when upper - lower <= E (default 0.001)")
    p.add_argument("-o", "--output", metavar="POLICY",
                   help="write the policy to this file (numpy .npz format, any file name)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON object (lower, upper, seconds, ...)")
    add_memory_limit(p)
    p.set_defaults(func=cmd_solve)


@solver_errors_exit_2
def cmd_solve(args: argparse.Namespace) -> int:
    """``hrc_pomdp solve MODEL [--timeout S] [--precision E] [-o POLICY] [--json]``."""
    from ros_hrc.pomdp import offline
    from ros_hrc.pomdp.output import check_writable

    began = getattr(args, "started", None)          # when run() began (None: called directly)
    if began is None:
        began = time.perf_counter()
    if args.output:
        check_writable(args.output)     # not after a long solve
    model = load_with_progress(args.model, args.memory_limit)
    shown = [0.0]

    def show(p) -> None:
        if p.seconds - shown[0] >= 1.0:
            shown[0] = p.seconds
            lo, up = _in_model_terms(model, p.lower, p.upper)
            progress(f"{p.seconds:.0f} s: lower {lo:.6g}, upper {up:.6g} ({p.trials} trials)")

    start = time.perf_counter()
    # The timeout counts from the start of the command: the solver gets what reading left.
    remaining = max(0.0, args.timeout - (start - began))
    policy = offline.solve(model, timeout=remaining, precision=args.precision, progress=show,
                           memory_limit=args.memory_limit)
    seconds = time.perf_counter() - start
    lower, upper = _in_model_terms(model, policy.lower, policy.upper)
    stats = {k: v for k, v in policy.stats.items() if k not in ("seconds", "state_policy")}
    facts = {"model": args.model, "kind": model_kind(model), "solver": stats.pop("solver"),
             "values": "cost" if model.minimise else "reward", "lower": lower, "upper": upper,
             "gap": upper - lower, "precision": args.precision,
             "converged": bool(upper - lower <= args.precision), "seconds": round(seconds, 4),
             "policy": args.output, "vectors": int(policy.actions.size), "stats": stats}
    require_finite(facts)               # before the policy file is written, too
    if args.output:
        policy.save(args.output)

    def print_text(facts: dict) -> None:
        if facts["converged"]:
            how = "converged"
        elif stats.get("memory_limit_reached"):
            how = "stopped at the memory limit"
        else:
            how = f"stopped at the {args.timeout:g} s timeout"
        print(f"{args.model}: {facts['kind']} solved by {facts['solver']} in {seconds:.3f} s "
              f"({how})")
        print(f"  lower bound   {lower:.6f}")
        print(f"  upper bound   {upper:.6f}")
        print(f"  gap           {upper - lower:.3g} (target {args.precision:g})")
        print(f"  {facts['values']}s at the initial belief; {facts['vectors']} vectors"
              + (f", policy written to {args.output}" if args.output else ""))

    return emit(facts, args.json, print_text)


def _register_policy(subparsers) -> None:
    from ros_hrc.agents.policy_sequences import DEFAULT_TRIALS, SEQUENCES
    p = subparsers.add_parser(
        "policy", help="the robot planner's actions after typical observation sequences",
        description="Step the robot's online planner (DESPOT, the robot's K, D and lambda) "
                    "through named observation sequences, each from the initial belief as the "
                    "robot process does, and print the action it takes after each observation "
                    "and its belief that the human needs help (S2..S5) and warned (S6). Each "
                    "decision is bounded by N trials, not by time, from seed K: the table is the "
                    "same on every machine. Sequences: " + "; ".join(
                        f"{q.name} ({' '.join(q.observations)}: {q.what})" for q in SEQUENCES))
    p.add_argument("model", help="a robot model: a name in models/robot/ or a .pomdp/.pomdpx "
                                 "file with the task's states, actions and observations")
    p.add_argument("--trials", type=ranged_number(int, 1, parameter("max_trials").high),
                   default=DEFAULT_TRIALS,
                   metavar="N", help=f"DESPOT trials per decision (default {DEFAULT_TRIALS})")
    p.add_argument("--seed", type=seed_arg, default=0, metavar="K",
                   help=f"the planner's seed, 0 to {MAX_SEED} (default 0)")
    p.add_argument("--sequence", action="append", type=_policy_sequence, metavar="NAME=OBS,...",
                   help="a sequence of your own, e.g. fails_after_warning=O7,O19,O7,O7 "
                        "(repeatable; given, only these are run)")
    p.add_argument("--belief", action="store_true",
                   help="add the whole belief after each sequence's last observation")
    p.add_argument("--json", action="store_true", help="print one JSON object (rows)")
    p.set_defaults(func=cmd_policy)


def _policy_sequence(text: str):
    from ros_hrc.agents.policy_sequences import parse_sequence
    try:
        return parse_sequence(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


@solver_errors_exit_2
def cmd_policy(args: argparse.Namespace) -> int:
    """``hrc_pomdp policy MODEL``: the planner's actions after the typical sequences."""
    from ros_hrc.models import load_robot_model
    from ros_hrc.agents.policy_table import SEQUENCES, despot_config, format_table, policy_table

    model = load_robot_model(args.model)
    sequences = tuple(args.sequence) if args.sequence else SEQUENCES
    try:
        rows = policy_table(model, sequences, config=despot_config(args.trials), seed=args.seed)
    except ValueError as exc:
        print(f"hrc_pomdp policy: {exc}", file=sys.stderr)
        return 2
    facts = {"model": args.model, "trials": args.trials, "seed": args.seed,
             "rows": [row.as_dict() for row in rows]}

    def print_text(facts: dict) -> None:
        print(f"{args.model}: DESPOT, {args.trials} trials per decision, seed {args.seed}")
        print(format_table(rows, with_belief=args.belief))

    return emit(facts, args.json, print_text)


#: Every subcommand's register function, in the order ``--help`` lists them.
SUBCOMMANDS: List[Callable[[argparse._SubParsersAction], None]] = [_register_info,
                                                                  _register_convert,
                                                                  _register_solve,
                                                                  register_simulate,
                                                                  _register_policy]


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
    started = time.perf_counter()
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        problem = args.check(args) if getattr(args, "check", None) else None
        if problem is not None:
            # A constraint between options: reported like argparse's own errors.
            option, message = problem
            _subparser(parser, args.command).error(f"argument {option}: {message}")
    except SystemExit as exc:           # argparse has printed its usage message
        return int(exc.code or 0)
    args.started = started
    try:
        return int(args.func(args))
    except (ModelFormatError, ModelError) as exc:
        print(f"{PROG}: {one_line(exc)}", file=sys.stderr)
        return 2
    except MemoryLimitError as exc:
        print(f"{PROG}: {one_line(exc)}; raise it with --memory-limit", file=sys.stderr)
        return 1
    except HrcError as exc:
        print(f"{PROG}: {one_line(exc)}", file=sys.stderr)
        return 1
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"{PROG}: {where}{exc.strerror or exc}", file=sys.stderr)
        return 1
    except MemoryError:
        # The estimates missed (they are estimates): still one line, and a way out.
        print(f"{PROG}: out of memory; give a lower --memory-limit so the model is refused "
              "or the solver stops early", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130


def _subparser(parser: argparse.ArgumentParser, command: str) -> argparse.ArgumentParser:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices[command]
    return parser


def main(argv: Optional[Sequence[str]] = None) -> None:
    """Entry point of ``scripts/hrc_pomdp``: run and exit with the status."""
    sys.exit(run(argv))


if __name__ == "__main__":
    main()
