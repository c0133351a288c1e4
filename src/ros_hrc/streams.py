"""Independent random streams: one per (seed, episode, role) (DESIGN §14; no ROS, no sockets).

A study's episodes must be independent draws: no two episodes of a grid may share the stream
of the human, of the world or of the planner, and replaying one (seed, episode) on its own must
give exactly that episode again. Adding the episode to the seed (``seed + episode``) fails the
first (seed 1, episode e replays seed 0, episode e + 1); this module is the one place a stream
is derived instead, with ``numpy.random.SeedSequence``: ``seed`` is the entropy and
``(episode, role)`` the spawn key, so streams of different keys are independent by
construction (NumPy's hashing of the key; see NumPy's "Parallel random number generation").

    stream(seed, episode, "human")      -> a SeedSequence
    generator(seed, episode, "world")   -> a numpy Generator on that stream
    stream_seed(seed, episode, "planner") -> a 64-bit integer seed, for consumers that take one

Who draws: the human MDP process (``despot_mdp``) reseeds its agent from the ``human`` stream at
each episode's reset, the robot process (``despot_pomdp``) its planner from ``planner``, and the
world (``hrc_world``) its generator (the walk-away's heading) from ``world``; a sequence's selector
(:mod:`ros_hrc.agents.selectors`) its choices from ``selector``, the sequence's number as the
episode, and a learning robot (:mod:`ros_hrc.agents.learning`) its posterior draws from
``learning``, numbered the same way; each learns the
episode's number at that reset, from the coordinator (``reset.episode``; the world through the
``/hrc/world/episode`` parameter). A task with observation noise (:mod:`ros_hrc.tasks`) draws
it in the coordinator from ``observation``, restarted at each episode's start. The number is
the study's: a live launch plays episodes 1,
2, 3 ...; an experiment cell plays the episodes it was asked for (:class:`EpisodeSchedule`,
the launch argument ``episodes``), in order, so that (seed, episode) is the same episode
whichever others ran before it.
"""
from __future__ import annotations

import operator
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterable, Optional, Tuple

if TYPE_CHECKING:
    import numpy as np

__all__ = ["ROLES", "MAX_SEED", "MAX_EPISODE", "checked_seed", "stream", "generator", "stream_seed",
           "EpisodeSchedule", "WORLD_EPISODE_PARAM", "WORLD_SEED_PARAM"]

#: Who draws from a stream. Appending a role keeps every existing stream as it was; reordering
#: or renaming one changes the streams of every recorded run, so don't.
ROLES: Tuple[str, ...] = ("human", "world", "planner", "observation", "selector", "learning")

#: The ROS parameter the coordinator's node (hrc_human) sets to the episode that starts just
#: before it resets the world (``/hrc/world/reset``, a Trigger); hrc_world reads it there.
WORLD_EPISODE_PARAM = "/hrc/world/episode"
#: The parameter holding the run's seed, set with :data:`WORLD_EPISODE_PARAM` (a warm stack's
#: next cell plays another seed on the same world).
WORLD_SEED_PARAM = "/hrc/world/seed"

#: The largest seed, the one range of every entry point (the ``seed`` launch argument, the
#: solver processes' and hrc_experiment's, hrc_fit's and hrc_pomdp's ``--seed``): the seed is a
#: ROS parameter (``/hrc/config``, :data:`WORLD_SEED_PARAM`, the nodes' own), and the parameter
#: server's ints are XML-RPC's signed 32-bit ones (roslaunch fails with a traceback on a larger
#: one). A run seeded past it could not be launched again.
MAX_SEED = 2 ** 31 - 1
#: The episode travels in ROS messages (Status, TaskStatus) as uint32.
MAX_EPISODE = 2 ** 32 - 1


def checked_seed(seed: int) -> int:
    """``seed`` as an int when it is one from 0 to :data:`MAX_SEED`; ValueError (one line,
    saying the range) otherwise."""
    return _checked("seed", seed, MAX_SEED)


def _checked(name: str, value: int, high: int) -> int:
    if isinstance(value, bool):
        raise ValueError(f"{name} must be an integer from 0 to {high}, got {value!r}")
    try:
        value = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be an integer from 0 to {high}, got {value!r}") from None
    if not 0 <= value <= high:
        raise ValueError(f"{name} must be an integer from 0 to {high}, got {value}")
    return value


def stream(seed: int, episode: int, role: str) -> np.random.SeedSequence:
    """The SeedSequence of ``role``'s draws in episode ``episode`` of a run seeded ``seed``."""
    seed = checked_seed(seed)
    episode = _checked("episode", episode, MAX_EPISODE)
    if role not in ROLES:
        raise ValueError(f"unknown stream role {role!r}: expected one of {', '.join(ROLES)}")
    import numpy as np     # here: the seed's range is read by hrc_pomdp's parser, numpy-free
    return np.random.SeedSequence(entropy=seed, spawn_key=(episode, ROLES.index(role)))


def next_episode(episode: Optional[int]) -> int:
    """The number after ``episode`` (a solver reset without a number starts the next): 0
    after none, and after the largest (:data:`MAX_EPISODE`) 0 again, never a number no stream
    takes."""
    return 0 if episode is None or episode >= MAX_EPISODE else episode + 1


def generator(seed: int, episode: int, role: str) -> np.random.Generator:
    """A fresh ``numpy.random.Generator`` on :func:`stream` (seed, episode, role)."""
    import numpy as np
    return np.random.default_rng(stream(seed, episode, role))


def stream_seed(seed: int, episode: int, role: str) -> int:
    """A 64-bit integer drawn from :func:`stream` (seed, episode, role), for a consumer that
    takes an integer seed (a planner, a process started with ``--seed``)."""
    import numpy as np
    high, low = stream(seed, episode, role).generate_state(2, np.uint32)
    return (int(high) << 32) | int(low)


#: The ``episodes`` text of no schedule: 1, 2, 3 ..., each reset the next (a live launch).
LIVE = "live"

_SPAN = re.compile(r"\s*([0-9]+)\s*(?:-\s*([0-9]+)\s*)?")


@dataclass(frozen=True)
class EpisodeSchedule:
    """The episode numbers a run plays, in increasing order: sorted, disjoint half-open spans
    ``[start, stop)`` (``0-999999`` is two integers, not a million).

    As text (the launch argument ``episodes``): numbers and inclusive ranges separated by
    commas, ``"2,5-7"`` is 2, 5, 6, 7; ``live`` (or the empty text) is no schedule, the live
    default: 1, 2, 3 ... with no end, each reset the next (``None`` from :meth:`parse`)."""

    spans: Tuple[Tuple[int, int], ...]

    @classmethod
    def of(cls, numbers: Iterable[int]) -> "EpisodeSchedule":
        spans: list = []
        for n in sorted(set(_checked("episode", n, MAX_EPISODE) for n in numbers)):
            if spans and spans[-1][1] == n:
                spans[-1][1] = n + 1
            else:
                spans.append([n, n + 1])
        if not spans:
            raise ValueError("an episode schedule needs at least one episode")
        return cls(tuple((a, b) for a, b in spans))

    @classmethod
    def parse(cls, text: str) -> Optional["EpisodeSchedule"]:
        """The schedule ``text`` names; None for ``live`` or the empty text (1, 2, 3 ...).
        ValueError naming what is wrong otherwise."""
        text = str(text).strip()
        if text in ("", LIVE):
            return None
        spans = []
        for part in text.split(","):
            match = _SPAN.fullmatch(part)
            if not match:
                raise ValueError(f"episodes {text!r}: {part.strip()!r} is not a number nor a "
                                 "range a-b (e.g. 2,5-7)")
            low = _checked("episode", int(match.group(1)), MAX_EPISODE)
            high = _checked("episode", int(match.group(2) or low), MAX_EPISODE)
            if high < low:
                raise ValueError(f"episodes {text!r}: the range {low}-{high} is empty")
            spans.append((low, high + 1))
        spans.sort()
        merged: list = []
        for a, b in spans:
            if merged and a <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b])
        return cls(tuple((a, b) for a, b in merged))

    def text(self) -> str:
        """The schedule as :meth:`parse` reads it."""
        return ",".join(str(a) if b == a + 1 else f"{a}-{b - 1}" for a, b in self.spans)

    def first(self) -> int:
        return self.spans[0][0]

    def after(self, episode: int) -> Optional[int]:
        """The first scheduled episode past ``episode``; None when none is left."""
        for a, b in self.spans:
            if episode + 1 < b:
                return max(a, episode + 1)
        return None

    def __len__(self) -> int:
        return sum(b - a for a, b in self.spans)
