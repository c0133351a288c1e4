"""The interface every online decision maker offers, and the planners that only read a policy.

A planner keeps a belief and is driven in lockstep::

    planner.reset()                  # or reset(belief)
    a = planner.act()                # choose from the current belief (stats in last_stats)
    planner.update(a, o)             # the world answered with observation o

What else the robot process asks of a planner is on :class:`Planner` too, each with a default
a planner overrides when it has the ability: ``reseed`` (a new episode's random stream),
``observe_time`` (the simulated time of the next observation, for ``reads_time`` planners),
``last_rule`` and ``mdp_state`` (why a rule-based robot chose), ``policy_text`` (its policy in
one line at start-up); and how it is made: ``from_settings`` (from the robot process's
settings), ``plans_on_model`` (whether it plans on the robot model: the one place that says
so), ``settings_used`` and ``options`` (what a library policy of it may set). The robot
process finds a planner by name (``planner:=``) in :mod:`ros_hrc.registry` (docs/extending.md).

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
from typing import Any, ClassVar, Dict, Mapping, Optional, Tuple, Type

import numpy as np

from ros_hrc import registry
from ros_hrc.errors import SolverError, ZeroProbabilityObservation
from ros_hrc.pomdp import belief as belief_mod
from ros_hrc.pomdp import mdp
from ros_hrc.pomdp.belief import Belief, make_belief
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.policy import Policy
from ros_hrc.pomdp.policy import load as load_policy

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
    """Chooses actions from a belief it keeps up to date.

    Every ability the robot process uses is declared here; the defaults are those of a
    planner without it (module docstring)."""

    model: Model
    last_stats: PlannerStats
    zero_probability_events: int = 0
    last_update_zero_probability: bool = False

    #: Whether it plans on the robot model: a library policy of it must name a model, the
    #: held-out rule of a fitted model applies to it (hrc_experiment), and the reports call
    #: the launch's one robot by its model's name. The one place that says so; a planner that
    #: decides without the model (a baseline) keeps its belief over the launch's model.
    plans_on_model: ClassVar[bool] = False
    #: Whether it reads each observation's simulated time (``observe_time``); the robot process
    #: says once when the observations carry none.
    reads_time: ClassVar[bool] = False
    #: Its own options and their defaults: keys a library policy of it may set besides the
    #: settings it reads (``settings_used``); given to ``from_settings`` with the settings.
    options: ClassVar[Mapping[str, Any]] = {}
    #: The rule behind the last ``act`` (a rule-based robot; None: it has no rules).
    last_rule: Optional[str] = None
    #: The state of its own MDP the last observation named (None: it has none).
    mdp_state: Optional[str] = None

    @classmethod
    def settings_used(cls, task: Any) -> Tuple[str, ...]:
        """The robot process's settings it reads on ``task`` (a ``ros_hrc.tasks`` Task), which
        a library policy of it may set as options (none by default)."""
        return ()

    @classmethod
    def from_settings(cls, model: Model, task: Any, values: Mapping[str, Any]) -> "Planner":
        """A planner on ``model`` from the robot process's settings ``values`` (setting name
        -> resolved value, ``seed`` among them) and its own ``options`` (their defaults where
        not given). By default ``cls(model, seed=..., **options)``. ValueError (one line)
        for values it cannot take."""
        own = {name: values.get(name, default) for name, default in cls.options.items()}
        return cls(model, seed=values.get("seed"), **own)

    @classmethod
    def checked_options(cls, given: Mapping[str, Any]) -> Dict[str, Any]:
        """``given`` (option name -> value: a library policy's keys, ``planner_options``)
        checked against its ``options``: each a name it declares, of its default's type (an
        integer for a float default is taken as the float). ValueError (one line naming the
        option) otherwise."""
        out: Dict[str, Any] = {}
        for name, value in given.items():
            if name not in cls.options:
                takes = ", ".join(cls.options) or "none"
                raise ValueError(f"unknown option {name!r} (its options: {takes})")
            default = cls.options[name]
            if isinstance(default, float) and isinstance(value, int) and \
                    not isinstance(value, bool):
                value = float(value)
            if not isinstance(value, type(default)) or (isinstance(value, bool)
                                                        and not isinstance(default, bool)):
                raise ValueError(f"option {name} must be a {type(default).__name__} like its "
                                 f"default {default!r}, got {value!r}")
            out[name] = value
        return out

    @classmethod
    def acts_by(cls, task: Any) -> Optional[str]:
        """What a report names as the robot model of a policy of this planner on ``task``
        (``/hrc/task_status.robot_model``) when that is not the model it keeps its belief
        over (a rule-based robot's own rules or MDP); None: that model."""
        return None

    def reseed(self, seed: int) -> None:
        """Draw from ``seed``'s stream from now on (each episode's reset). By default nothing:
        a planner that draws nothing at random."""

    def observe_time(self, elapsed: Optional[float]) -> None:
        """The simulated seconds since the episode's reset of the next observation (None:
        unknown). By default ignored (``reads_time`` False)."""

    def policy_text(self) -> Optional[str]:
        """Its policy in one line, printed at start-up after ``<process>: `` (None: nothing to
        print), e.g. ``the reactive MDP's policy (value iteration): ...``."""
        return None

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

    plans_on_model = True

    @classmethod
    def settings_used(cls, task: Any) -> Tuple[str, ...]:
        return ("policy_file",)

    @classmethod
    def from_settings(cls, model: Model, task: Any, values: Mapping[str, Any]
                      ) -> "PolicyPlanner":
        """The policy file ``policy_file`` read against ``model``, with the lookahead."""
        if not values.get("policy_file"):
            raise ValueError("--planner policy needs --policy FILE (hrc_pomdp solve -o FILE)")
        return cls(model, load_policy(values["policy_file"], model), seed=values.get("seed"),
                   lookahead=True)

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


def planner_class(name: str) -> Type[Planner]:
    """The planner ``name`` names (``planner:=``): a registered name or ``module:Class``
    (:mod:`ros_hrc.registry`). RegistryError (a ValueError, one line) otherwise."""
    return registry.load(registry.PLANNERS, name, Planner)
