"""Scoring one episode from its steps: when it ends, who succeeded, what the robot did.

A step is anything with the fields of ``ros_hrc/Status`` (the message itself, or a plain
object in tests): ``step, human_action, human_state, observation_bits, robot_observation,
robot_state, robot_action, belief_states, belief, decision_ms, sim_time, object_holder,
object_left_belt, surprise``. No ROS here: the experiment's ROS side hands these over.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from typing import Any, Mapping, Optional, Sequence, Tuple

import numpy as np

from ros_hrc import registry, tasks
from ros_hrc.tasks.definition import Task
from ros_hrc.tasks.utility import sim_span
from ros_hrc.experiment.paired import counterfactual_outcome
from ros_hrc.experiment.rows import UNPAIRED, EpisodeKey, EpisodeRow, StepRow
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.typed import TypeLayout


@dataclass(frozen=True)
class RobotPolicy:
    """A robot policy of a grid (``hrc_experiment --policies``): the robot process's
    ``--planner`` (a name the ``planner`` setting takes), the robot model it runs with (None:
    the grid's ``--robot-model``; a name of the task's robot models or a file) and, for
    ``reactive@N``, its budget (None: the grid's ``--reactive-budget``), and its planner's own
    options (``planner_options:=``; the planner's defaults where not given). Found by name in
    :mod:`ros_hrc.registry` (``ros_hrc.policies``): ours below, an installed package's, or
    ``module:NAME`` (docs/extending.md)."""
    planner: str
    robot_model: Optional[str] = None
    doc: str = ""
    reactive_budget: Optional[int] = None
    options: Mapping[str, Any] = field(default_factory=dict)


# Ours, registered in ros_hrc.registry.BUILT_IN under their names.
POMDP = RobotPolicy("despot", None, "anticipates the human's state of mind: the robot POMDP (the "
                                    "authors' model by default), planned online with DESPOT")
POMDP_FITTED = RobotPolicy("despot", "robot_fitted", "the same planner on the robot model "
                                                     "fitted to the world (hrc_fit)")
POMDP_CONSIDERATE = RobotPolicy("despot", "robot_considerate_fitted",
                                "the same planner on the considerate robot model (success "
                                "valued once; acting against a warning and pre-empting "
                                "costly), its T and O fitted to the world (hrc_fit)")
POMDP_TYPES = RobotPolicy("despot", "robot_types",
                          "the same planner on the robot model of human types: its hidden "
                          "state is (type, task state), each type's T and O fitted to the "
                          "world (hrc_fit --types), so it infers whom it works with")
REACTIVE_ROBOT = RobotPolicy("reactive", None, "treats the need for help as observable "
                                               "(agents/robots.py)")
NO_ROBOT = RobotPolicy("none", None, "never acts")
EXPLORE = RobotPolicy("explore", None, "a uniformly random action each step: hrc_fit's "
                                       "exploring robot")

#: The policies of ``make experiment``'s default grid.
DEFAULT_POLICIES = ("pomdp", "pomdp_fitted", "pomdp_considerate", "reactive", "no_robot")
#: The robot that infers its human's type (issue #31); in a sequence study it is a selector
#: name too: the one robot plays every task, its type belief carried from task to task.
TYPES_POLICY = "pomdp_types"
#: The human alone: the counterfactual every robot's episode is set against.
ALONE_POLICY = "no_robot"
REACTIVE = "reactive"
#: Budgets a ``reactive@N`` may name (hrc.launch's reactive_budget is an int32).
MAX_REACTIVE_BUDGET = 2**31 - 1
_REACTIVE_AT = re.compile(r"reactive@([0-9]{1,10})")


class UnknownPolicy(KeyError):
    """A policy name that finds no robot policy: one line (the registry's, with the known
    names and the nearest)."""

    def __str__(self) -> str:        # KeyError would quote the message
        return str(self.args[0])


def robot_policy(name: str) -> RobotPolicy:
    """The policy a grid names: ``reactive@N``, or a robot policy of the registry (ours, an
    installed package's, ``module:NAME``). UnknownPolicy (a KeyError, one line) otherwise."""
    match = _REACTIVE_AT.fullmatch(name)
    if match and 1 <= int(match.group(1)) <= MAX_REACTIVE_BUDGET:
        return replace(REACTIVE_ROBOT, reactive_budget=int(match.group(1)),
                       doc=f"the reactive robot with budget {int(match.group(1))}")
    try:
        return registry.load(registry.POLICIES, name, RobotPolicy, instance=True)
    except registry.RegistryError as exc:
        raise UnknownPolicy(f"{exc}; or reactive@N") from None


def policy_names() -> Tuple[str, ...]:
    """The robot policies a grid may name now (ours first, then installed packages')."""
    return registry.names(registry.POLICIES)


def is_reactive(name: str) -> bool:
    """Whether the policy is the reactive robot (``reactive`` or ``reactive@N``)."""
    try:
        return robot_policy(name).planner == "reactive"
    except KeyError:
        return False


def reactive_policy_name(budget: int) -> str:
    """``reactive@N``: the name of the reactive robot with budget N in a grid."""
    return f"{REACTIVE}@{budget}"


#: The human's world services that leave the belt, and those that come back to it first.
_LEAVES = frozenset({"walk_away"})
_RETURNS = frozenset({"attempt_grasp", "grasp"})


def task_of_steps(steps: Sequence) -> Task:
    """The task an episode was played in: the one whose robot states its beliefs are over
    (the default task for an episode without steps)."""
    return tasks.of_robot_states(steps[0].belief_states if steps else ())


def needs_help_mass(step, task: Optional[Task] = None) -> float:
    """The robot's belief in "the human needs help" (the task's needs-help states: the seed's
    S2..S5) at this step."""
    task = task or tasks.of_robot_states(step.belief_states)
    return float(sum(p for name, p in zip(step.belief_states, step.belief)
                     if name in task.needs_help_states))


def discounted_robot_reward(steps: Sequence, model: Model) -> float:
    """sum_t gamma^t R(s_t, a_t) of the robot model, with the true robot state s_t the
    observer reported and the action a_t the robot took (for a model of human types, R
    expected under the step's type belief: the observer knows no type)."""
    total, weight = 0.0, 1.0
    layout = TypeLayout.of(model)
    for step in steps:
        a = model.index("action", step.robot_action)
        if layout is None:
            reward = float(model.R_sa[a, model.index("state", step.robot_state)])
        else:   # a model of human types: the reward expected under the step's type belief
            reward = layout.expected_reward(model, step.robot_state, a,
                                            getattr(step, "type_belief", None))
        total += weight * reward
        weight *= model.discount
    return total


def sim_duration(steps: Sequence, start_sim_time: float) -> float:
    """Simulated seconds from the episode's start to the end of its last step, to the
    microsecond (:func:`ros_hrc.tasks.utility.sim_span`)."""
    if not steps:
        return 0.0
    return sim_span(start_sim_time, steps[-1].sim_time)


def time_to_success(steps: Sequence, reason: str, start_sim_time: float) -> float:
    """Simulated seconds from the episode's start to the end of the step that succeeded;
    NaN when the episode did not succeed."""
    if reason != "success" or not steps:
        return math.nan
    return sim_duration(steps, start_sim_time)


def wasted_actions(steps: Sequence, task: Optional[Task] = None) -> int:
    """Robot actions the world answered with nothing:

    * a grasp (the seed's ``rGrasp_obj``, fabric's ``grasp``) after which the robot does not
      hold the object (the world refused it: out of reach, the human holds it; or the gripper
      missed);
    * a point (``rPoint_obj``, ``point``) at a human who is away from the belt: he left with
      ``walkAway`` (the world's ``/human/walk_away``) and has not come back, which only a grasp
      attempt does (``/human/attempt_grasp`` and ``/human/grasp`` walk back first).
    """
    task = task or task_of_steps(steps)
    grasps, points = task.robot_actions_calling("grasp"), task.robot_actions_calling("point_to_obj")
    wasted, away = 0, False
    for step in steps:
        service = task.human_action_services.get(step.human_action)
        if service in _LEAVES:
            away = True
        elif service in _RETURNS:
            away = False
        if step.robot_action in grasps and step.object_holder != "robot":
            wasted += 1
        elif step.robot_action in points and away:
            wasted += 1
    return wasted


def against_warning(steps: Sequence, task: Optional[Task] = None) -> int:
    """Grasps and points while a warning is in force (:meth:`Task.warning_in_force`: from
    the observation that carries the warning until the human acts on the object again; a
    reset, a new episode, lifts it)."""
    task = task or task_of_steps(steps)
    count, in_force = 0, False
    for step in steps:
        in_force = task.warning_in_force(in_force, int(step.observation_bits))
        if in_force and step.robot_action in task.helping_actions:
            count += 1
    return count


def warnings_after_help(steps: Sequence, task: Optional[Task] = None) -> int:
    """Warnings the human gave right after the robot helped: steps whose observation carries
    the warning bit and whose previous step's robot action was a grasp or a point. What an
    intrusion cost: in fabric the robot's grasp makes the human RobotInterfered, from which he
    may warn it (the seed's human does not hear the robot, so there it counts coincidences)."""
    task = task or task_of_steps(steps)
    warning = task.bit("warning")
    return sum(1 for before, step in zip(steps, steps[1:])
               if before.robot_action in task.helping_actions
               and int(step.observation_bits) & warning)


def points(steps: Sequence, task: Optional[Task] = None) -> int:
    """The robot's points (``rPoint_obj``, fabric's ``point``) in the episode."""
    pointing = (task or task_of_steps(steps)).robot_actions_calling("point_to_obj")
    return sum(1 for step in steps if step.robot_action in pointing)


def score_episode(key: EpisodeKey, steps: Sequence, reason: str, start_sim_time: float,
                  model: Model, wall_seconds: float) -> EpisodeRow:
    """One results row for a finished episode, not yet paired with the human alone
    (outcome ``unpaired``: :func:`pair` sets the counterfactual columns)."""
    human_model, robot_policy, seed, episode = key
    holder = steps[-1].object_holder if steps else "none"
    success = reason == "success"
    task = task_of_steps(steps)
    # The old label-based count: helping while the observer's label says no help is needed.
    intrusive = sum(1 for s in steps if s.robot_action in task.helping_actions
                    and s.robot_state not in task.needs_help_states)
    warnings = sum(1 for s in steps if s.observation_bits & task.bit("warning"))
    # Observations the robot's model gave probability 0: where the model and the world disagree.
    zero_probability = sum(1 for s in steps if getattr(s, "surprise", False))
    decisions = [s.decision_ms for s in steps]
    return EpisodeRow(
        human_model=human_model, robot_policy=robot_policy, seed=seed, episode=episode,
        success=int(success),
        succeeded_by=holder if success else "none", end_reason=reason, steps=len(steps),
        sim_seconds=sim_duration(steps, start_sim_time),
        time_to_success=time_to_success(steps, reason, start_sim_time),
        alone_success=0, alone_time_to_success=math.nan, outcome=UNPAIRED,
        time_gain=math.nan, wasted_actions=wasted_actions(steps, task),
        against_warning=against_warning(steps, task), in_sample=0, points=points(steps, task),
        warnings_after_help=warnings_after_help(steps, task),
        robot_discounted_reward=discounted_robot_reward(steps, model),
        intrusive_actions=intrusive, warnings=warnings,
        zero_probability_observations=zero_probability,
        mean_decision_ms=float(np.mean(decisions)) if decisions else 0.0,
        wall_seconds=wall_seconds)


def stream_of(row: EpisodeRow) -> tuple:
    """(human_model, seed, episode): the human stream an episode ran on."""
    return (row.human_model, row.seed, row.episode)


def pair(row: EpisodeRow, alone: EpisodeRow, in_sample: bool = False) -> EpisodeRow:
    """``row`` with its counterfactual columns set from ``alone``, the ``no_robot`` episode
    on the same (human model, seed, episode) stream; ``in_sample`` marks a row whose robot
    model was fitted on this stream. ValueError when ``alone`` is not that episode."""
    if alone.robot_policy != ALONE_POLICY or stream_of(alone) != stream_of(row):
        raise ValueError(f"episode {alone.key} is not the human alone on the stream of "
                         f"{row.key}")
    both = bool(row.success and alone.success)
    return replace(
        row, alone_success=alone.success, alone_time_to_success=alone.time_to_success,
        outcome=counterfactual_outcome(bool(alone.success), bool(row.success),
                                       row.succeeded_by),
        time_gain=(alone.time_to_success - row.time_to_success) if both else math.nan,
        in_sample=int(bool(in_sample)))


def pair_alone(row: EpisodeRow) -> EpisodeRow:
    """A ``no_robot`` row paired with itself: it is the human alone."""
    return pair(row, row)


def step_rows(key: EpisodeKey, steps: Sequence) -> list:
    """The episode's per-step trace (for the belief plot)."""
    human_model, robot_policy, seed, episode = key
    task = task_of_steps(steps)
    return [StepRow(human_model=human_model, robot_policy=robot_policy, seed=seed,
                    episode=episode, step=int(s.step), human_action=s.human_action,
                    human_state=s.human_state, robot_state=s.robot_state,
                    robot_action=s.robot_action, observation=s.robot_observation,
                    belief_needs_help=needs_help_mass(s, task),
                    needs_help=int(s.robot_state in task.needs_help_states),
                    zero_probability=int(bool(getattr(s, "surprise", False))))
            for s in steps]
