"""Which human streams a fitted robot model was fitted on: written by hrc_fit, read by
hrc_experiment (held-out discipline, DESIGN §14). No ROS.

``hrc_fit`` writes one machine-readable comment line per human model into the fitted model's
header, after the words for people::

    # hrc-fitted-on: {"human_model": "beginner", "sha256": "<the human model file's>", "seed": 0, "episodes": [0, 100]}

``episodes`` is the half-open range ``[start, stop)`` of episode numbers fitted on with that
seed. A human model is known by its file's contents (SHA-256), so a copy or another name of
the same file is the same human. ``hrc_experiment`` reads these lines from every robot model a
policy runs with and refuses to evaluate it on a (human model, seed, episode) stream in them,
unless ``--allow-in-sample`` (then such rows are marked ``in_sample``).
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from typing import Iterable, List, Tuple, Union

#: The marker of a fitted-on line (after ``# ``).
FITTED_ON = "hrc-fitted-on:"


@dataclass(frozen=True)
class FittedStreams:
    """Episodes ``[start, stop)`` of one human model (by contents) and one seed, fitted on."""
    human_model: str       # the name hrc_fit was given (for messages)
    sha256: str            # the human model file's contents
    seed: int
    episodes: Tuple[int, int]

    def covers(self, human_sha256: str, seed: int, episode: int) -> bool:
        start, stop = self.episodes
        return (human_sha256, seed) == (self.sha256, self.seed) and start <= episode < stop

    def line(self) -> str:
        """The header line (without ``# ``)."""
        return FITTED_ON + " " + json.dumps({
            "human_model": self.human_model, "sha256": self.sha256, "seed": self.seed,
            "episodes": list(self.episodes)})


def file_sha256(path: Union[str, os.PathLike]) -> str:
    """The SHA-256 of a file's contents, in hex."""
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def read_fitted_on(path: Union[str, os.PathLike]) -> List[FittedStreams]:
    """The fitted-on lines of a model file's leading comments ([] for a model that says
    none: not fitted by hrc_fit, or fitted before these lines existed). ValueError naming the
    file and the line for a fitted-on line that cannot be read."""
    found: List[FittedStreams] = []
    with open(path, "r", encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            text = line.strip()
            if text and not text.startswith("#"):
                break       # the header is over
            body = text.lstrip("#").strip()
            if not body.startswith(FITTED_ON):
                continue
            try:
                data = json.loads(body[len(FITTED_ON):])
                start, stop = (int(v) for v in data["episodes"])
                found.append(FittedStreams(str(data["human_model"]), str(data["sha256"]),
                                           int(data["seed"]), (start, stop)))
            except (ValueError, KeyError, TypeError) as exc:
                raise ValueError(f"{path}:{number}: unreadable {FITTED_ON} line ({exc})") \
                    from None
    return found


def ranges_text(numbers: Iterable[int]) -> str:
    """``0-9, 12`` for 0..9 and 12 (sorted, runs joined)."""
    spans: List[List[int]] = []
    for n in sorted(set(numbers)):
        if spans and spans[-1][1] == n - 1:
            spans[-1][1] = n
        else:
            spans.append([n, n])
    return ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in spans)
