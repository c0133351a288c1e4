"""The observation sequences ``hrc_pomdp policy`` replays (:mod:`ros_hrc.agents.policy_table`),
and its default trials: data alone, so the command's parser lists them without importing the
planner (``hrc_pomdp`` imports only what its verb uses).

The sequences name observations of the robot model (``O<bits>``, :mod:`ros_hrc.tasks.seed`):
1 object visible, 2 in range, 4 grasp attempt, 8 has object, 16 warning, 32 idle.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Tuple

#: Trials per decision (the robot's online default K, D, lambda otherwise): enough for the
#: decisions on the robot models to settle (the same actions at 2x and 4x the trials).
DEFAULT_TRIALS = 300


@dataclass(frozen=True)
class ObservationSequence:
    """A named sequence of observations and what it shows of the human."""

    name: str
    observations: Tuple[str, ...]
    what: str


#: The typical sequences: the first few are what a considerate robot must get right.
SEQUENCES: Tuple[ObservationSequence, ...] = (
    ObservationSequence("warning", ("O19",),
                        "the human warns the robot off (object visible and in range)"),
    ObservationSequence("warning_unseen", ("O16",),
                        "a warning while the object is neither visible nor in range"),
    ObservationSequence("failed_then_warning", ("O7", "O7", "O19"),
                        "two failed grasps, then a warning"),
    ObservationSequence("failed_grasp", ("O7",), "one failed grasp (object in view and range)"),
    ObservationSequence("failed_grasps", ("O7", "O7", "O7", "O7"),
                        "four failed grasps in a row"),
    ObservationSequence("idle_once", ("O35",), "the human idles once, object in view and range"),
    ObservationSequence("idle_streak", ("O35",) * 6, "six idle steps in a row"),
    ObservationSequence("looks_away", ("O2", "O2", "O2"),
                        "object in range but not seen, three steps (attention lost)"),
    ObservationSequence("human_away", ("O0", "O0", "O0"),
                        "nothing seen, nothing in range, three steps (walked away)"),
    ObservationSequence("holds_object", ("O7", "O11"),
                        "a failed grasp, then the human holds the object"),
)


def parse_sequence(text: str) -> ObservationSequence:
    """A sequence a user names on the command line, ``NAME=O7,O7,O19`` (commas or spaces);
    ValueError saying what is wrong. Its observations are checked against the model later
    (:func:`check_sequences`)."""
    name, sep, observations = text.partition("=")
    name = name.strip()
    words = observations.replace(",", " ").split()
    if not sep or not name or not words:
        raise ValueError(f"sequence {text!r}: expected NAME=OBS,OBS,... (e.g. "
                         f"fails_after_warning=O7,O19,O7,O7)")
    return ObservationSequence(name, tuple(words), "given on the command line")
