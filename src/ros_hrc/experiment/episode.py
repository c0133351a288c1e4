"""Scoring one episode from its steps: when it ends, who succeeded, what the robot did.

A step is anything with the fields of ``ros_hrc/Status`` (the message itself, or a plain
object in tests): ``step, human_action, human_state, observation_bits, robot_observation,
robot_state, robot_action, belief_states, belief, decision_ms, sim_time, object_holder,
object_left_belt``. No ROS here: the experiment's ROS side hands these over.
"""
from __future__ import annotations

from typing import Dict, Sequence

import numpy as np

from ros_hrc.loop import task
from ros_hrc.experiment.store import EpisodeKey, EpisodeRow, StepRow
from ros_hrc.pomdp.model import Model

#: Robot policies of a grid -> the robot process's ``--planner``.
ROBOT_POLICIES: Dict[str, str] = {
    "pomdp": "despot",       # anticipates the human's state of mind (the POMDP, online DESPOT)
    "reactive": "reactive",  # treats the need for help as observable (robot_policies.py)
    "no_robot": "none",      # never acts
}

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
    decisions = [s.decision_ms for s in steps]
    return EpisodeRow(
        human_model=human_model, robot_policy=robot_policy, seed=seed, episode=episode,
        success=int(success),
        succeeded_by=holder if success else "none", end_reason=reason, steps=len(steps),
        sim_seconds=(steps[-1].sim_time - start_sim_time) if steps else 0.0,
        robot_discounted_reward=discounted_robot_reward(steps, model),
        intrusive_actions=intrusive, warnings=warnings,
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
                    needs_help=int(s.robot_state in task.NEEDS_HELP_STATES))
            for s in steps]
