"""What an action or a predicate answers: a yes/no and a sentence a person can act on.

Both map one-to-one onto ``std_srvs/Trigger``'s response (``success``, ``message``).
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Outcome:
    """Result of an action: did it do what was asked, and what happened."""

    success: bool
    message: str
    duration: float = 0.0  # simulated seconds from start to end


@dataclass(frozen=True)
class Reading:
    """Value of a predicate, with the geometry behind it."""

    value: bool
    message: str
