"""A POMDP whose hidden state carries a type that never changes: (type, state).

Nikolaidis et al. (HRI 2015) put the human's type into the robot's model as a hidden variable
inferred online. Here each type has a POMDP of its own over the same states, actions and
observations (e.g. T and O fitted to the humans of that type); :func:`compose` makes one POMDP
whose states are every (type, state) pair, named ``<state>__<type>``, in type-major order:

* T((s', t) | (s, t), a) = T_t(s' | s, a), and no transition leaves a type;
* O(o | (s', t), a) = O_t(o | s', a);
* R((s, t), a, (s', t)) = R_t(s, a, s');
* the initial belief is prior(t) · b0_t(s).

A belief over the composed states is then a belief over the type (its marginal,
:meth:`TypeLayout.type_marginal`) and over the state (:meth:`TypeLayout.state_marginal`), and
a planner on the composed model plans with both, e.g. acting to find out the type when that
pays. With one type the composed model is that type's model with its states renamed.

The toolkit knows no task: the types and states are names given as data.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import ModelError
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.type_names import (TYPE_SEPARATOR, check_type_name, split_state,
                                      typed_state)


@dataclass(frozen=True)
class TypeLayout:
    """Where each (type, state) sits in a composed model: state ``s`` of type ``t`` is at
    ``t * len(states) + s``."""
    types: Tuple[str, ...]
    states: Tuple[str, ...]

    @classmethod
    def of(cls, model: Model) -> Optional["TypeLayout"]:
        """The layout of ``model``'s states, or None when they are not every (type, state)
        pair in type-major order (a model of no type)."""
        return cls.of_names(model.states)

    @classmethod
    def of_names(cls, names: Sequence[str]) -> Optional["TypeLayout"]:
        split = [split_state(n) for n in names]
        if not split or any(p is None for p in split):
            return None
        types = tuple(dict.fromkeys(t for _, t in split))   # type: ignore[misc]
        n = len(split) // len(types)
        states = tuple(s for s, _ in split[:n])             # type: ignore[misc]
        layout = cls(types, states)
        if len(split) != len(types) * n or list(names) != layout.names():
            return None
        return layout

    def names(self) -> list:
        return [typed_state(s, t) for t in self.types for s in self.states]

    def blocks(self, belief: np.ndarray) -> np.ndarray:
        """``belief`` as a (types, states) array."""
        b = np.asarray(belief, dtype=float)
        if b.shape != (len(self.types) * len(self.states),):
            raise ValueError(f"a belief of {b.size} entries for {len(self.types)} types x "
                             f"{len(self.states)} states")
        return b.reshape(len(self.types), len(self.states))

    def type_marginal(self, belief: np.ndarray) -> np.ndarray:
        """P(type) under ``belief``."""
        return self.blocks(belief).sum(axis=1)

    def state_marginal(self, belief: np.ndarray) -> np.ndarray:
        """P(state) under ``belief``, the type summed out."""
        return self.blocks(belief).sum(axis=0)

    def expected_reward(self, model: Model, state: str, action: int,
                        type_belief: Optional[Sequence[float]] = None) -> float:
        """R(state, action) of a task state when the type is known only by ``type_belief``
        (the model's initial type marginal when not given): Σ_t P(t) R((state, t), action).
        A step's reward is scored so, since the world tells the task state, never the type."""
        p = self.type_marginal(model.initial_belief) if type_belief is None or \
            len(type_belief) == 0 else np.asarray(type_belief, dtype=float)
        s = self.states.index(state)
        n = len(self.states)
        return float(sum(pt * model.R_sa[action, t * n + s] for t, pt in enumerate(p)))

    def with_type_prior(self, initial: np.ndarray, prior: Sequence[float]) -> np.ndarray:
        """The belief whose type marginal is ``prior`` and whose state belief given each type
        is ``initial``'s (a composed model's initial belief: each type's own start).
        ValueError when ``prior`` is no distribution over the types, or puts weight on a type
        ``initial`` gives none (its start is then unknown)."""
        p = np.asarray(prior, dtype=float)
        if p.shape != (len(self.types),) or not np.all(np.isfinite(p)) or p.min() < 0 \
                or not np.isclose(p.sum(), 1.0, atol=1e-6):
            raise ValueError(f"a prior over the {len(self.types)} types must be "
                             f"{len(self.types)} probabilities summing to 1")
        blocks = self.blocks(initial)
        mass = blocks.sum(axis=1)
        if np.any((p > 0) & (mass <= 0)):
            missing = [t for t, pt, m in zip(self.types, p, mass) if pt > 0 and m <= 0]
            raise ValueError(f"type {missing[0]} has no start in the initial belief")
        given = np.divide(blocks, mass[:, None], out=np.zeros_like(blocks),
                          where=mass[:, None] > 0)
        return (given * p[:, None]).ravel()


def compose(models: Mapping[str, Model], prior: Optional[Sequence[float]] = None,
            name: str = "") -> Model:
    """One POMDP of every (type, state) from one model per type (``models``: type name ->
    model; see the module docstring). ``prior``: P(type), uniform when not given. The models
    must share states, actions, observations, discount and the kind of values; ModelError
    names the first that does not."""
    if not models:
        raise ModelError("no types to compose")
    types = list(models)
    for t in types:
        check_type_name(t)
    first = models[types[0]]
    for t in types:
        m = models[t]
        m.validate()
        for label in ("states", "actions", "observations"):
            if list(getattr(m, label)) != list(getattr(first, label)):
                raise ModelError(f"type {t}: its {label} are not type {types[0]}'s")
        if m.discount != first.discount or m.minimise != first.minimise:
            raise ModelError(f"type {t}: its discount or values are not type {types[0]}'s")
        if any(TYPE_SEPARATOR in s for s in m.states):
            raise ModelError(f"type {t}: state names already carry a type")
    p = np.full(len(types), 1.0 / len(types)) if prior is None else np.asarray(prior, float)
    layout = TypeLayout(tuple(types), tuple(first.states))
    initial = np.concatenate([np.asarray(models[t].initial_belief, float) for t in types])
    initial = layout.with_type_prior(initial, p)

    def diagonal(table: str, a: int) -> sp.csr_matrix:
        return sp.block_diag([getattr(models[t], table)[a] for t in types], format="csr")

    def stacked(a: int) -> sp.csr_matrix:
        return sp.vstack([models[t].O[a] for t in types], format="csr")

    A = first.n_actions
    composed = Model(states=layout.names(), actions=list(first.actions),
                     observations=list(first.observations), discount=first.discount,
                     initial_belief=initial,
                     T=[diagonal("T", a) for a in range(A)], O=[stacked(a) for a in range(A)],
                     R=[diagonal("R", a) for a in range(A)], minimise=first.minimise,
                     name=name or "+".join(types),
                     meta={"types": list(types), "type_prior": p.tolist()})
    composed.validate()
    return composed
