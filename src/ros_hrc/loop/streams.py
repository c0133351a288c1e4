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
"""
from __future__ import annotations

import operator
from typing import Tuple

import numpy as np

__all__ = ["ROLES", "MAX_SEED", "MAX_EPISODE", "stream", "generator", "stream_seed"]

#: Who draws from a stream. Appending a role keeps every existing stream as it was; reordering
#: or renaming one changes the streams of every recorded run, so don't.
ROLES: Tuple[str, ...] = ("human", "world", "planner")

#: The seed and episode travel through ROS messages and parameters as uint32.
MAX_SEED = 2 ** 32 - 1
MAX_EPISODE = 2 ** 32 - 1


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
    seed = _checked("seed", seed, MAX_SEED)
    episode = _checked("episode", episode, MAX_EPISODE)
    if role not in ROLES:
        raise ValueError(f"unknown stream role {role!r}: expected one of {', '.join(ROLES)}")
    return np.random.SeedSequence(entropy=seed, spawn_key=(episode, ROLES.index(role)))


def generator(seed: int, episode: int, role: str) -> np.random.Generator:
    """A fresh ``numpy.random.Generator`` on :func:`stream` (seed, episode, role)."""
    return np.random.default_rng(stream(seed, episode, role))


def stream_seed(seed: int, episode: int, role: str) -> int:
    """A 64-bit integer drawn from :func:`stream` (seed, episode, role), for a consumer that
    takes an integer seed (a planner, a process started with ``--seed``)."""
    high, low = stream(seed, episode, role).generate_state(2, np.uint32)
    return (int(high) << 32) | int(low)
