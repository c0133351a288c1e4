"""The seed's task (the manual's, DESIGN §1, §4): the default task, as the seed defines it.

* How the world's predicates become the robot model's observation (DESIGN §4): bits
  1 object visible, 2 object in range, 4 grasp attempt, 8 human has object, 16 warning
  received, 32 human idle; only 15 bit sums are observations of the robot model, and any other
  pattern maps to the nearest legal one (rule in :func:`legal_bits`).
* How the human's true MDP state, and its history since the last reset, maps to the robot
  model's true state S0..S6 (rule in :class:`RobotStateTracker`). The robot never sees it:
  it is reported and used for scoring.
* Which world service carries out each human and robot action.
* The human does not react to the robot (his next state is his MDP's, drawn before the robot
  acts) and the robot's observations carry no noise.

:data:`SEED` is all of it as one :class:`~ros_hrc.tasks.definition.Task`; the module's names
(``LEGAL_BITS``, ``legal_bits`` ...) stay importable as before (also as ``ros_hrc.tasks.seed``).
No ROS, no PyBullet: plain data and functions.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, Mapping, Optional, Tuple

from ros_hrc.model_files import MODELS_DIR
from ros_hrc.tasks.definition import Observations, Task

VISIBLE, IN_RANGE, GRASP_ATTEMPT, HAS_OBJECT, WARNING, IDLE = 1, 2, 4, 8, 16, 32

#: The robot model's observations, as bit sums, in the model's order (O0 ... O35).
LEGAL_BITS: Tuple[int, ...] = (0, 1, 2, 3, 7, 10, 11, 16, 17, 18, 19, 32, 33, 34, 35)

# When a pattern is equally far from two legal ones, keep the bit that matters most for
# deciding whether the human needs help: holding the object ends the task, a warning must
# stop the robot, a grasp attempt shows intent, idling shows hesitation, range and
# visibility are context.
_BIT_PRIORITY = (HAS_OBJECT, WARNING, GRASP_ATTEMPT, IDLE, IN_RANGE, VISIBLE)

#: Predicate services of the world (seed Table 3.2) and the bit each one sets.
PREDICATE_BITS: Dict[str, int] = {
    "is_ov": VISIBLE, "is_oir": IN_RANGE, "is_a0": GRASP_ATTEMPT,
    "is_ho": HAS_OBJECT, "is_h4": WARNING, "is_a2": IDLE,
}

#: The robot model's observations: one bit sum each (O0 ... O35), nearest for the others.
OBSERVATIONS = Observations(
    [(f"O{b}", (b,)) for b in LEGAL_BITS],
    bit_names=[(VISIBLE, "visible"), (IN_RANGE, "in_range"), (GRASP_ATTEMPT, "grasp_attempt"),
               (HAS_OBJECT, "has_object"), (WARNING, "warning"), (IDLE, "idle")],
    priority=_BIT_PRIORITY, max_bits=63)

#: Human MDP actions -> world service under /human (None: nothing to call, the human stays idle).
HUMAN_ACTION_SERVICES: Dict[str, Optional[str]] = {
    "graspAttempt": "attempt_grasp",   # "grasp" instead when the MDP's next state is success
    "lookAround": "look_around",
    "idle": "idle",
    "walkAway": "walk_away",
    "warnRobot": "warn_robot",
}

#: Robot POMDP actions -> world service under /robot (None: keep observing, move nothing).
ROBOT_ACTION_SERVICES: Dict[str, Optional[str]] = {
    "rIdle": None,
    "rPoint_obj": "point_to_obj",
    "rGrasp_obj": "grasp",
    "rStop_all": "cancel_action",
}

HUMAN_STATES: Tuple[str, ...] = ("task_assigned", "success", "failed_to_grasp", "no_attention",
                                 "evaluating", "tired", "recovery", "warningTheRobot")
ROBOT_STATES: Tuple[str, ...] = ("S0", "S1", "S2", "S3", "S4", "S5", "S6")
#: Robot states in which the human needs (or may need) help: used to score intrusive actions.
NEEDS_HELP_STATES = frozenset({"S2", "S3", "S4", "S5"})


def human_service_for(action: str, next_state: str) -> Optional[str]:
    """The /human/* service that carries out the MDP's action leading to ``next_state``."""
    return SEED.human_service_for(action, next_state)


def bits_from_predicates(predicates: Mapping[str, bool]) -> int:
    """Bit sum of the true predicates, keyed by service name (``is_ov`` ...)."""
    return sum(bit for name, bit in PREDICATE_BITS.items() if predicates.get(name))


def legal_bits(bits: int) -> int:
    """The legal observation nearest to ``bits``.

    Nearest means fewest differing bits; among equally near ones, the one that agrees with
    ``bits`` on the most important bit first (order of ``_BIT_PRIORITY``), then the smaller
    (:meth:`~ros_hrc.tasks.definition.Observations.nearest`).
    """
    return OBSERVATIONS.nearest(bits)


def observation_name(bits: int) -> str:
    """Name of a legal observation in the robot model, e.g. ``O35``."""
    if bits not in LEGAL_BITS:
        raise ValueError(f"{bits} is not one of the robot model's observations {LEGAL_BITS}")
    return f"O{bits}"


def predicates_text(predicates: Mapping[str, bool]) -> str:
    """The predicates as the step block prints them, e.g. ``ov=1 oir=1 a0=0 ...``."""
    return SEED.predicates_text(predicates)


def describe_bits(bits: int) -> str:
    """Human-readable list of the bits set, e.g. ``visible+in_range+idle``."""
    return OBSERVATIONS.describe(bits)


#: Consecutive steps spent evaluating (without a failure first) after which a human "may need
#: help" (S2) and "needs help" (S3): a human who keeps evaluating and never grasps is stuck.
EVALUATING_MAY_NEED_HELP = 2
EVALUATING_NEEDS_HELP = 4


@dataclass
class RobotStateTracker:
    """Maps the human's MDP state, with its history since reset, to the robot's true state.

    The robot's states say whether the human needs help to get the object, so the label looks
    at what the human has been doing, not only at where he is now:

    S0 no help needed: the task was just assigned, or he has evaluated for less than
       :data:`EVALUATING_MAY_NEED_HELP` steps in a row with no failure so far;
    S1 the human has the object (success);
    S2 may need help grasping: one failed grasp, evaluating after a failure, or evaluating for
       :data:`EVALUATING_MAY_NEED_HELP` steps in a row;
    S3 needs help grasping: failed twice or more, tired, recovering after walking away, or
       evaluating for :data:`EVALUATING_NEEDS_HELP` steps in a row without ever grasping;
    S4 may need help grasping or finding: attention lost once;
    S5 needs help finding: attention lost twice or more in a row;
    S6 the human warned the robot: he is in ``warningTheRobot`` and his action was
       ``warnRobot`` (the world shows the warning). A human who reaches ``warningTheRobot``
       by another action means to warn but has not: a grasp attempt that brought him there
       counts as a failed grasp, any other action keeps the previous step's label (labelling
       S6 there taught a fitted robot that a failed grasp, O7, may be a warning).
    """

    failures: int = 0
    inattention_streak: int = 0
    evaluating_streak: int = 0
    label: str = "S0"

    def reset(self) -> None:
        self.failures = 0
        self.inattention_streak = 0
        self.evaluating_streak = 0
        self.label = "S0"

    def update(self, human_state: str, human_action: Optional[str] = None) -> str:
        """Account for the human's new state, reached by ``human_action`` (None: not known,
        the state alone decides), and return the robot's true state."""
        self.label = self._label(human_state, human_action)
        return self.label

    def _label(self, human_state: str, human_action: Optional[str]) -> str:
        if human_state not in HUMAN_STATES:
            raise ValueError(f"unknown human state {human_state!r}")
        if human_state == "warningTheRobot" and human_action not in (None, "warnRobot"):
            self.inattention_streak = self.evaluating_streak = 0
            if human_action == "graspAttempt":
                self.failures += 1
                return "S2" if self.failures == 1 else "S3"
            return self.label
        self.inattention_streak = self.inattention_streak + 1 if human_state == "no_attention" else 0
        self.evaluating_streak = self.evaluating_streak + 1 if human_state == "evaluating" else 0
        if human_state == "failed_to_grasp":
            self.failures += 1
            return "S2" if self.failures == 1 else "S3"
        if human_state == "success":
            return "S1"
        if human_state == "warningTheRobot":
            return "S6"
        if human_state in ("tired", "recovery"):
            return "S3"
        if human_state == "no_attention":
            return "S4" if self.inattention_streak == 1 else "S5"
        if human_state == "evaluating":
            if self.evaluating_streak >= EVALUATING_NEEDS_HELP and not self.failures:
                return "S3"
            if self.failures or self.evaluating_streak >= EVALUATING_MAY_NEED_HELP:
                return "S2"
            return "S0"
        return "S0"  # task_assigned


def snapshot_bits(snapshot: Any) -> int:
    """The raw bits of a world snapshot: its predicates' (the human's own view)."""
    return bits_from_predicates(snapshot.predicates)


#: The seed's task, as data.
SEED = Task(
    name="seed",
    title="the seed's task (the manual's): an 8-state human who does not react to the robot, "
          "a 7-state, 4-action, 15-observation robot",
    human_states=HUMAN_STATES,
    human_action_services=HUMAN_ACTION_SERVICES,
    human_grasp_action="graspAttempt",
    goal_state="success",
    robot_states=ROBOT_STATES,
    robot_action_services=ROBOT_ACTION_SERVICES,
    robot_idle_action="rIdle",
    needs_help_states=NEEDS_HELP_STATES,
    robot_success_state="S1",
    recovery_state="S2",
    learning_prior="robot_utility_fitted",
    learning_bonus=10.0,
    robot_warned_state="S6",
    observations=OBSERVATIONS,
    predicate_bits=PREDICATE_BITS,
    raw_bits=snapshot_bits,
    new_tracker=lambda human_model="": RobotStateTracker(),
    reaction=None,
    noise=None,
    default_human_model="humanModel",
    default_robot_model="robot",
    reactive_robot="rules",
    model_dirs={"human": MODELS_DIR / "human", "robot": MODELS_DIR / "robot"},
    notes=("The human's next state is his MDP's, drawn with his action before the robot "
           "acts; the step shows it (the state his action led to).",
           "Observations are the true predicates, mapped to the nearest of the 15 legal bit "
           "sums; no noise."),
)

#: What :func:`ros_hrc.tasks.get` returns for "seed".
TASK = SEED
