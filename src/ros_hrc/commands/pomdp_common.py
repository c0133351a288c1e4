"""What every ``hrc_pomdp`` subcommand shares: the numeric options' limits and argparse types,
the memory limit, progress on a terminal, printing a result (strict JSON or text, never a
number that is not finite) and one-line errors. The subcommands are in
:mod:`ros_hrc.commands.pomdp` and, for ``simulate``, :mod:`ros_hrc.commands.pomdp_simulate`.

On a small model ``hrc_pomdp``'s wall time is mostly start-up, so the command modules import
at their top only what parsing the command line needs (nothing of numpy or scipy): a verb
imports the toolkit's modules it uses inside its handler, and ``io`` only the parser of the
file's format.
"""
from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING, Callable, Optional, TextIO

from ros_hrc.command_line import ranged_number, seed_argument
from ros_hrc.errors import HrcError, ModelError, SolverError
from ros_hrc.model_files import names_a_file, resolve_model
from ros_hrc.pomdp import memory
from ros_hrc.pomdp.despot_parameters import parameter

if TYPE_CHECKING:
    from ros_hrc.pomdp.model import Model

PROG = "hrc_pomdp"

#: What a MODEL argument may be (every verb but ``policy``, whose names are robot models).
MODEL_HELP = ("a .pomdp or .pomdpx file, or a shipped model's name (robot, humanModel, "
              "robot_types, ...: looked up in the seed task's models/robot and models/human, "
              "then in the other tasks')")

#: Upper limits of the numeric options: beyond them a run could not finish or fit in memory.
#: DESPOT's options take their limits from ros_hrc.pomdp.despot_parameters (:func:`despot_option`),
#: the seed its range from ros_hrc.streams, as the launch arguments do.
MAX_SECONDS = 1e6                  # --timeout: 11.6 days
MAX_RUNS = 10_000_000              # --sim-len, --sim-num, and their product
MAX_MEMORY = 1 << 50               # --memory-limit: 1 PiB


class ResultError(HrcError):
    """A result to print is not a finite number (it is reported, never printed)."""


def progress(message: str, stream: Optional[TextIO] = None) -> None:
    """Show a progress line on a terminal only, so pipes, logs and --json output stay clean."""
    stream = stream if stream is not None else sys.stderr
    if stream.isatty():
        print(f"{PROG}: {message}", file=stream, flush=True)


def model_file(name_or_path: str) -> str:
    """The file a MODEL argument names: a path as typed (a relative one is relative to where
    the command runs), or the name of a shipped model (``robot``, ``humanModel``,
    ``robot_types``) looked up in each task's robot and human folders, the default task's
    first, as ``hrc_pomdp policy`` and the launch look names up. ModelError lists the known
    names when none is found."""
    if names_a_file(name_or_path):
        return name_or_path
    from ros_hrc import tasks           # only for a name: its folders
    order = [tasks.DEFAULT_TASK] + [n for n in tasks.TASK_NAMES if n != tasks.DEFAULT_TASK]
    folders = [tasks.get(n).model_dirs[kind] for n in order for kind in ("robot", "human")]
    try:
        return str(resolve_model(name_or_path, "", folders))
    except FileNotFoundError as exc:
        raise ModelError(str(exc)) from None


def load_with_progress(name_or_path: str, memory_limit: Optional[int] = None) -> "Model":
    """Load a model file or a shipped model by name (:func:`model_file`), saying so on a
    terminal (large models take a moment)."""
    from ros_hrc.pomdp import io
    path = model_file(name_or_path)
    progress(f"reading {path} ...")
    return io.load_model(path, memory_limit=memory_limit)


def non_finite(value, where: str = "") -> Optional[str]:
    """The path (``lower``, ``stats.residual``) of the first non-finite float in ``value``."""
    if isinstance(value, float):
        return None if math.isfinite(value) else where
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, (list, tuple)):
        items = enumerate(value)
    else:
        return None
    for key, item in items:
        found = non_finite(item, f"{where}.{key}" if where else str(key))
        if found is not None:
            return found
    return None


def require_finite(facts: dict) -> None:
    """ResultError when a number of the result is not finite (it must not be printed)."""
    bad = non_finite(facts)
    if bad is not None:
        raise ResultError(f"the result {bad} is not a finite number ({value_at(facts, bad)}); "
                          "nothing printed or written")


def emit(facts: dict, as_json: bool, print_text: Callable[[dict], None]) -> int:
    """Print the result: strict JSON (one line) or text. A number that is not finite is an
    error (ResultError), whichever way the result would have been printed."""
    require_finite(facts)
    if as_json:
        import json
        print(json.dumps(facts, allow_nan=False))
    else:
        print_text(facts)
    return 0


def value_at(facts, path: str):
    for key in path.split("."):
        facts = facts[int(key)] if isinstance(facts, (list, tuple)) else facts[key]
    return facts


def largest_value() -> float:
    """The largest value a model may reach (``model.MAX_VALUE``), read when an option that
    it bounds is given: the model module imports numpy and scipy."""
    from ros_hrc.pomdp.model import MAX_VALUE
    return MAX_VALUE


def precision_arg(text: str) -> float:
    """An argparse type: a precision above 0, at most ``model.MAX_VALUE``."""
    return ranged_number(float, 0.0, largest_value(), low_open=True)(text)


seconds_arg = ranged_number(float, 0.0, MAX_SECONDS)
run_count_arg = ranged_number(int, 1, MAX_RUNS)


#: An argparse type: a seed, in the one range of every seed (ros_hrc.streams.MAX_SEED).
seed_arg = seed_argument


def despot_option(group, name: str, metavar: str, **more) -> None:
    """Add DESPOT's parameter ``name`` to ``group`` as its definition says
    (:mod:`ros_hrc.pomdp.despot_parameters`): the option, the kind, the limits (refused in one
    line that says them), the default and the doc."""
    p = parameter(name)

    def parse(text: str):
        try:
            return p.parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    parse.__name__ = p.kind.__name__
    shown = "none" if p.default is None else p.default
    help_text = f"{p.doc}; {p.requirement()[len('must be '):]} (default {shown})"
    if p.choices:
        group.add_argument(p.option, dest=p.field, choices=p.choices, default=p.default,
                           help=help_text.replace("%", "%%"), **more)
    else:
        group.add_argument(p.option, dest=p.field, type=parse, default=p.default,
                           metavar=metavar, help=help_text.replace("%", "%%"), **more)


def memory_size_arg(text: str) -> int:
    """An argparse type: a memory size (``512M``, ``4G``, ``4096`` = MiB), 1 MiB to 1 PiB."""
    try:
        size = memory.parse_size(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if not memory.MiB <= size <= MAX_MEMORY:
        raise argparse.ArgumentTypeError(f"must be between 1M and 1P (1 MiB .. 1 PiB), "
                                         f"got {text!r}")
    return size


def add_memory_limit(p: argparse.ArgumentParser) -> None:
    p.add_argument("--memory-limit", type=memory_size_arg, default=memory.DEFAULT_MEMORY_LIMIT,
                   metavar="SIZE",
                   help="refuse a model whose reading, solving or simulation would need more "
                        "memory than SIZE, estimated before it is allocated (a number with K, "
                        "M, G or T; plain numbers are MiB; default "
                        f"{memory.format_bytes(memory.DEFAULT_MEMORY_LIMIT)})")


def solver_errors_exit_2(handler: Callable[[argparse.Namespace], int]):
    """Report a SolverError (a bad policy file, a planner that does not fit the model) in one
    line with exit status 2, like a bad model file: both are the user's input to fix."""
    def wrapped(args: argparse.Namespace) -> int:
        try:
            return handler(args)
        except SolverError as exc:
            print(f"{PROG}: {one_line(exc)}", file=sys.stderr)
            return 2
    wrapped.__doc__ = handler.__doc__
    wrapped.__name__ = handler.__name__
    return wrapped


def one_line(exc: Exception) -> str:
    return " ".join(str(exc).split())
