"""What the package's ROS-free commands share about their command line."""
from __future__ import annotations

import argparse
import math
import sys
from typing import Callable, List, Optional, Sequence


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
