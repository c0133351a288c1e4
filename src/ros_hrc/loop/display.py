"""What a person watching the collaboration is shown of each step, in words and bars (no ROS).

One source for the PyBullet window's overlay and RViz's markers: :func:`status_lines` turns a
step (anything with the fields of ``ros_hrc/Status``) into a few short lines, and
:func:`belief_bars` into the robot's belief per state with the true state marked.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import List, Sequence

from ros_hrc.loop import task


@dataclass(frozen=True)
class BeliefBar:
    """One state's bar: its name, the robot's belief in it, and whether it is the true state."""
    state: str
    probability: float
    true_state: bool
    needs_help: bool


def needs_help_probability(belief_states: Sequence[str], belief: Sequence[float]) -> float:
    """The robot's belief that the human needs help (the mass on S2..S5)."""
    return float(sum(p for s, p in zip(belief_states, belief) if s in task.NEEDS_HELP_STATES))


def holder_text(holder: str) -> str:
    return {"human": "the human holds the object", "robot": "the robot holds the object"}.get(
        holder, "nobody holds the object")


def status_lines(status) -> List[str]:
    """The step in four lines: which step, what the human did and is, what the robot saw and
    did, and what it believes; e.g. ::

        episode 2, step 3
        human: graspAttempt -> failed_to_grasp
        robot: sees O7 (grasp_attempt+visible+in_range), does rGrasp_obj (true state S2)
        P(human needs help) = 0.87; nobody holds the object
    """
    bits = int(getattr(status, "observation_bits", 0))
    lines = [f"episode {getattr(status, 'episode', 0)}, step {status.step}",
             f"human: {status.human_action or '-'} -> {status.human_state or '-'}",
             f"robot: sees {status.robot_observation or '-'} ({task.describe_bits(bits)}), "
             f"does {status.robot_action or '-'} (true state {status.robot_state or '-'})"]
    help_p = needs_help_probability(status.belief_states, status.belief)
    tail = holder_text(getattr(status, "object_holder", "none"))
    if getattr(status, "episode_over", False):
        tail += f"; episode over: {getattr(status, 'end_reason', '') or '?'}"
    lines.append(f"P(human needs help) = {help_p:.2f}; {tail}")
    return lines


def belief_bars(status) -> List[BeliefBar]:
    """The robot's belief over its model's states, in the model's order, the true one marked."""
    return [BeliefBar(state=s, probability=float(p), true_state=(s == status.robot_state),
                      needs_help=s in task.NEEDS_HELP_STATES)
            for s, p in zip(status.belief_states, status.belief)]
