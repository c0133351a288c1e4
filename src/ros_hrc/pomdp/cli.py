"""``hrc_pomdp``: look at, convert, solve and simulate (PO)MDP model files.

::

    hrc_pomdp info MODEL [--json]      sizes, discount, MDP or POMDP, the checks that passed
    hrc_pomdp convert IN OUT           .pomdp <-> .pomdpx (by extension), round-trip exact

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
from typing import Callable, List, Optional, Sequence, TextIO

import numpy as np

from ros_hrc.errors import HrcError, ModelError, ModelFormatError
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


#: Every subcommand's register function, in the order ``--help`` lists them.
SUBCOMMANDS: List[Callable[[argparse._SubParsersAction], None]] = [_register_info,
                                                                  _register_convert]


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
