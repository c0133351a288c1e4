"""The robot that learns the human it works with, across a sequence (issue #40).

Its model of the human is a Dirichlet posterior over the robot model's transition rows
(:class:`ros_hrc.pomdp.bayes_adaptive.DirichletPosterior`): the prior is a pooled robot model
(e.g. ``robot_utility_fitted``: fitted on the zoo's fit set, priced by the task's utility), of
``strength`` pseudo-counts per row. After each task the posterior takes the task's expected
transitions (forward-backward over the robot's own actions and observations; the true state
is never read) and its ending (a success: the robot's last action led into the success
state), after the counts so far were moved towards the prior by ``forgetting``. Before
each task the robot plans on the posterior: its mean (``planning="mean"``,
``pomdp_learning_mean``) or root sampling over ``draws`` posterior draws (``"sampled"``,
``pomdp_learning``), which plans for what an action reveals of this human.

What it believes of the human, in one figure (:meth:`LearntHuman.figure`): the probability
that a human who has just failed once recovers alone within the task's ``recovery_steps``
steps while the robot idles (the seed's S2 to S1 under rIdle), under the posterior, with its
spread over posterior draws. docs/learning.md says why this figure.

No ROS; a task's names come from its :class:`~ros_hrc.tasks.definition.Task`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np

from ros_hrc import settings
from ros_hrc.pomdp.bayes_adaptive import (DirichletPosterior, End, LookBonus, check_bonus,
                                          check_draws, check_forgetting, check_strength,
                                          planning_model, reach_probability)
from ros_hrc.pomdp.model import Model
from ros_hrc.tasks.definition import Task

__all__ = ["LEARNING_SELECTORS", "planning_of", "LearntFigure", "LearntHuman",
           "FIGURE_DRAWS"]

#: ``selector:=`` values of the learning robot (``settings.LEARNING_SELECTORS``), and how
#: each plans on its posterior.
LEARNING_SELECTORS = dict(zip(settings.LEARNING_SELECTORS, ("sampled", "mean")))
#: Posterior draws the figure's spread is computed from.
FIGURE_DRAWS = 200


def selector_of(planning: str) -> str:
    """The ``selector:=`` value of a learning robot that plans so."""
    return next(name for name, how in LEARNING_SELECTORS.items() if how == planning)


def planning_of(selector: str) -> Optional[str]:
    """How the ``selector:=`` value plans on a posterior (None: not a learning robot)."""
    return LEARNING_SELECTORS.get(selector)


@dataclass(frozen=True)
class LearntFigure:
    """The learnt model's key figure: its ``name`` (one line), its value under the posterior
    mean and its spread (the standard deviation over posterior draws)."""
    name: str
    value: float
    spread: float


class LearntHuman:
    """A learning robot's model of its human, carried from task to task of one sequence.

    ``prior``: the pooled robot model (checked against ``task`` by whoever loaded it);
    ``strength``, ``forgetting``, ``draws`` as the module docstring says; ``bonus``: the
    scale of the exploration bonus on the task's idle action
    (:class:`ros_hrc.pomdp.bayes_adaptive.LookBonus`, :meth:`look_bonus`; 0: none);
    ``seed``: the stream the draws come from (a new sequence starts it again:
    :meth:`restart`)."""

    def __init__(self, prior: Model, task: Task, strength: float, forgetting: float,
                 planning: str, draws: int, seed: int = 0, bonus: float = 0.0) -> None:
        self.prior = prior
        self.task = task
        self.strength = check_strength(strength)
        self.forgetting = check_forgetting(forgetting)
        self.bonus = check_bonus(bonus)
        self.planning = planning
        self.draws = check_draws(draws)
        self.tasks_learnt = 0
        self._recovery = self._figure_indices(prior, task)
        self.restart(seed)

    @staticmethod
    def _figure_indices(model: Model, task: Task) -> Optional[Tuple[int, int, int, int]]:
        if not (task.recovery_state and task.robot_success_state):
            return None
        return (model.index("state", task.recovery_state),
                model.index("action", task.robot_idle_action),
                model.index("state", task.robot_success_state), task.recovery_steps)

    def restart(self, seed: int) -> None:
        """Back to the prior (a new sequence: a new human), drawing from ``seed``'s stream."""
        self.posterior = DirichletPosterior(self.prior, self.strength)
        self.rng = np.random.default_rng(seed)
        self.tasks_learnt = 0

    def model_for_task(self) -> Model:
        """The model the next task is planned on (a new draw for root sampling each task)."""
        return planning_model(self.posterior, self.planning, self.draws, self.rng)

    def look_bonus(self) -> Optional[LookBonus]:
        """The next task's exploration bonus on the idle action, from what the posterior has
        seen of it (None: no bonus). A task's decisions take it on their first step."""
        if not self.bonus:
            return None
        idle = self.prior.index("action", self.task.robot_idle_action)
        return LookBonus(self.bonus, idle, self.posterior.times_seen(idle))

    def learn(self, steps: Sequence[Tuple[int, int]], last_action: Optional[int] = None,
              succeeded: Optional[bool] = None) -> None:
        """The task that ended: its ``(action, observation)`` steps, as the robot's belief
        update took them, and how it ended: the robot's ``last_action`` (chosen after the last
        observation) led into the success state if it ``succeeded``, into any other state if
        not (None: the end is not counted). Its expected counts come from the posterior the
        task was planned on; the counts so far are then moved towards the prior, and the
        task's added whole: ``n <- (1 - forgetting) n + the task's``."""
        self.posterior.learn(steps, forget_first=self.forgetting,
                             end=self._end(last_action, succeeded))
        self.tasks_learnt += 1

    def _end(self, last_action: Optional[int], succeeded: Optional[bool]) -> Optional[End]:
        """A task's ending as evidence (:data:`ros_hrc.pomdp.bayes_adaptive.End`): a success is
        the task's success state (whoever brought it about, as ``hrc_fit`` counts it), any
        other ending every state but it."""
        if last_action is None or succeeded is None or not self.task.robot_success_state:
            return None
        success = np.zeros(self.prior.n_states)
        success[self.prior.index("state", self.task.robot_success_state)] = 1.0
        return last_action, (success if succeeded else 1.0 - success)

    @classmethod
    def figure_of(cls, model: Model, task: Task) -> Optional[float]:
        """The key figure of a fixed ``model`` (a ceiling's fit of one human: what the learnt
        figure is measured against); None when the task names no recovery."""
        indices = cls._figure_indices(model, task)
        if indices is None:
            return None
        start, idle, success, k = indices
        return reach_probability(model.dense_T[idle], start, success, k)

    def figure(self) -> Optional[LearntFigure]:
        """The key figure under the posterior now (None: the task names no recovery)."""
        if self._recovery is None:
            return None
        start, idle, success, k = self._recovery
        posterior = self.posterior
        value = reach_probability(posterior.mean_transitions(idle), start, success, k)
        # Its spread: draws from their own stream, so showing the figure changes no plan.
        rng = np.random.default_rng(self.tasks_learnt)
        draws = [reach_probability(posterior.sample_transitions(idle, rng), start, success, k)
                 for _ in range(FIGURE_DRAWS)]
        name = (f"P(recovers alone from {self.task.recovery_state} within {k} steps of "
                f"{self.task.robot_idle_action})")
        return LearntFigure(name, value, float(np.std(draws, ddof=1)))
