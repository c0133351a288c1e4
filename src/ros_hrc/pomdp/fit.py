"""Fitting a POMDP's T and O to labelled experience, with a model as a Dirichlet prior.

The ROS-free core of ``hrc_fit``: whatever produces the experience (episodes in the ROS stack,
or :func:`sample_experience` from a known model), it arrives here as counts

* ``transitions[a, s, s']`` -- how often action ``a`` in state ``s`` led to ``s'``;
* ``observations[a, s', o]`` -- how often ``o`` was observed on reaching ``s'`` by action ``a``

(:class:`ExperienceCounts`), and :func:`fit_model` turns a prior model and the counts into the
posterior mean of a Dirichlet per row. With prior row ``p`` (``T[a][s, :]`` or ``O[a][s', :]``),
its strength ``k`` (pseudo-counts per row) and the row's counts ``n`` (``N = sum(n)``)::

    fitted row = (k * p + n) / (k * sum(p) + N)        where N > 0
    fitted row = p, unchanged                          where N = 0

``sum(p)`` is 1 within the reader's tolerance; dividing by it (not by 1) makes every fitted row
an exact distribution. ``k = 0`` is maximum likelihood (the observed frequencies) wherever a row
has counts, and the prior where it has none; a large ``k`` stays near the prior. Rewards,
discount, initial belief, names and flags are the prior's: experience fits the dynamics and the
sensing, never what the designer wants. (An MDP or mixed-observability prior keeps that
structure only while the fitted O puts no weight where the prior's O has none.)

:func:`write_fitted` writes the result as a Cassandra ``.pomdp`` with ``#`` header lines saying
how it was made; the numbers are written exactly (shortest round-trip text), so reading the file
back gives the same tables bit for bit.

Counts are dense numpy arrays (A x S x S' and A x S' x O): meant for the HRC models (a few
states), refused above :data:`MAX_CELLS` cells.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Callable, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import ModelError
from ros_hrc.pomdp import cassandra
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.output import write_atomically
from ros_hrc.pomdp.sampling import ModelSampler

__all__ = ["MAX_CELLS", "ExperienceCounts", "RowSupport", "fit_model", "posterior_table",
           "row_support",
           "support_lines", "fit_header", "fitted_text", "write_fitted", "sample_experience",
           "uniform_policy"]

#: The largest count table (A x S x S' or A x S' x O cells) :class:`ExperienceCounts` holds.
MAX_CELLS = 50_000_000

Label = Union[int, str]


# --------------------------------------------------------------------------------------------
# Counts
# --------------------------------------------------------------------------------------------
@dataclass
class ExperienceCounts:
    """Counts of labelled transitions ``transitions[a, s, s']`` and observations
    ``observations[a, s', o]`` (int64 arrays); build one with :meth:`for_model` or :meth:`zeros`.
    """

    transitions: np.ndarray                    # (A, S, S')
    observations: np.ndarray                   # (A, S', O)

    def __post_init__(self) -> None:
        t = np.asarray(self.transitions)
        o = np.asarray(self.observations)
        if t.ndim != 3 or t.shape[1] != t.shape[2]:
            raise ModelError(f"transition counts must have shape (A, S, S), not {t.shape}")
        if o.ndim != 3 or o.shape[:2] != t.shape[:2]:
            raise ModelError(f"observation counts must have shape (A, S, O) = "
                             f"({t.shape[0]}, {t.shape[1]}, O), not {o.shape}")
        for label, arr in (("transition", t), ("observation", o)):
            if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
                raise ModelError(f"{label} counts must be numbers, not {arr.dtype}")
            if arr.size and not np.all(np.isfinite(arr)):
                raise ModelError(f"{label} counts hold a NaN or an infinity")
            if arr.size and arr.min() < 0:
                raise ModelError(f"{label} counts hold a negative count ({arr.min():g})")
            if np.issubdtype(arr.dtype, np.floating) and np.any(arr != np.round(arr)):
                raise ModelError(f"{label} counts must be whole numbers")
        self.transitions = t.astype(np.int64)
        self.observations = o.astype(np.int64)

    # -- construction -----------------------------------------------------------------------
    @classmethod
    def zeros(cls, n_actions: int, n_states: int, n_observations: int) -> "ExperienceCounts":
        """Empty counts for the given sizes."""
        cells = n_actions * n_states * max(n_states, n_observations)
        if cells > MAX_CELLS:
            raise ModelError(f"{n_actions} actions x {n_states} states x "
                             f"{max(n_states, n_observations)} are too many cells to count "
                             f"densely (limit {MAX_CELLS:,})")
        return cls(np.zeros((n_actions, n_states, n_states), dtype=np.int64),
                   np.zeros((n_actions, n_states, n_observations), dtype=np.int64))

    @classmethod
    def for_model(cls, model: Model) -> "ExperienceCounts":
        """Empty counts sized for ``model``."""
        return cls.zeros(model.n_actions, model.n_states, model.n_observations)

    @classmethod
    def from_steps(cls, model: Model,
                   steps: Iterable[Tuple[Label, Label, Label, Label]]) -> "ExperienceCounts":
        """Counts of steps ``(state, action, next_state, observation)``, by name or index."""
        counts = cls.for_model(model)
        for step in steps:
            counts.add_step(*step, model=model)
        return counts

    # -- sizes --------------------------------------------------------------------------------
    @property
    def n_actions(self) -> int:
        return self.transitions.shape[0]

    @property
    def n_states(self) -> int:
        return self.transitions.shape[1]

    @property
    def n_observations(self) -> int:
        return self.observations.shape[2]

    @property
    def shape(self) -> Tuple[int, int, int]:
        """(actions, states, observations)."""
        return self.n_actions, self.n_states, self.n_observations

    @property
    def n_transitions(self) -> int:
        """How many transitions were counted."""
        return int(self.transitions.sum())

    @property
    def n_observations_counted(self) -> int:
        """How many observations were counted."""
        return int(self.observations.sum())

    # -- adding -------------------------------------------------------------------------------
    def add_transition(self, s: Label, a: Label, s2: Label, model: Optional[Model] = None) -> None:
        """Count action ``a`` in state ``s`` leading to ``s2`` (indices, or names and ``model``)."""
        s = self._index(model, "state", s, self.n_states)
        a = self._index(model, "action", a, self.n_actions)
        s2 = self._index(model, "state", s2, self.n_states)
        self.transitions[a, s, s2] += 1

    def add_observation(self, a: Label, s2: Label, o: Label, model: Optional[Model] = None) -> None:
        """Count observation ``o`` on reaching ``s2`` by action ``a``."""
        a = self._index(model, "action", a, self.n_actions)
        s2 = self._index(model, "state", s2, self.n_states)
        o = self._index(model, "observation", o, self.n_observations)
        self.observations[a, s2, o] += 1

    def add_step(self, s: Label, a: Label, s2: Label, o: Label,
                 model: Optional[Model] = None) -> None:
        """Count one step: the transition (s, a, s') and the observation (a, s', o)."""
        self.add_transition(s, a, s2, model)
        self.add_observation(a, s2, o, model)

    def add(self, other: "ExperienceCounts") -> "ExperienceCounts":
        """Add ``other``'s counts to these (same sizes); returns self."""
        if not isinstance(other, ExperienceCounts):
            raise TypeError(f"cannot add {type(other).__name__} to ExperienceCounts")
        if other.shape != self.shape:
            raise ModelError(f"cannot merge counts of sizes {other.shape} into {self.shape} "
                             "(actions, states, observations)")
        self.transitions += other.transitions
        self.observations += other.observations
        return self

    def __iadd__(self, other: "ExperienceCounts") -> "ExperienceCounts":
        return self.add(other)

    def __add__(self, other: "ExperienceCounts") -> "ExperienceCounts":
        return self.copy().add(other)

    def copy(self) -> "ExperienceCounts":
        return ExperienceCounts(self.transitions.copy(), self.observations.copy())

    def __eq__(self, other) -> bool:
        return (isinstance(other, ExperienceCounts)
                and np.array_equal(self.transitions, other.transitions)
                and np.array_equal(self.observations, other.observations))

    @staticmethod
    def _index(model: Optional[Model], kind: str, label: Label, size: int) -> int:
        if isinstance(label, str):
            if model is None:
                raise ModelError(f"{kind} {label!r} is a name: pass the model to look it up")
            return model.index(kind, label)
        if isinstance(label, (bool, np.bool_)) or not isinstance(label, (int, np.integer)):
            raise ModelError(f"{kind} {label!r} is neither an index nor a name")
        index = int(label)
        if not 0 <= index < size:
            raise ModelError(f"{kind} index {index} is outside 0..{size - 1}")
        return index


# --------------------------------------------------------------------------------------------
# Support
# --------------------------------------------------------------------------------------------
@dataclass
class RowSupport:
    """How many samples each row of T and O had: ``transitions[a, s]``, ``observations[a, s']``."""

    transitions: np.ndarray                    # (A, S)
    observations: np.ndarray                   # (A, S')

    def weakest(self) -> int:
        """The fewest samples any row had (0 when some row had none)."""
        both = np.concatenate([self.transitions.ravel(), self.observations.ravel()])
        return int(both.min()) if both.size else 0


def row_support(counts: ExperienceCounts) -> RowSupport:
    """Samples per row: ``T[a][s, :]`` had ``transitions[a, s]``, ``O[a][s', :]`` had
    ``observations[a, s']``."""
    return RowSupport(counts.transitions.sum(axis=2), counts.observations.sum(axis=2))


def support_lines(model: Model, counts: ExperienceCounts, minimum: int = 30) -> List[str]:
    """Text for a report: totals, then every row with fewer than ``minimum`` samples (whose
    fitted row leans on the prior), or a line saying every row has at least that many."""
    _check_sizes(model, counts)
    support = row_support(counts)
    lines = [f"{counts.n_transitions} transitions, {counts.n_observations_counted} "
             f"observations; rows with fewer than {minimum} samples:"]
    weak = 0
    for label, table in (("T", support.transitions), ("O", support.observations)):
        for a, s in zip(*np.nonzero(table < minimum)):
            lines.append(f"  {label}: {model.actions[a]} : {model.states[s]}  "
                         f"{int(table[a, s])} sample(s)")
            weak += 1
    if not weak:
        lines[0] = (f"{counts.n_transitions} transitions, {counts.n_observations_counted} "
                    f"observations; every row has at least {minimum} samples")
    return lines


# --------------------------------------------------------------------------------------------
# Fitting
# --------------------------------------------------------------------------------------------
def _check_sizes(model: Model, counts: ExperienceCounts) -> None:
    want = (model.n_actions, model.n_states, model.n_observations)
    if counts.shape != want:
        who = f"the model {model.name}" if model.name else "the model"
        raise ModelError(f"the counts are for {counts.shape[0]} actions, {counts.shape[1]} states "
                         f"and {counts.shape[2]} observations; {who} has {want[0]}, {want[1]} "
                         f"and {want[2]}")


def _check_strength(strength) -> float:
    try:
        k = float(strength)
    except (TypeError, ValueError):
        raise ValueError(f"the prior's strength must be a number, not {strength!r}") from None
    if not math.isfinite(k) or k < 0:
        raise ValueError(f"the prior's strength must be a finite number >= 0, not {strength!r}")
    return k


def posterior_table(prior: sp.csr_matrix, n: np.ndarray, k: float) -> sp.csr_matrix:
    """Row-wise Dirichlet posterior mean of one table with ``k`` pseudo-counts per prior row
    and counts ``n`` (whole, or expected: :mod:`ros_hrc.pomdp.bayes_adaptive`); rows without
    counts keep the prior."""
    p = sp.csr_matrix(prior).toarray().astype(float)
    n = n.astype(float)
    N = n.sum(axis=1)
    seen = N > 0
    out = p.copy()
    if seen.any():
        alpha = k * p[seen] + n[seen]
        out[seen] = alpha / alpha.sum(axis=1, keepdims=True)
    m = sp.csr_matrix(out)
    m.eliminate_zeros()
    m.sort_indices()
    return m


def _support_within(fitted: sp.csr_matrix, prior: sp.csr_matrix) -> bool:
    """True when every nonzero cell of ``fitted`` is nonzero in ``prior`` too."""
    f = (sp.csr_matrix(fitted) != 0).astype(np.int8)
    p = (sp.csr_matrix(prior) != 0).astype(np.int8)
    return not ((f - p) > 0).nnz


def fit_model(prior: Model, counts: ExperienceCounts, strength: float,
              name: Optional[str] = None) -> Model:
    """T and O fitted to ``counts`` with ``prior`` as a Dirichlet prior of ``strength``
    pseudo-counts per row (see the module docstring); everything else is the prior's.

    ``strength`` 0 gives the observed frequencies where a row has counts and the prior's row
    where it has none. A fully observable prior (or a mixed-observability one, with
    ``observed_key``) stays so while no fitted O row puts weight where the prior's row has none;
    otherwise the result is a plain POMDP.

    Raises ModelError for counts of other sizes or an invalid prior, and ValueError for a
    negative, NaN or infinite strength.
    """
    k = _check_strength(strength)
    prior.validate()
    _check_sizes(prior, counts)
    T = [posterior_table(prior.T[a], counts.transitions[a], k) for a in range(prior.n_actions)]
    O = [posterior_table(prior.O[a], counts.observations[a], k) for a in range(prior.n_actions)]
    # The prior's observation structure (an MDP's identity O, a MOMDP's observed values) still
    # holds while no fitted O row gives weight to an observation its prior row rules out.
    same_support = all(_support_within(o, po) for o, po in zip(O, prior.O))
    meta = dict(prior.meta)
    meta["fit"] = {"prior": prior.name, "strength": k, "transitions": counts.n_transitions,
                   "observations": counts.n_observations_counted}
    changes = dict(states=list(prior.states), actions=list(prior.actions),
                   observations=list(prior.observations),
                   initial_belief=np.array(prior.initial_belief, dtype=float, copy=True),
                   T=T, O=O, R=[sp.csr_matrix(r, copy=True) for r in prior.R],
                   fully_observable=prior.fully_observable and same_support,
                   observed_key=(np.array(prior.observed_key, copy=True)
                                 if prior.observed_key is not None and same_support else None),
                   name=name if name is not None else f"{prior.name or 'model'}-fitted",
                   source=None, meta=meta)
    model = dataclasses.replace(prior, **changes)
    model.validate()
    return model


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------
def fit_header(strength: float, counts: ExperienceCounts, prior: str = "",
               **items) -> List[str]:
    """Header lines for :func:`write_fitted`: ``key: value`` for the prior, its strength, the
    counts and each further item (e.g. ``models=..., episodes=..., seed=...``), in order."""
    lines = ["fitted by ros_hrc: T and O are Dirichlet posterior means, the prior's rows "
             "weighted by its strength"]
    if prior:
        lines.append(f"prior: {prior}")
    lines.append(f"strength: {_check_strength(strength):g} pseudo-counts per row")
    for key, value in items.items():
        if isinstance(value, (list, tuple)):
            value = " ".join(str(v) for v in value)
        lines.append(f"{key}: {value}")
    lines.append(f"counts: {counts.n_transitions} transitions, "
                 f"{counts.n_observations_counted} observations")
    return lines


def fitted_text(model: Model, header_lines: Sequence[str]) -> str:
    """The Cassandra text of ``model`` with ``header_lines`` first, each as a ``# `` comment."""
    comments = []
    for line in header_lines:
        for part in str(line).splitlines() or [""]:
            comments.append(f"# {part}".rstrip())
    text = cassandra.dump(model)
    return "\n".join(comments) + ("\n" if comments else "") + text


def write_fitted(model: Model, path, header_lines: Sequence[str] = ()) -> None:
    """Write ``model`` to ``path`` as a Cassandra ``.pomdp`` whose first lines are
    ``header_lines`` as ``# `` comments. The file appears whole or not at all."""
    model.validate()
    text = fitted_text(model, header_lines)
    write_atomically(path, lambda f: f.write(text.encode("utf-8")))


# --------------------------------------------------------------------------------------------
# Synthetic experience
# --------------------------------------------------------------------------------------------
PolicyFn = Callable[[np.random.Generator, int], int]


def uniform_policy(n_actions: int) -> PolicyFn:
    """An exploring policy: every action equally likely at every step."""
    if n_actions < 1:
        raise ValueError("a policy needs at least one action")
    return lambda rng, step: int(rng.integers(n_actions))


def sample_experience(model: Model, policy_fn: PolicyFn, episodes: int, steps: int,
                      seed: int = 0,
                      progress: Optional[Callable[[int], None]] = None) -> ExperienceCounts:
    """Counts of ``episodes`` x ``steps`` steps simulated in ``model``.

    Each episode starts from a state drawn from the initial belief; at each step
    ``policy_fn(rng, step)`` gives the action index, s' ~ T(.|s,a) and o ~ O(.|s',a) are drawn,
    and both the transition (s, a, s') and the observation (a, s', o) are counted.
    ``numpy.random.SeedSequence(seed)`` is split into one child per episode, so the result
    depends on ``seed`` alone (and each episode on its child). ``progress(episodes_done)`` is
    called after each episode.
    """
    if episodes < 0 or steps < 0:
        raise ValueError(f"episodes and steps must be >= 0 (got {episodes}, {steps})")
    model.validate()
    sampler = ModelSampler(model)
    counts = ExperienceCounts.for_model(model)
    A = model.n_actions
    trans, obs = counts.transitions, counts.observations
    for done, child in enumerate(np.random.SeedSequence(seed).spawn(episodes), 1):
        rng = np.random.default_rng(child)
        state = int(sampler.sample_initial(rng, 1)[0])
        for t in range(steps):
            action = policy_fn(rng, t)
            if isinstance(action, (bool, np.bool_)) or not isinstance(action, (int, np.integer)) \
                    or not 0 <= action < A:
                raise ModelError(f"the policy chose {action!r} at step {t}: "
                                 f"not an action index in 0..{A - 1}")
            action = int(action)
            u1, u2 = rng.random(2)
            nxt, o, _ = sampler.step1(state, action, float(u1), float(u2))
            trans[action, state, nxt] += 1
            obs[action, nxt, o] += 1
            state = nxt
        if progress is not None:
            progress(done)
    return counts
