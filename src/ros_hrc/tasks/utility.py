"""How one task of a sequence went, and the one utility that scores it (issue #30).

A task of a sequence ends in one of three ways (:data:`OUTCOMES`): ``success`` (the object
was taken, by the human or by the robot: FABRIC counts both trays), ``fail`` (the object left
the belt) or ``timeout`` (the task ran ``task_timeout`` simulated seconds, or its step limit).
:class:`TaskOutcome` is what the loop's coordinator measured; :func:`task_utility` scores it
on one scale whatever the robot's policy, never with a policy's own POMDP reward (FABRIC's
performance model used each policy's own reward, whose scales differ between policies).
Why these weights: docs/sequences.md, "The utility". No ROS, no sockets: plain data.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["OUTCOMES", "WHO_SUCCEEDED", "TaskOutcome", "task_utility", "sim_span",
           "utility_rewards", "UTILITY_REWARD_SCALE", "AGAINST_WARNING_COST"]

#: How a task ends.
OUTCOMES = ("success", "fail", "timeout")
#: Who took the object ("" when no one did).
WHO_SUCCEEDED = ("human", "robot", "")


def sim_span(start: float, end: float) -> float:
    """Simulated seconds from ``start`` to ``end``, two readings of the world's clock, to the
    microsecond (never below 0). The world's clock runs on across episodes, tasks and a warm
    stack's cells, so the plain difference of two readings carries rounding from the clock's
    size: unrounded, the same task would last 6.6 s on a new world and 6.599999999999994 s on
    an older one, and a wait compared with it could end a step apart."""
    return round(max(0.0, float(end) - float(start)), 6)


@dataclass(frozen=True)
class TaskOutcome:
    """How one task went, as the loop measured it.

    ``outcome``: one of :data:`OUTCOMES`; ``who_succeeded``: ``human``, ``robot`` or ``""``;
    ``warnings``: the human's warnRobot actions in the task; ``preemptions``: the robot took
    the object while the human's true state was not a needs-help state of the task
    (``Task.needs_help_states``), counted once; ``duration``: simulated seconds from the
    task's start to its end; ``timeout``: the ``task_timeout`` in force (simulated s)."""

    outcome: str
    who_succeeded: str
    warnings: int
    preemptions: int
    duration: float
    timeout: float

    def __post_init__(self) -> None:
        if self.outcome not in OUTCOMES:
            raise ValueError(f"outcome must be one of {', '.join(OUTCOMES)}, not "
                             f"{self.outcome!r}")
        if self.who_succeeded not in WHO_SUCCEEDED:
            raise ValueError(f"who_succeeded must be human, robot or empty, not "
                             f"{self.who_succeeded!r}")
        if self.warnings < 0 or self.preemptions < 0 or self.duration < 0 or self.timeout <= 0:
            raise ValueError("warnings, preemptions and duration >= 0 and timeout > 0 are "
                             "required")


#: The largest utility a task can have: a success at once, with no warning and no pre-emption.
UTILITY_MAX = 1.0


def task_utility(outcome: TaskOutcome) -> float:
    """The task's utility, the same scale for every policy (range about [-1.5, 1]): 1 for a
    success, minus half the share of the timeout it took, minus 0.1 a warning, minus 0.5 a
    pre-emption (docs/sequences.md says why; the selector model file keeps this definition in
    one line, ``ros_hrc.agents.selector_model.UTILITY_DEFINITION``)."""
    return ((1.0 if outcome.outcome == "success" else 0.0)
            - 0.5 * min(outcome.duration / outcome.timeout, 1.0)
            - 0.1 * outcome.warnings - 0.5 * outcome.preemptions)


#: Reward units per unit of utility in a model of the utility (:func:`utility_rewards`): a
#: success is worth 20, as in the considerate robot model, so DESPOT's pruning constant
#: (lambda 0.1) weighs the same against it.
UTILITY_REWARD_SCALE = 20.0
#: What acting against a warning costs in a model of the utility, in utility units. The
#: utility does not price it (a warning's own -0.1 has been paid by then), but the studies
#: require that a robot never does it (docs/learning.md), so it is priced above any success.
AGAINST_WARNING_COST = 1.5


def utility_rewards(task, step_seconds: float, timeout: float = 0.0,
                    scale: float = UTILITY_REWARD_SCALE) -> list:
    """R[a][s][s'] of the task's robot model (its actions and states in the task's order) that
    prices a step as :func:`task_utility` prices a task, times ``scale``: +1 on the step into
    the success state (whoever brought it about); -0.5 more when the robot's grasp brought it
    about from a state that needed no help (a pre-emption); -0.1 on a step into the warned
    state (a warning); -0.5 x ``step_seconds`` / ``timeout`` on every step before success (the
    share of the timeout used; ``timeout`` 0: the task's); and :data:`AGAINST_WARNING_COST` for
    any action but idling or stopping in the warned state. Nested lists of floats."""
    if not step_seconds > 0:
        raise ValueError(f"step_seconds must be > 0, not {step_seconds!r}")
    timeout = timeout or task.task_timeout
    states, actions = list(task.robot_states), list(task.robot_actions)
    success = task.robot_success_state
    warned = task.robot_warned_state
    if not success or not warned:
        raise ValueError(f"task {task.name} names no success or warned robot state: its "
                         f"utility has no model")
    grasps = task.robot_actions_calling("grasp")
    quiet = {task.robot_idle_action} | set(task.robot_actions_calling("cancel_action"))
    time_cost = 0.5 * min(step_seconds / timeout, 1.0)
    R = []
    for a in actions:
        rows = []
        for s in states:
            row = []
            for s2 in states:
                r = 0.0
                if s != success:
                    r -= time_cost
                    if s2 == success:
                        r += 1.0
                        if a in grasps and s not in task.needs_help_states:
                            r -= 0.5
                    if s2 == warned and s != warned:
                        r -= 0.1
                if s == warned and a not in quiet:
                    r -= AGAINST_WARNING_COST
                row.append(r * scale)
            rows.append(row)
        R.append(rows)
    return R
