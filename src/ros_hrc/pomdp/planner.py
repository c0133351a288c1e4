"""The interface every online decision maker offers, and the planners that only read a policy.

A planner keeps a belief and is driven in lockstep::

    planner.reset()                  # or reset(belief)
    a = planner.act()                # choose from the current belief (stats in last_stats)
    planner.update(a, o)             # the world answered with observation o

A run starts from ``reset(model.start_belief(state))`` (``simulate`` does so): with fully
observable state variables (mixed observability) the planner knows their values from the first
step, so it starts from the initial belief conditioned on them (an MDP: a point mass on the start
state). Every planner here then works from that belief as from any other.

``update`` never raises on an observation the belief gives probability zero: the belief falls
back to the prediction through T alone (``Belief.predict``), ``last_update_zero_probability``
is set, ``zero_probability_events`` counts it and a warning is logged. Planners:

    PolicyPlanner   reads a saved offline Policy (alpha vectors), optional one-step lookahead
    MdpPlanner      a fully observable model: the greedy action of the MDP's Q values
    DespotPlanner   online search (despot.py)
"""
from __future__ import annotations

import logging
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Dict, Optional

import numpy as np

from ros_hrc.errors import SolverError, ZeroProbabilityObservation
from ros_hrc.pomdp import belief as belief_mod
from ros_hrc.pomdp import mdp
from ros_hrc.pomdp.belief import Belief, make_belief
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.policy import Policy

log = logging.getLogger("ros_hrc.pomdp")


@dataclass
class PlannerStats:
    """What the last ``act`` did: search trials, time, bounds at the root, tree size, and
    ``action_values``: action index -> the value the planner compared that action by (its
    choice has the best one, ties aside); only the actions it valued, empty for a planner that
    decides without values (a baseline robot). Reported, never used to decide."""

    trials: int = 0
    seconds: float = 0.0
    lower: float = math.nan
    upper: float = math.nan
    nodes: int = 0
    depth: int = 0
    action_values: Dict[int, float] = field(default_factory=dict)


class Planner(ABC):
    """Chooses actions from a belief it keeps up to date."""

    model: Model
    last_stats: PlannerStats
    zero_probability_events: int = 0
    last_update_zero_probability: bool = False

    @abstractmethod
    def reset(self, belief: Optional[np.ndarray] = None) -> None:
        """Start again from ``belief`` (a distribution over states) or the initial belief."""

    @abstractmethod
    def act(self) -> int:
        """The action to take at the current belief."""

    @abstractmethod
    def update(self, action: int, observation: int) -> None:
        """Condition the belief on the action taken and the observation received."""

    @property
    @abstractmethod
    def belief(self) -> np.ndarray:
        """The current belief as a distribution over states (a histogram for particles)."""


class BeliefPlanner(Planner):
    """A planner over a ``Belief`` object, with the zero-probability fallback in one place."""

    def __init__(self, model: Model, seed: Optional[int] = None,
                 particles: Optional[int] = None, sampler=None) -> None:
        self.model = model
        self.rng = np.random.default_rng(seed)
        self.particles = particles
        # A particle belief steps its particles with ``sampler`` (a ModelSampler of the model,
        # e.g. DESPOT's, shared), or builds its own.
        self._belief: Belief = make_belief(model, self.rng, particles, sampler=sampler)
        self.last_stats = PlannerStats()
        self.zero_probability_events = 0
        self.last_update_zero_probability = False

    def reset(self, belief: Optional[np.ndarray] = None) -> None:
        self._belief.reset(belief)
        self.last_update_zero_probability = False

    def reseed(self, seed: int) -> None:
        """Draw from ``seed``'s stream from now on, from its start (the robot process reseeds
        its planner at each episode's reset). In place: the belief holds the same generator."""
        self.rng.bit_generator.state = np.random.default_rng(seed).bit_generator.state

    def update(self, action: int, observation: int) -> None:
        try:
            self._belief.update(action, observation)
            self.last_update_zero_probability = False
        except ZeroProbabilityObservation as exc:
            # Documented fallback: keep the prediction through T and carry on.
            self._belief.predict(action)
            self.zero_probability_events += 1
            self.last_update_zero_probability = True
            log.warning("%s; belief falls back to the prediction without the observation", exc)

    @property
    def belief(self) -> np.ndarray:
        return self._belief.probabilities()


class PolicyPlanner(BeliefPlanner):
    """Follows a saved offline policy.

    With ``lookahead`` the action is chosen like SARSOP's pomdpsim by default: one step of
    lookahead, R(b,a) + γ Σ_o P(o|b,a) V(b_ao), over the policy's value function V.
    """

    def __init__(self, model: Model, policy: Policy, seed: Optional[int] = None,
                 lookahead: bool = False) -> None:
        policy.check(model)
        super().__init__(model, seed)
        self.policy = policy
        self.lookahead = lookahead
        if lookahead:
            if not model.dense_tables_fit:
                raise SolverError("one-step lookahead is only for small models (at most "
                                  f"{belief_mod.DENSE_STATE_LIMIT} states and dense T and O "
                                  "of a few million numbers)")
            self._T = model.dense_T                                   # (A, S, S')
            self._OT = np.transpose(model.dense_O, (0, 2, 1))         # (A, Z, S')

    def act(self) -> int:
        b = self.belief
        if not self.lookahead:
            a = self.policy.action(b)
            self.last_stats = PlannerStats(lower=self.policy.value(b),
                                           action_values=self.policy.action_values(b))
            return a
        joint = (b @ self._T)[:, None, :] * self._OT                  # (A, Z, S')
        # Σ_o P(o) max_i α_i·b_ao = Σ_o max_i α_i·joint_o (the normaliser cancels).
        future = (joint @ self.policy.alphas.T).max(axis=2).sum(axis=1)
        q = self.model.R_sa @ b + self.model.discount * future
        a = int(np.argmax(q))
        self.last_stats = PlannerStats(lower=float(q[a]),
                                       action_values=dict(enumerate(q.tolist())))
        return a


class MdpPlanner(BeliefPlanner):
    """A fully observable model: the action maximising b·Q[a] (the MDP's greedy action when the
    belief is a point mass, QMDP otherwise, e.g. after a noisy manual state entry)."""

    def __init__(self, model: Model, solution: Optional[mdp.MdpSolution] = None,
                 seed: Optional[int] = None, epsilon: float = 1e-6) -> None:
        super().__init__(model, seed)
        self.solution = solution if solution is not None else mdp.value_iteration(model, epsilon)
        self.Q = self.solution.Q

    @classmethod
    def from_policy(cls, model: Model, policy: Policy, seed: Optional[int] = None) -> "MdpPlanner":
        """An MDP planner from a saved "mdp" policy (its vectors are the Q rows)."""
        policy.check(model)
        q = np.full((model.n_actions, model.n_states), -np.inf)
        for alpha, a in zip(policy.alphas, policy.actions):
            q[a] = np.maximum(q[a], alpha)
        sol = mdp.MdpSolution(V=q.max(axis=0), Q=q, policy=q.argmax(axis=0), iterations=0,
                              residual=0.0, discount=model.discount)
        return cls(model, sol, seed)

    def act(self) -> int:
        q = self.Q @ self.belief
        a = int(np.argmax(q))
        self.last_stats = PlannerStats(lower=float(q[a]), upper=float(q[a]),
                                       action_values=dict(enumerate(q.tolist())))
        return a
