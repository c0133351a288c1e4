"""Beliefs: the exact Bayes filter for small models and a particle filter for large ones.

``update(model, b, a, o)`` is the textbook filter b'(s') ∝ O(o | s', a) Σ_s T(s' | s, a) b(s).
When the observation has probability zero under ``b`` it raises ``ZeroProbabilityObservation``;
callers that must keep going (planners) then use ``Belief.predict(a)``, the belief propagated
through T alone, as the documented fallback, and report the event.

Every random draw takes a seeded ``numpy.random.Generator``: nothing reads global random state.
"""
from __future__ import annotations

import weakref
from abc import ABC, abstractmethod
from typing import Dict, Optional, Tuple

import numpy as np

from ros_hrc.errors import SolverError, ZeroProbabilityObservation
from ros_hrc.pomdp.model import DENSE_STATE_LIMIT, Model
from ros_hrc.pomdp.sampling import ModelSampler, sample_from

__all__ = ["DENSE_STATE_LIMIT", "ZERO_PROBABILITY", "update", "predict", "Belief", "ExactBelief",
           "ParticleBelief", "make_belief"]

#: A probability of an observation at or below this counts as zero (rounding in printed tables).
ZERO_PROBABILITY = 1e-300


class _Filter:
    """Per-model tables for the exact update, dense when the model is small."""

    def __init__(self, model: Model) -> None:
        # The tables, not the model, are kept so the cache below does not keep models alive.
        self.T = model.T
        self.O = model.O
        # Small models (Model.dense_tables_fit: A·S² floats at most) update with dense tables.
        self.dense = model.dense_tables_fit
        if self.dense:
            self.T = model.dense_T
            self.O = model.dense_O
        self._columns: Dict[Tuple[int, int], np.ndarray] = {}

    def predict(self, b: np.ndarray, a: int) -> np.ndarray:
        if self.dense:
            return b @ self.T[a]
        return np.asarray(self.T[a].T @ b).ravel()

    def obs_column(self, a: int, o: int) -> np.ndarray:
        """O(o | s', a) for every s'."""
        if self.dense:
            return self.O[a][:, o]
        col = self._columns.get((a, o))
        if col is None:
            col = self.O[a][:, o].toarray().ravel()
            self._columns[(a, o)] = col
        return col


_FILTERS: Dict[int, Tuple["weakref.ref", _Filter]] = {}


def _filter_for(model: Model) -> _Filter:
    """The model's filter tables, built once per model.

    Keyed by identity (models are unhashable dataclasses); an entry goes when its model does.
    """
    entry = _FILTERS.get(id(model))
    if entry is None or entry[0]() is not model:
        entry = (weakref.ref(model), _Filter(model))
        _FILTERS[id(model)] = entry
        weakref.finalize(model, _FILTERS.pop, id(model), None)
    return entry[1]


def _check_indices(model: Model, a: int, o: int) -> None:
    if not 0 <= a < model.n_actions:
        raise SolverError(f"action {a} out of range 0..{model.n_actions - 1}")
    if not 0 <= o < model.n_observations:
        raise SolverError(f"observation {o} out of range 0..{model.n_observations - 1}")


def update(model: Model, b: np.ndarray, a: int, o: int) -> Tuple[np.ndarray, float]:
    """Exact Bayes update: (b', P(o | b, a)).

    Raises ZeroProbabilityObservation when P(o | b, a) is zero (b' would be undefined).
    """
    _check_indices(model, a, o)
    f = _filter_for(model)
    joint = f.predict(np.asarray(b, dtype=float), a) * f.obs_column(a, o)
    p_o = float(joint.sum())
    if p_o <= ZERO_PROBABILITY:
        raise ZeroProbabilityObservation(a, o, "exact belief")
    return joint / p_o, p_o


def predict(model: Model, b: np.ndarray, a: int) -> np.ndarray:
    """The belief after action ``a`` with the observation ignored: b'(s') = Σ_s T(s'|s,a) b(s)."""
    out = _filter_for(model).predict(np.asarray(b, dtype=float), a)
    return out / out.sum()


class Belief(ABC):
    """What a planner needs from a belief, whatever its representation."""

    model: Model

    @abstractmethod
    def probabilities(self) -> np.ndarray:
        """The belief as a distribution over states, shape (S,)."""

    @abstractmethod
    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` states drawn independently from the belief."""

    def sample_systematic(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` states by systematic (stratified) sampling: one uniform offset, n even strata.

        Each state appears within one of n·b(s) times, so sample means of state functions are
        far less noisy than with independent draws (DESPOT's scenarios use this).
        """
        positions = (rng.random() + np.arange(n)) / n
        return self._from_positions(positions)

    def _from_positions(self, positions: np.ndarray) -> np.ndarray:
        probs = self.probabilities()
        return sample_from(np.cumsum(probs), positions)

    @abstractmethod
    def update(self, a: int, o: int) -> float:
        """Condition on (a, o); returns (an estimate of) P(o | b, a).

        Raises ZeroProbabilityObservation and leaves the belief unchanged when that is zero.
        """

    @abstractmethod
    def predict(self, a: int) -> None:
        """Propagate through T only: the fallback after a zero-probability observation."""

    @abstractmethod
    def reset(self, b: Optional[np.ndarray] = None) -> None:
        """Back to ``b`` (a distribution over states), or to the model's initial belief."""


class ExactBelief(Belief):
    """A full probability vector, updated exactly."""

    def __init__(self, model: Model, b: Optional[np.ndarray] = None) -> None:
        self.model = model
        self.b = np.empty(model.n_states)
        self.reset(b)

    def probabilities(self) -> np.ndarray:
        return self.b

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return sample_from(np.cumsum(self.b), rng.random(n))

    def update(self, a: int, o: int) -> float:
        self.b, p_o = update(self.model, self.b, a, o)
        return p_o

    def predict(self, a: int) -> None:
        self.b = predict(self.model, self.b, a)

    def reset(self, b: Optional[np.ndarray] = None) -> None:
        self.b = _as_distribution(self.model, b)


class ParticleBelief(Belief):
    """Weighted particles (states): propagated by sampling T, weighted by O, resampled when
    degenerate.

    Resampling is systematic and happens when the effective sample size falls below
    ``resample_threshold`` times the particle count.
    """

    def __init__(self, model: Model, n_particles: int, rng: np.random.Generator,
                 b: Optional[np.ndarray] = None, sampler: Optional[ModelSampler] = None,
                 resample_threshold: float = 0.5) -> None:
        if n_particles < 1:
            raise SolverError(f"a particle belief needs at least one particle, got {n_particles}")
        self.model = model
        self.n = int(n_particles)
        self.rng = rng
        self.sampler = sampler if sampler is not None else ModelSampler(model)
        self.resample_threshold = resample_threshold
        self.states = np.zeros(self.n, dtype=np.int64)
        self.weights = np.full(self.n, 1.0 / self.n)
        self.reset(b)

    def probabilities(self) -> np.ndarray:
        return np.bincount(self.states, weights=self.weights, minlength=self.model.n_states)

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return self.states[sample_from(np.cumsum(self.weights), rng.random(n))]

    def _propagate(self, a: int) -> np.ndarray:
        u = self.rng.random((2, self.n))
        nxt, _, _ = self.sampler.step(self.states, a, u[0], u[1])
        return nxt

    def update(self, a: int, o: int) -> float:
        _check_indices(self.model, a, o)
        nxt = self._propagate(a)
        w = self.weights * _filter_for(self.model).obs_column(a, o)[nxt]
        total = float(w.sum())
        if total <= ZERO_PROBABILITY:
            raise ZeroProbabilityObservation(a, o, f"no particle of {self.n} explains it")
        self.states = nxt
        self.weights = w / total
        if 1.0 / float(np.dot(self.weights, self.weights)) < self.resample_threshold * self.n:
            self._resample()
        return total

    def predict(self, a: int) -> None:
        self.states = self._propagate(a)

    def _from_positions(self, positions: np.ndarray) -> np.ndarray:
        return self.states[sample_from(np.cumsum(self.weights), positions)]

    def _resample(self) -> None:
        positions = (self.rng.random() + np.arange(self.n)) / self.n
        idx = np.minimum(np.searchsorted(np.cumsum(self.weights), positions, side="right"),
                         self.n - 1)
        self.states = self.states[idx]
        self.weights = np.full(self.n, 1.0 / self.n)

    def reset(self, b: Optional[np.ndarray] = None) -> None:
        dist = _as_distribution(self.model, b)
        self.states = sample_from(np.cumsum(dist), self.rng.random(self.n))
        self.weights = np.full(self.n, 1.0 / self.n)


def make_belief(model: Model, rng: np.random.Generator, particles: Optional[int] = None,
                b: Optional[np.ndarray] = None,
                sampler: Optional[ModelSampler] = None) -> Belief:
    """An exact belief, or a particle belief when ``particles`` is given (stepped with
    ``sampler``, or a ModelSampler of its own)."""
    if particles:
        return ParticleBelief(model, particles, rng, b, sampler=sampler)
    return ExactBelief(model, b)


def _as_distribution(model: Model, b: Optional[np.ndarray]) -> np.ndarray:
    """``b`` checked and normalised (a copy), or the model's initial belief."""
    arr = np.array(model.initial_belief if b is None else b, dtype=float)
    if arr.shape != (model.n_states,):
        raise SolverError(f"belief has shape {arr.shape}, expected ({model.n_states},)")
    if not np.all(np.isfinite(arr)) or arr.min() < 0 or arr.sum() <= 0:
        raise SolverError("belief must be non-negative, finite and not all zero")
    return arr / arr.sum()
