"""Scoring one episode from its steps: when it ends, who succeeded, what the robot did.

A step is anything with the fields of ``ros_hrc/Status`` (the message itself, or a plain
object in tests): ``step, human_action, human_state, observation_bits, robot_observation,
robot_state, robot_action, belief_states, belief, decision_ms, sim_time, object_holder,
object_left_belt, surprise``. No ROS here: the experiment's ROS side hands these over.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Optional, Sequence

import numpy as np

from ros_hrc.loop import task
from ros_hrc.experiment.store import EpisodeKey, EpisodeRow, StepRow
from ros_hrc.pomdp.model import Model

@dataclass(frozen=True)
class RobotPolicy:
    """A robot policy of a grid: the robot process's ``--planner`` and the robot model it
    runs with (None: the grid's ``--robot-model``)."""
    planner: str
    robot_model: Optional[str] = None
    doc: str = ""


#: Robot policies of a grid, by name.
ROBOT_POLICIES: Dict[str, RobotPolicy] = {
    "pomdp": RobotPolicy("despot", None, "anticipates the human's state of mind: the robot POMDP "
                                         "(the authors' model by default), planned online with "
                                         "DESPOT"),
    "pomdp_fitted": RobotPolicy("despot", "robot_fitted", "the same planner on the robot model "
                                                          "fitted to the world (hrc_fit)"),
    "reactive": RobotPolicy("reactive", None, "treats the need for help as observable "
                                              "(robot_policies.py)"),
    "no_robot": RobotPolicy("none", None, "never acts"),
    "explore": RobotPolicy("explore", None, "a uniformly random action each step: hrc_fit's "
                                            "exploring robot"),
}
#: The policies of ``make experiment``'s default grid.
DEFAULT_POLICIES = ("pomdp", "pomdp_fitted", "reactive", "no_robot")

#: Robot actions that intrude when the human does not need help.
HELPING_ACTIONS = frozenset({"rGrasp_obj", "rPoint_obj"})


def needs_help_mass(step) -> float:
    """The robot's belief in "the human needs help" (S2..S5) at this step."""
    return float(sum(p for name, p in zip(step.belief_states, step.belief)
                     if name in task.NEEDS_HELP_STATES))


def discounted_robot_reward(steps: Sequence, model: Model) -> float:
    """sum_t gamma^t R(s_t, a_t) of the robot model, with the true robot state s_t the
    observer reported and the action a_t the robot took."""
    total, weight = 0.0, 1.0
    for step in steps:
        s = model.index("state", step.robot_state)
        a = model.index("action", step.robot_action)
        total += weight * float(model.R_sa[a, s])
        weight *= model.discount
    return total


def score_episode(key: EpisodeKey, steps: Sequence, reason: str, start_sim_time: float,
                  model: Model, wall_seconds: float) -> EpisodeRow:
    """One results row for a finished episode."""
    human_model, robot_policy, seed, episode = key
    holder = steps[-1].object_holder if steps else "none"
    success = reason == "success"
    intrusive = sum(1 for s in steps if s.robot_action in HELPING_ACTIONS
                    and s.robot_state not in task.NEEDS_HELP_STATES)
    warnings = sum(1 for s in steps if s.observation_bits & task.WARNING)
    # Observations the robot's model gave probability 0: where the model and the world disagree.
    zero_probability = sum(1 for s in steps if getattr(s, "surprise", False))
    decisions = [s.decision_ms for s in steps]
    return EpisodeRow(
        human_model=human_model, robot_policy=robot_policy, seed=seed, episode=episode,
        success=int(success),
        succeeded_by=holder if success else "none", end_reason=reason, steps=len(steps),
        sim_seconds=(steps[-1].sim_time - start_sim_time) if steps else 0.0,
        robot_discounted_reward=discounted_robot_reward(steps, model),
        intrusive_actions=intrusive, warnings=warnings,
        zero_probability_observations=zero_probability,
        mean_decision_ms=float(np.mean(decisions)) if decisions else 0.0,
        wall_seconds=wall_seconds)


def step_rows(key: EpisodeKey, steps: Sequence) -> list:
    """The episode's per-step trace (for the belief plot)."""
    human_model, robot_policy, seed, episode = key
    return [StepRow(human_model=human_model, robot_policy=robot_policy, seed=seed,
                    episode=episode, step=int(s.step), human_action=s.human_action,
                    human_state=s.human_state, robot_state=s.robot_state,
                    robot_action=s.robot_action, observation=s.robot_observation,
                    belief_needs_help=needs_help_mass(s),
                    needs_help=int(s.robot_state in task.NEEDS_HELP_STATES),
                    zero_probability=int(bool(getattr(s, "surprise", False))))
            for s in steps]
