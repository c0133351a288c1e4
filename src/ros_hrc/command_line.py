"""What the package's programs share about their command line and terminal: dropping
roslaunch's own arguments, ranged numbers, seeds, a solver's options from its launch session, and
printing whole lines into a terminal that several processes share."""
from __future__ import annotations

import argparse
import math
import re
import sys
from typing import Callable, List, Optional, Sequence, TextIO


def own_arguments(argv: Optional[Sequence[str]] = None) -> List[str]:
    """The command line (``sys.argv[1:]`` by default) without the ``__name:=`` / ``__log:=``
    arguments roslaunch appends to every node it starts: they are not ours to parse, and
    these commands must not import rospy (whose ``myargv`` does the same) to drop them."""
    return [a for a in (sys.argv[1:] if argv is None else argv) if not a.startswith("__")]


def ranged_number(kind: type, low: float, high: float,
                  low_open: bool = False) -> Callable[[str], float]:
    """An argparse type: a finite ``kind`` (int or float) in [low, high], or (low, high] with
    ``low_open``; anything else (nan, inf, out of range, not a number) is argparse's error."""
    noun = "an integer" if kind is int else "a number"

    def parse(text: str):
        try:
            value = kind(text)
        except (ValueError, OverflowError):
            raise argparse.ArgumentTypeError(f"not {noun}: {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
        if value < low or (low_open and value == low):
            raise argparse.ArgumentTypeError(
                f"must be {'>' if low_open else '>='} {low:g}, got {text!r}")
        if value > high:
            raise argparse.ArgumentTypeError(f"must be at most {high:g}, got {text!r}")
        return value
    parse.__name__ = kind.__name__      # argparse names it in some messages
    return parse


def seed_argument(text: str) -> int:
    """An argparse type: a seed, an integer from 0 to :data:`ros_hrc.streams.MAX_SEED`, the one
    range of every seed (the launch argument's too); anything else is argparse's one line."""
    from ros_hrc.streams import MAX_SEED, checked_seed
    try:
        return checked_seed(int(text.strip()))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer from 0 to {MAX_SEED}, got "
                                         f"{text!r}") from None


def parse_launch_options(parser: argparse.ArgumentParser,
                         argv: Optional[Sequence[str]] = None) -> argparse.Namespace:
    """Parse a solver process's command line (:func:`own_arguments` of ``argv``). With
    ``--link-session NAME`` (what hrc.launch gives), the launch's resolved settings, which its
    pre-flight wrote beside the session's token (:func:`ros_hrc.link.token.read_session_settings`),
    are the defaults of the options made from settings: every path in them is absolute,
    resolved in the directory the user ran roslaunch from. An option on the command line still
    wins. Settings that cannot be read are argparse's one-line error (exit status 2)."""
    from ros_hrc.link.token import TokenError, read_session_settings
    from ros_hrc.settings import use_as_defaults

    words = own_arguments(argv)
    known, _rest = parser.parse_known_args(words)
    session = getattr(known, "link_session", "")
    if session:
        try:
            use_as_defaults(parser, read_session_settings(session))
        except TokenError as exc:
            parser.error(str(exc))
    return parser.parse_args(words)


def reread_launch_options(parser: argparse.ArgumentParser, argv: Optional[Sequence[str]],
                          running: argparse.Namespace) -> argparse.Namespace:
    """A running solver process's options read again, as :func:`parse_launch_options` read
    them at its start (a ``configure``: the launch's settings file was rewritten for a warm
    stack's next cell). Raises ValueError (one line, nothing changed) when they cannot be
    read, or when a setting that a running process cannot take in place (one outside
    :data:`ros_hrc.settings.IN_PLACE`: its port, its task) differs from ``running``'s."""
    from ros_hrc import settings

    try:
        args = parse_launch_options(parser, argv)
    except SystemExit:    # argparse said why on stderr
        raise ValueError("the launch's settings cannot be read again") from None
    moved = settings.needs_new_launch(vars(running), vars(args))
    if moved:
        raise ValueError(f"{', '.join(moved)} changed: a running process takes "
                         f"{'it' if len(moved) == 1 else 'them'} only from a new launch")
    return args


#: A line's end: its newline, then any terminal escape sequences (colour codes) written after
#: it. rospy colours a line on a terminal as colour + text + newline + colour reset, so the
#: reset comes after the newline: that text has ended its line, and must not wait for the next.
_LINE_END = re.compile(r"\n(?:\x1b\[[0-9;?]*[A-Za-z])*\Z")


def counted(number: int, noun: str, plural: Optional[str] = None) -> str:
    """``1 step``, ``4 steps``: a count and its noun, singular for one (the one plural of
    every line a program prints); ``plural`` when it is not the noun and an s (policies)."""
    return f"{number} {noun}" if number == 1 else f"{number} {plural or noun + 's'}"


class WholeLines:
    """A text stream that passes text on to ``stream`` a whole line at a time, each in one
    write, flushed: ``print(text)`` (the text, then its newline) becomes one write, however
    many lines ``text`` has; a write that does not end a line waits for the rest (or
    :meth:`flush`). A newline followed only by terminal escape sequences (rospy's colour
    reset after a warning's newline) ends a line too. Everything else is ``stream``'s."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream
        self._pending = ""

    def write(self, text: str) -> int:
        self._pending += text
        if _LINE_END.search(self._pending):
            self.flush()
        return len(text)

    def flush(self) -> None:
        if self._pending:
            text, self._pending = self._pending, ""
            self._stream.write(text)
        self._stream.flush()

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def print_whole_lines() -> None:
    """Make this process print whole lines, each in one write, on stdout and stderr, so that
    processes printing into one terminal (roslaunch's) never glue their lines mid-line. On a
    terminal Python flushes at each newline *inside* a text, and unbuffered (``python -u``,
    PYTHONUNBUFFERED) at each part of a print: a print of several lines then left its last
    line and its newline in two writes, and another process's line came between. Text still
    comes out at each line's end, as line buffering would."""
    if not isinstance(sys.stdout, WholeLines):
        sys.stdout = WholeLines(sys.stdout)   # type: ignore[assignment]
    if not isinstance(sys.stderr, WholeLines):
        sys.stderr = WholeLines(sys.stderr)   # type: ignore[assignment]
