"""The simulated human: an MDP agent that picks actions and moves between states of mind.

One step: the agent picks an action from its belief over states (QMDP over the exact MDP
values, or a softer choice), then the next state is either sampled from T(s'|s,a) (auto) or
given by the user (manual). A manually given state gets ``manual_share`` of the belief
(80 % by default, as in the seed's modified DESPOT) and the rest is spread over the other
states in proportion to what the model predicted, uniformly when it predicted none of them;
so a typed state is followed, yet the agent's next choice stays a little sceptical.

**A human who hears the robot** (a task with reaction rules, :mod:`ros_hrc.tasks`): one
step is two calls. :meth:`HumanAgent.act` takes the action in the current state and returns
the state the step shows (a grasp's outcome is drawn then, before the robot acts);
:meth:`HumanAgent.react`, once the robot's action is known, moves to the next state by the
task's rules, or to a typed state. Every draw is from the model's row as the task's rules
shape it (:meth:`~ros_hrc.tasks.definition.ReactionRules.row`), renormalised over the states
they allow (a rejected draw drawn again), from the agent's own random stream.

**The human of a sequence's task** (:meth:`HumanAgent.play`): a sequence's schedule may give
each task another human model, or one drifting to a second: the agent then plays the task
with T, R and the action values mixed row by row, ``(1 - w)`` of the first model's and ``w``
of the second's (both models of one task, so their states and actions are the same). Each
model's values are computed once.

No ROS and no websocket here: the process in :mod:`ros_hrc.processes.despot_mdp` drives it.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from ros_hrc import settings
from ros_hrc.pomdp.mdp import value_iteration
from ros_hrc.pomdp.model import Model
from ros_hrc.tasks.definition import ReactionRules

ACTION_CHOICES = settings.SETTINGS["human_choice"].choices


@dataclass
class HumanAgentConfig:
    """How the human chooses: ``optimal`` (argmax of expected Q), ``softmax`` with a
    temperature, or ``random``; the belief share of a manually given state; the seed."""

    choice: str = settings.default("human_choice")
    temperature: float = settings.default("temperature")
    manual_share: float = settings.default("manual_share")
    seed: int = settings.default("seed")

    def __post_init__(self) -> None:
        if self.choice not in ACTION_CHOICES:
            raise ValueError(f"choice must be one of {ACTION_CHOICES}, not {self.choice!r}")
        if not 0.0 < self.manual_share <= 1.0:
            raise ValueError(f"manual_share must be in (0, 1], not {self.manual_share}")
        if self.temperature <= 0.0:
            raise ValueError(f"temperature must be positive, not {self.temperature}")


@dataclass
class HumanStep:
    """What one step did, in the terms the seed's MDP terminal prints."""

    step: int
    action: str
    previous_state: str
    state: str
    state_index: int
    manual: bool
    reward: float
    discounted: float
    undiscounted: float
    belief: Dict[str, float] = field(default_factory=dict)
    #: A reacting human: the robot's action he heard, the rule that chose his next state
    #: (``manual`` for a typed one) and what it says.
    robot_action: str = ""
    rule: str = ""
    reaction: str = ""


class HumanAgent:
    """An MDP human with a belief over its own state (one-hot unless a state was typed)."""

    def __init__(self, model: Model, config: Optional[HumanAgentConfig] = None,
                 reaction: Optional[ReactionRules] = None) -> None:
        self.config = config or HumanAgentConfig()
        #: The task's reaction rules (None: he does not hear the robot, as the seed's human).
        self.reaction = reaction
        self._tables: Dict[int, Tuple[Model, np.ndarray, np.ndarray, np.ndarray]] = {}
        self.play(model)
        self.reset()

    def _tables_of(self, model: Model) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Q, T, R) of ``model`` as dense arrays (A x S, A x S x S, A x S x S), computed once."""
        cached = self._tables.get(id(model))
        if cached is None or cached[0] is not model:
            cached = (model, value_iteration(model).Q, model.dense_T,
                      np.stack([r.toarray() for r in model.R]))
            self._tables[id(model)] = cached
        return cached[1:]

    def play(self, model: Model, drift_to: Optional[Model] = None, drift: float = 0.0) -> None:
        """From the next :meth:`reset` on, be the human of ``model``; with ``drift_to``, a human
        between the two: every row of T and R, and the action values, ``(1 - drift)`` of
        ``model``'s and ``drift`` of ``drift_to``'s (the two must have the same states and
        actions)."""
        if not model.fully_observable:
            raise ValueError(f"{model.source or model.name}: the human model must be an MDP "
                             "(all state variables fullyObs=\"true\")")
        if not 0.0 <= drift <= 1.0:
            raise ValueError(f"drift must be from 0 to 1, not {drift}")
        q, t, r = self._tables_of(model)
        if drift_to is not None and drift > 0.0:
            if drift_to.states != model.states or drift_to.actions != model.actions:
                raise ValueError(f"{drift_to.source or drift_to.name}: cannot drift to it from "
                                 f"{model.source or model.name}: their states or actions differ")
            q2, t2, r2 = self._tables_of(drift_to)
            q, t, r = ((1.0 - drift) * q + drift * q2, (1.0 - drift) * t + drift * t2,
                       (1.0 - drift) * r + drift * r2)
        self.model = model
        self._q, self._dense_T, self._rewards = q, t, r

    # -- episode -------------------------------------------------------------------
    def reset(self, seed: Optional[int] = None) -> None:
        """Back to a state drawn from the initial belief, step 0, no reward."""
        self.rng = np.random.default_rng(self.config.seed if seed is None else seed)
        self.state = int(self.rng.choice(self.model.n_states, p=self.model.initial_belief))
        self.belief = np.zeros(self.model.n_states)
        self.belief[self.state] = 1.0
        self.step = 0
        self.discounted = 0.0
        self.undiscounted = 0.0
        self._acting: Optional[Tuple[int, int, str]] = None   # (state, action, shown state)

    @property
    def state_name(self) -> str:
        return self.model.states[self.state]

    @property
    def reacts(self) -> bool:
        """Whether he chooses his next state after the robot acted (:meth:`act`, then
        :meth:`react`) rather than with his action (:meth:`advance`)."""
        return self.reaction is not None

    # -- acting ----------------------------------------------------------------------
    def choose_action(self) -> int:
        """The action for the current belief (expected Q over the belief)."""
        q = self._q @ self.belief   # Q is (A, S)
        if self.config.choice == "optimal":
            return int(np.argmax(q))
        if self.config.choice == "random":
            return int(self.rng.integers(self.model.n_actions))
        z = (q - q.max()) / self.config.temperature
        p = np.exp(z) / np.exp(z).sum()
        return int(self.rng.choice(self.model.n_actions, p=p))

    def advance(self, action: int, manual_state: Optional[int] = None) -> HumanStep:
        """Take ``action``; move to ``manual_state`` if given, else sample the next state."""
        n = self.model.n_states
        predicted = self._dense_T[action, self.state]
        if manual_state is not None:
            if not 0 <= manual_state < n:
                raise ValueError(f"state must be an integer from 0 to {n - 1}, not {manual_state}")
            next_state = int(manual_state)
            self.belief = self._manual_belief(next_state, predicted)
        else:
            next_state = int(self.rng.choice(n, p=predicted / predicted.sum()))
            self.belief = np.zeros(n)
            self.belief[next_state] = 1.0
        reward = float(self._rewards[action][self.state, next_state])
        self.discounted += self.model.discount ** self.step * reward
        self.undiscounted += reward
        previous = self.state_name
        self.state = next_state
        result = HumanStep(step=self.step, action=self.model.actions[action],
                           previous_state=previous, state=self.state_name,
                           state_index=next_state, manual=manual_state is not None,
                           reward=reward, discounted=self.discounted,
                           undiscounted=self.undiscounted, belief=self.belief_dict())
        self.step += 1
        return result

    # -- a human who hears the robot --------------------------------------------------------
    def draw(self, state: str, action: str) -> str:
        """A next state from the model's row T(. | state, action), shaped by the task's rules
        and restricted to the states they allow; the state itself when they allow none."""
        names = self.model.states
        s, a = names.index(state), self.model.actions.index(action)
        row = np.asarray(self.reaction.row(self._dense_T[a, s], names), dtype=float)
        allowed = np.array([self.reaction.allowed(state, action, n) for n in names])
        weights = np.where(allowed, np.clip(row, 0.0, None), 0.0)
        if weights.sum() <= 0.0:
            return state
        return names[int(self.rng.choice(len(names), p=weights / weights.sum()))]

    def act(self, action: int) -> str:
        """A reacting human takes ``action`` in his state: the state the step shows (for a
        grasp its outcome, drawn now, before the robot acts)."""
        if self.reaction is None:
            raise ValueError("act/react are for a human who reacts to the robot; this one "
                             "steps with advance()")
        name = self.model.actions[action]
        shown = self.reaction.acting_state(self.state_name, name, self.draw)
        self._acting = (self.state, action, shown)
        return shown

    def react(self, robot_action: str, end_reason: str = "",
              manual_state: Optional[int] = None) -> HumanStep:
        """After the robot did ``robot_action`` (``end_reason``: the loop's, when the step
        ended the episode), move to the next state by the task's reaction rules, or to
        ``manual_state`` when one was typed."""
        if self._acting is None:
            raise ValueError("react() comes after act()")
        before, action, shown = self._acting
        self._acting = None
        names = self.model.states
        n = self.model.n_states
        if manual_state is not None:
            if not 0 <= manual_state < n:
                raise ValueError(f"state must be an integer from 0 to {n - 1}, not {manual_state}")
            next_state, rule, text = int(manual_state), "manual", "typed"
            predicted = self._dense_T[action, names.index(shown)]
            self.belief = self._manual_belief(next_state, predicted)
        else:
            reaction = self.reaction.next_state(shown, self.model.actions[action], robot_action,
                                                end_reason or "", self.draw)
            next_state, rule, text = names.index(reaction.state), reaction.rule, reaction.text
            self.belief = np.zeros(n)
            self.belief[next_state] = 1.0
        reward = float(self._rewards[action][before, next_state])
        self.discounted += self.model.discount ** self.step * reward
        self.undiscounted += reward
        self.state = next_state
        result = HumanStep(step=self.step, action=self.model.actions[action],
                           previous_state=names[before], state=self.state_name,
                           state_index=next_state, manual=manual_state is not None,
                           reward=reward, discounted=self.discounted,
                           undiscounted=self.undiscounted, belief=self.belief_dict(),
                           robot_action=robot_action, rule=rule, reaction=text)
        self.step += 1
        return result

    def _manual_belief(self, chosen: int, predicted: np.ndarray) -> np.ndarray:
        share = self.config.manual_share
        others = predicted.copy()
        others[chosen] = 0.0
        if others.sum() <= 0.0:
            others = np.ones_like(predicted)
            others[chosen] = 0.0
        belief = (1.0 - share) * others / others.sum() if others.sum() > 0 else np.zeros_like(others)
        belief[chosen] = share if others.sum() > 0 else 1.0
        return belief

    def belief_dict(self) -> Dict[str, float]:
        """Non-zero belief entries, largest first."""
        order: List[int] = list(np.argsort(-self.belief, kind="stable"))
        return {self.model.states[i]: float(self.belief[i]) for i in order if self.belief[i] > 0}
