"""The command lines of hrc_experiment and hrc_fit: the argument types they share, each
error one line naming the argument (argparse's exit status 2), and the one line of a file that
cannot be written. No ROS here.
"""
from __future__ import annotations

import argparse
import sys
from typing import Callable, List, Optional


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line, ``<program>: argument --x: ...``, exit 2."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, f"{self.prog}: {' '.join(message.split())}\n")


def names_argument(text: str) -> List[str]:
    """Comma-separated names: at least one, none empty (``a,,b`` is a typo, not two names),
    none twice."""
    names = [part.strip() for part in text.split(",")]
    if not any(names):
        raise argparse.ArgumentTypeError("give at least one name (comma-separated)")
    if not all(names):
        raise argparse.ArgumentTypeError(f"an empty item between commas in {text!r}")
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise argparse.ArgumentTypeError(f"{repeated[0]!r} is given twice in {text!r}")
    return names


#: A step limit travels as the ``max_steps`` ROS parameter: an XML-RPC int (int32).
MAX_STEP_LIMIT = 2**31 - 1
#: Stacks side by side: each is a roscore and six processes.
MAX_JOBS = 1000
#: Digits an integer option may have before it is not read at all (Python refuses to convert
#: more than 4300; none of these numbers needs 20).
_MAX_DIGITS = 40


def at_least(minimum: int, maximum: Optional[int] = None) -> Callable[[str], int]:
    """An argparse type: an integer >= ``minimum`` (and <= ``maximum``)."""
    def parse(text: str) -> int:
        shown = text if len(text) <= 60 else f"{text[:40]}... ({len(text)} characters)"
        try:
            if len(text.strip()) > _MAX_DIGITS:
                raise ValueError
            value = int(text.strip())
        except ValueError:
            if text.strip().isdigit() and maximum is not None:
                raise argparse.ArgumentTypeError(f"must be an integer from {minimum} to "
                                                 f"{maximum}, got {shown!r}") from None
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, "
                                             f"got {shown!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {shown!r}")
        if maximum is not None and value > maximum:
            raise argparse.ArgumentTypeError(f"must be an integer from {minimum} to {maximum}, "
                                             f"got {shown!r}")
        return value

    parse.__name__ = "int"
    return parse


def file_error_line(exc: OSError) -> str:
    """``<file>: <why>`` of an I/O error (a full disk), for one line."""
    where = f"{exc.filename}: " if exc.filename else ""
    return f"{where}{exc.strerror or exc}"


def say_one_line(program: str, text: object) -> int:
    """Print ``<program>: <text>`` on stderr as one line (its whitespace folded: an error's
    own newlines would split it); returns 2, the exit status of a refusal."""
    print(f"{program}: {' '.join(str(text).split())}", file=sys.stderr, flush=True)
    return 2
