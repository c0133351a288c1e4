"""What every ``hrc_pomdp`` subcommand shares: the numeric options' limits and argparse types,
the memory limit, progress on a terminal, printing a result (strict JSON or text, never a
number that is not finite) and one-line errors. The subcommands are in
:mod:`ros_hrc.commands.pomdp` and, for ``simulate``, :mod:`ros_hrc.commands.pomdp_simulate`.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Callable, Optional, TextIO

from ros_hrc.command_line import ranged_number
from ros_hrc.errors import HrcError, SolverError
from ros_hrc.pomdp import io, memory
from ros_hrc.pomdp.model import MAX_VALUE, Model

PROG = "hrc_pomdp"

#: Upper limits of the numeric options: beyond them a run could not finish or fit in memory.
MAX_SECONDS = 1e6                  # --timeout, --time-per-step: 11.6 days
MAX_RUNS = 10_000_000              # --sim-len, --sim-num, and their product
MAX_SCENARIOS = 1_000_000          # --scenarios, --particles
MAX_DEPTH = 100_000                # --depth
MAX_TRIALS = 10**12                # --max-trials
MAX_SEED = 2**64 - 1
MAX_MEMORY = 1 << 50               # --memory-limit: 1 PiB


class ResultError(HrcError):
    """A result to print is not a finite number (it is reported, never printed)."""


def progress(message: str, stream: Optional[TextIO] = None) -> None:
    """Show a progress line on a terminal only, so pipes, logs and --json output stay clean."""
    stream = stream if stream is not None else sys.stderr
    if stream.isatty():
        print(f"{PROG}: {message}", file=stream, flush=True)


def load_with_progress(path: str, memory_limit: Optional[int] = None) -> Model:
    """Load a model file, saying so on a terminal (large models take a moment)."""
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
        print(json.dumps(facts, allow_nan=False))
    else:
        print_text(facts)
    return 0


def value_at(facts, path: str):
    for key in path.split("."):
        facts = facts[int(key)] if isinstance(facts, (list, tuple)) else facts[key]
    return facts


seconds_arg = ranged_number(float, 0.0, MAX_SECONDS)
precision_arg = ranged_number(float, 0.0, MAX_VALUE, low_open=True)
fraction_arg = ranged_number(float, 0.0, 1.0)
regularization_arg = ranged_number(float, 0.0, MAX_VALUE)
run_count_arg = ranged_number(int, 1, MAX_RUNS)
scenario_count_arg = ranged_number(int, 1, MAX_SCENARIOS)
depth_arg = ranged_number(int, 0, MAX_DEPTH)
trial_count_arg = ranged_number(int, 0, MAX_TRIALS)
seed_arg = ranged_number(int, 0, MAX_SEED)


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
