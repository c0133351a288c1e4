"""``fabric``: the seed authors' successor task, a human who reacts to the robot.

FABRIC is the successor system of the seed's authors (GitHub
``cangorur/human_robot_collaboration``, GPL-3.0; Görür et al., "Social Cobots", HRI 2018, and
ACM THRI 2023, DOI 10.1145/3585276). Its rules, as facts, are in
``docs/tasks_fabric_facts.md`` (with the files and commits they were read from); this module
is our own code for them, and ``docs/tasks.md`` says where it differs and why.

* **The human** (12 states, the seed's five actions) *reacts* (:class:`FabricReaction`): he acts
  in his state (a grasp's outcome is drawn before the robot acts, and is the state the step
  shows); after the robot acted, the first rule that applies gives his next state: the task's
  end (or a terminal state) stays; Recovery, or a walk away, -> Recovery; the robot grasped ->
  RobotInterfered (already in it: a draw from its row); his own grasp -> its outcome; the robot pointed -> Evaluating; he warned
  and the robot idled or cancelled -> RobotIsWarned; else a draw from his model's row.
* **The robot** (11 states, 5 actions: idle, grasp, cancel, point, graspPlanning, the last
  through ``/robot/grasp_planning``) sees 12 observations mapped from seven bits: the seed's
  six, with 8 meaning "someone holds the object", and 64 "the object left the belt"
  (:class:`FabricObservationMap`, the authors' two-step table).
* **Noise** (:func:`noisy_bits`): with p = 1/20 a shown grasp or warning is swapped (half the
  time) or missed as idling (the other half); else, with p = 1/20, a human who looks around or
  idles is seen doing the other.
* **The robot's true state** (:class:`FabricStateTracker`): the authors' per-task counters and
  rules, with the two facts they take per human: his mood (a ``tired`` type) and whether he
  trusts the robot (drawn per episode, p = 2/3).
* **Its world** (:data:`WORLD_FACTS`, the task's ``world_facts``): the product waits between
  the human and the robot on a still belt; 45 s into the task the belt runs, and 7 s later
  the product falls into the tray at the belt's end (the task failed); the robot plans 4 s
  before a grasp or a point unless a graspPlanning did, and its grasp counts once the product
  lies in its own tray, 4.2 s after the gripper closed, a cancel before that putting the
  product back; the grasp is answered as it starts, so the human acts (warns) meanwhile
  (docs/tasks.md, "Why a fabric task fails").

No ROS, no PyBullet: data and small pure functions.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Sequence, Tuple

from ros_hrc.model_files import MODELS_DIR
from ros_hrc.tasks.definition import Draw, Observations, Reaction, Task

__all__ = ["FABRIC", "TASK", "WORLD_FACTS", "TaskWithWorld", "HUMAN_STATES",
           "HUMAN_ACTION_SERVICES", "ROBOT_STATES", "ROBOT_ACTION_SERVICES", "OBSERVATIONS", "FabricObservationMap", "noisy_bits",
           "FabricStateTracker", "FabricReaction", "NOISE_ONE_IN", "TRUST_PROBABILITY"]

# -- bits -------------------------------------------------------------------------------------
VISIBLE, IN_RANGE, GRASP_ATTEMPT, SUCCESS, WARNING, IDLE, FAILURE = 1, 2, 4, 8, 16, 32, 64

#: Predicate services of the world and the bit each sets (8 comes from who holds the object,
#: 64 from the object having left the belt: :func:`snapshot_bits`).
PREDICATE_BITS: Dict[str, int] = {
    "is_ov": VISIBLE, "is_oir": IN_RANGE, "is_a0": GRASP_ATTEMPT,
    "is_ho": SUCCESS, "is_h4": WARNING, "is_a2": IDLE,
}


def snapshot_bits(snapshot: Any) -> int:
    """The seven bits of a world snapshot: the human's predicates, but 8 when anyone holds
    the object (the authors' tray sensor saw either's success) and 64 when it left the belt."""
    predicates = snapshot.predicates
    bits = sum(bit for name, bit in PREDICATE_BITS.items()
               if bit != SUCCESS and predicates.get(name))
    if getattr(snapshot, "holder", "none") in ("human", "robot") or predicates.get("is_ho"):
        bits |= SUCCESS
    if getattr(snapshot, "left_belt", False):
        bits |= FAILURE
    return bits


# -- the names ----------------------------------------------------------------------------------
HUMAN_STATES: Tuple[str, ...] = (
    "TaskHuman", "GlobalSuccess", "GlobalFail", "FailedToGrasp", "NoAttention", "Evaluating",
    "Tired", "Recovery", "RobotInterfered", "WarningTheRobot", "RobotIsWarned", "TaskRobot")
TERMINAL_STATES = frozenset({"GlobalSuccess", "GlobalFail"})

HUMAN_ACTION_SERVICES: Dict[str, Optional[str]] = {
    "graspAttempt": "attempt_grasp",   # "grasp" when the drawn outcome is GlobalSuccess
    "lookAround": "look_around",
    "idle": "idle",
    "walkAway": "walk_away",
    "warnRobot": "warn_robot",
}

ROBOT_STATES: Tuple[str, ...] = (
    "TaskHuman", "MayNotBeCapable", "MayBeTired", "NoFocus", "NeedsToBeReminded", "NeedsHelp",
    "NoNeedHelp", "WarningReceived", "GlobalSuccess", "GlobalFail", "TaskRobot")
NEEDS_HELP_STATES = frozenset({"MayNotBeCapable", "MayBeTired", "NoFocus",
                               "NeedsToBeReminded", "NeedsHelp"})

ROBOT_ACTION_SERVICES: Dict[str, Optional[str]] = {
    "idle": None,
    "grasp": "grasp",
    "cancel": "cancel_action",
    "point": "point_to_obj",
    "graspPlanning": "grasp_planning",   # the arm moves to a pre-grasp pose
}

# -- observations -------------------------------------------------------------------------------
#: The robot model's 12 observations (named by their smallest bit sum), in the model's order,
#: and the authors' observables each one stands for.
OBSERVATIONS = Observations(
    [("O0", (0, 1)), ("O2", (2,)), ("O3", (3,)), ("O6", (6,)), ("O7", (7,)),
     ("O8", (8, 9, 10, 11, 14, 15)), ("O16", (16, 17, 18, 19, 27)), ("O32", (32, 33)),
     ("O34", (34,)), ("O35", (35,)), ("O40", (40, 42, 43)),
     ("O64", (64, 65, 66, 67, 70, 71) + tuple(range(80, 88)) + (96, 98, 99, 103))],
    bit_names=[(VISIBLE, "visible"), (IN_RANGE, "in_range"), (GRASP_ATTEMPT, "grasp_attempt"),
               (SUCCESS, "object_taken"), (WARNING, "warning"), (IDLE, "idle"),
               (FAILURE, "left_belt")],
    priority=(FAILURE, SUCCESS, WARNING, GRASP_ATTEMPT, IDLE, IN_RANGE, VISIBLE),
    max_bits=127)

#: The authors' step 1: the bit combinations that are an observable of their own.
NAMED_OBSERVABLES = frozenset({
    0, 1, 2, 3, 6, 7, 8, 9, 10, 11, 14, 15, 16, 18, 19, 27, 32, 34, 35, 40, 42, 43, 46, 47, 64,
    66, 67, 70, 71, 80, 82, 83, 86, 87, 96, 98, 99, 102, 103})


class FabricObservationMap:
    """One episode's map, the authors' two steps. Step 1: bits -> observable (a named
    combination is itself; any other is 64 when the object left the belt, else 8 when it is
    held, else the previous step's observable, 0 at the episode's start). Step 2: observable
    -> observation (by the table of :data:`OBSERVATIONS`; an observable outside it is the
    previous step's observation; at the episode's start, where the authors have none, the
    nearest pattern's, :meth:`Observations.nearest`)."""

    def __init__(self, observations: Observations = OBSERVATIONS) -> None:
        self.observations = observations
        self.previous_observable = 0
        self.previous_observation: Optional[str] = None

    def __call__(self, raw: int) -> Tuple[int, str]:
        if not 0 <= raw <= self.observations.max_bits:
            raise ValueError(f"observation bits {raw} outside 0..{self.observations.max_bits}")
        if raw in NAMED_OBSERVABLES:
            observable = raw
        elif raw & FAILURE:
            observable = FAILURE
        elif raw & SUCCESS:
            observable = SUCCESS
        else:
            observable = self.previous_observable
        try:
            name = self.observations.name_of(observable)
        except ValueError:
            name = self.previous_observation or self.observations.name_of(
                self.observations.nearest(observable))
        self.previous_observable, self.previous_observation = observable, name
        return observable, name


# -- noise ----------------------------------------------------------------------------------------
#: One chance in this many, per step, that the robot misreads the human (the authors' r = 0).
NOISE_ONE_IN = 20


def noisy_bits(bits: int, rng: Any) -> Tuple[int, str]:
    """The bits the robot sees, and what the noise did ("" when nothing). Two numbers are
    drawn every call (r uniform in 0..19, a coin m), so the stream stays aligned:

    * a grasp attempt or a warning shows and r = 0: with m = 0 both bits are inverted (a grasp
      reads as a warning and the reverse), with m = 1 both clear and idle is set (missed);
    * else, the human does not look at the object or idles, and r = 0: those two bits invert.
    """
    r = int(rng.integers(NOISE_ONE_IN))
    m = int(rng.integers(2))
    gesture = GRASP_ATTEMPT | WARNING
    if bits & gesture:
        if r != 0:
            return bits, ""
        if m == 0:
            return bits ^ gesture, "grasp and warning mixed up"
        return (bits & ~gesture) | IDLE, "grasp or warning missed: seen as idle"
    if (not bits & VISIBLE or bits & IDLE) and r == 0:
        return bits ^ (VISIBLE | IDLE), "looking around and idling mixed up"
    return bits, ""


# -- the robot's true state ----------------------------------------------------------------------
#: The chance that a new human trusts the robot (the authors' task manager draws it per human).
TRUST_PROBABILITY = 2.0 / 3.0


def tired_mood(human_model: str) -> bool:
    """Whether a human model is of a tired type: ``tired`` is a word of its file's name
    (``beginner_tired_collaborative``; not ``nontired``)."""
    stem = Path(str(human_model)).name.split(".")[0]
    return "tired" in stem.lower().split("_")


@dataclass
class FabricStateTracker:
    """The robot model's true state from the human's state, the authors' rules (the task is
    the human's): counters of FailedToGrasp, Evaluating, Tired and NoAttention states (all
    back to 0 at TaskHuman, TaskRobot and every reset), the human's mood (``tired``) and
    whether he trusts the robot (drawn per episode: :meth:`begin_episode`).

    TaskHuman, GlobalSuccess, GlobalFail, TaskRobot: themselves; Recovery: NeedsHelp;
    WarningTheRobot: WarningReceived; RobotIsWarned: NoNeedHelp; RobotInterfered: the label
    stays. Evaluating: MayBeTired for a tired human; else TaskHuman for the first two, then
    MayNotBeCapable after a failure, NoFocus after inattention (it wins), else TaskHuman.
    FailedToGrasp: the first NeedsHelp when he trusts the robot and evaluated more than once,
    else MayNotBeCapable; later ones NeedsHelp when he trusts it, else NoNeedHelp. NoAttention:
    MayBeTired for a tired human; else NoFocus the first time, NeedsToBeReminded after.
    Tired: the first MayBeTired (NeedsHelp when he trusts the robot and was inattentive more
    than once or evaluated more than twice); later ones NeedsHelp when he trusts it, else
    NoNeedHelp."""

    tired: bool = False
    trusts_robot: bool = True
    failed: int = 0
    evaluating: int = 0
    tired_count: int = 0
    no_attention: int = 0
    label: str = "TaskHuman"

    def reset(self) -> None:
        self.failed = self.evaluating = self.tired_count = self.no_attention = 0
        self.label = "TaskHuman"

    def begin_episode(self, rng: Any) -> None:
        """A new human: whether he trusts the robot, drawn from the episode's stream."""
        self.trusts_robot = bool(rng.random() < TRUST_PROBABILITY)

    def update(self, human_state: str, human_action: Optional[str] = None) -> str:
        if human_state not in HUMAN_STATES:
            raise ValueError(f"unknown human state {human_state!r}")
        self.failed += human_state == "FailedToGrasp"
        self.evaluating += human_state == "Evaluating"
        self.tired_count += human_state == "Tired"
        self.no_attention += human_state == "NoAttention"
        if human_state in ("TaskHuman", "TaskRobot"):
            self.failed = self.evaluating = self.tired_count = self.no_attention = 0
        self.label = self._label(human_state)
        return self.label

    def _label(self, state: str) -> str:
        fixed = {"TaskHuman": "TaskHuman", "GlobalSuccess": "GlobalSuccess",
                 "GlobalFail": "GlobalFail", "TaskRobot": "TaskRobot", "Recovery": "NeedsHelp",
                 "WarningTheRobot": "WarningReceived", "RobotIsWarned": "NoNeedHelp"}
        if state in fixed:
            return fixed[state]
        if state == "Evaluating":
            if self.tired:
                return "MayBeTired"
            if self.evaluating <= 2:
                return "TaskHuman"
            label = "TaskHuman"
            if self.failed > 0:
                label = "MayNotBeCapable"
            if self.no_attention > 0:
                label = "NoFocus"
            return label
        if state == "FailedToGrasp":
            if self.failed == 1:
                return "NeedsHelp" if self.trusts_robot and self.evaluating > 1 \
                    else "MayNotBeCapable"
            return "NeedsHelp" if self.trusts_robot else "NoNeedHelp"
        if state == "NoAttention":
            if self.tired:
                return "MayBeTired"
            return "NoFocus" if self.no_attention == 1 else "NeedsToBeReminded"
        if state == "Tired":
            if self.tired_count == 1:
                helped = self.trusts_robot and (self.no_attention > 1 or self.evaluating > 2)
                return "NeedsHelp" if helped else "MayBeTired"
            return "NeedsHelp" if self.trusts_robot else "NoNeedHelp"
        return self.label   # RobotInterfered: no rule of its own


def new_tracker(human_model: str = "") -> FabricStateTracker:
    """The labeller for a human model (its name or path says whether he is a tired type)."""
    return FabricStateTracker(tired=tired_mood(human_model))


# -- how the human reacts ------------------------------------------------------------------------
#: The world's ends of the task (the loop's end reasons) and the human's state they set.
END_STATES = {"success": "GlobalSuccess", "object_left_belt": "GlobalFail"}


class FabricReaction:
    """The authors' reaction rules (``getNextState``), in their order; see the module
    docstring and ``docs/tasks.md`` (where a robot's grasp differs: the interfered human is
    RobotInterfered for a step of his own)."""

    grasp = "graspAttempt"

    def acting_state(self, state: str, action: str, draw: Draw) -> str:
        """The state the step shows: a grasp's outcome, drawn now (before the robot acts);
        for any other action the state he acts in."""
        if action == self.grasp and state not in TERMINAL_STATES:
            return draw(state, action)
        return state

    def next_state(self, acting: str, action: str, robot_action: str, end_reason: str,
                   draw: Draw) -> Reaction:
        if end_reason in END_STATES:
            state = END_STATES[end_reason]
            return Reaction(state, "task_end", f"the task ended ({end_reason}): {state}")
        if acting in TERMINAL_STATES:
            return Reaction(acting, "terminal", f"{acting} stays")
        if acting == "Recovery" or action == "walkAway":
            why = "he walked away" if action == "walkAway" else "he is recovering"
            return Reaction("Recovery", "recovery", f"{why}: Recovery")
        if robot_action == "grasp":
            if acting != "RobotInterfered":
                return Reaction("RobotInterfered", "robot_grasped",
                                "the robot grasped: RobotInterfered")
            # Interfered already and the robot grasps on: the authors draw from
            # RobotInterfered's row at every grasp, so a human under a robot that keeps
            # grasping may warn it or turn away, not stand still (docs/tasks.md).
            state = draw("RobotInterfered", action)
            return Reaction(state, "robot_grasped_again",
                            f"the robot grasped again: drawn from RobotInterfered's {action} "
                            f"row: {state}")
        if action == self.grasp:
            return Reaction(acting, "own_grasp", f"his grasp's outcome, drawn before the robot "
                                                 f"acted: {acting}")
        if robot_action == "point":
            return Reaction("Evaluating", "robot_pointed", "the robot pointed: Evaluating")
        if action == "warnRobot" and robot_action in ("idle", "cancel"):
            did = "idled" if robot_action == "idle" else "cancelled"
            return Reaction("RobotIsWarned", "robot_warned",
                            f"he warned and the robot {did}: RobotIsWarned")
        state = draw(acting, action)
        return Reaction(state, "model", f"drawn from his model's {action} row: {state}")

    def allowed(self, state: str, action: str, next_state: str) -> bool:
        """A draw never gives GlobalFail (only the task's end sets it), GlobalSuccess but
        after a grasp, RobotInterfered but to one already in it, nor TaskRobot (the authors
        draw from the table without it)."""
        if next_state in ("GlobalFail", "TaskRobot"):
            return False
        if next_state == "GlobalSuccess" and action != self.grasp:
            return False
        if next_state == "RobotInterfered" and state != "RobotInterfered":
            return False
        return True

    def row(self, probabilities: Sequence[float], states: Sequence[str]) -> Sequence[float]:
        """The row as the authors draw from it: without TaskRobot, and every entry equal to
        the row's smallest (their 0.01 floors) folded into its largest (the first, on a tie):
        a row of 0.9 and ten 0.01 becomes "stay"."""
        row = [0.0 if name == "TaskRobot" else float(p) for name, p in zip(states, probabilities)]
        live = [i for i, name in enumerate(states) if name != "TaskRobot"]
        if not live:
            return row
        low = min(row[i] for i in live)
        high = max(row[i] for i in live)
        if high <= low:
            return row
        floors = [i for i in live if row[i] == low]
        top = next(i for i in live if row[i] == high)
        row[top] += sum(row[i] for i in floors)
        for i in floors:
            row[i] = 0.0
        return row


# -- its world ------------------------------------------------------------------------------------
#: FABRIC's world, as facts of the task (docs/tasks_fabric_facts.md, "The task's world", has
#: the files and lines): ``ros_hrc.world.config.task_world_config`` makes the world of them.
WORLD_FACTS: Mapping[str, Any] = {
    # The product is put between the human and the robot (in our scene x = 0, midway between
    # them, in reach of both), on a belt that stands still ...
    "object_start_x": 0.0,
    # ... until the task manager's 1 Hz timer reaches 45 s: then the belt runs, ...
    "belt_start": 45.0,
    # ... for 7 s, which carries the product into the unprocessed tray at the belt's end:
    # the task failed, and nobody can take the product any more.
    "belt_run": 7.0,
    "end_tray": True,
    # The robot plans its motion (4 s) before a grasp or a point, unless graspPlanning did.
    "robot_plan_time": 4.0,
    # Its grasp counts once the product lies in the robot's tray: the gripper closes, then
    # lift 2 s, 0.1 s, turn 2 s, and 0.1 s into the drop the product leaves the gripper. A
    # cancel before that puts the product back where it started.
    "robot_delivery_time": 4.2,
    # The grasp runs on a thread of its own: the call is answered at once, the human goes on
    # (he may warn, and the robot cancel) while the robot plans, reaches and carries.
    "async_actions": ("robot/grasp",),
}


@dataclass(frozen=True)
class TaskWithWorld(Task):
    """A :class:`Task` whose world has facts of its own (``world_facts``, the names of
    ``ros_hrc.world.config.TASK_WORLD_FACTS``; empty: the default world). The field belongs
    on :class:`Task` (issue #30's B owns it; reported): until then fabric is this subclass,
    and readers use ``getattr(task, "world_facts", {})``."""

    world_facts: Mapping[str, Any] = field(default_factory=dict)


FABRIC = TaskWithWorld(
    name="fabric",
    title="FABRIC, the seed authors' successor (cangorur/human_robot_collaboration): a "
          "12-state human who reacts to the robot, an 11-state, 5-action, 12-observation "
          "robot, 5 % observation noise",
    human_states=HUMAN_STATES,
    human_action_services=HUMAN_ACTION_SERVICES,
    human_grasp_action="graspAttempt",
    goal_state="GlobalSuccess",
    robot_states=ROBOT_STATES,
    robot_action_services=ROBOT_ACTION_SERVICES,
    robot_idle_action="idle",
    needs_help_states=NEEDS_HELP_STATES,
    robot_success_state="GlobalSuccess",
    recovery_state="MayNotBeCapable",
    learning_prior="robot_utility_fitted",
    learning_bonus=10.0,
    robot_warned_state="WarningReceived",
    observations=OBSERVATIONS,
    predicate_bits=PREDICATE_BITS,
    raw_bits=snapshot_bits,
    new_tracker=new_tracker,
    new_observation_map=FabricObservationMap,
    reaction=FabricReaction(),
    noise=noisy_bits,
    # The authors' floor: 0.01 on each next state a row of theirs leaves open ("stay": 0.9 on
    # the state left, 0.01 on each other).
    model_floor=0.01,
    default_human_model="beginner_nontired_collaborative",
    default_robot_model="base",
    # The authors' human in Recovery waited while the task's clock ran on (their task ended
    # when the product reached the belt's end): a walk away while away lasts as long as an idle.
    away_time=0.8,
    world_facts=WORLD_FACTS,
    # Its study: the successor authors' three (THRI 2023 §6.1.3), the human alone, the reactive
    # MDP robot and the proactive POMDP robot; an episode ends in the world (the object taken,
    # or in the tray at the belt's end after about 52 simulated seconds), so the step limit
    # is only a safety net; the reactive robot is tuned by its wait (the authors' 15 s).
    study_policies=("pomdp", "reactive", "no_robot"),
    study_step_limit=300,
    reactive_parameter="reactive_wait",
    reactive_robot="mdp",
    model_dirs={"human": MODELS_DIR / "fabric" / "human",
                "robot": MODELS_DIR / "fabric" / "robot"},
    notes=("The human acts in his state (a grasp's outcome drawn first, and shown); after the "
           "robot acted his next state follows the reaction rules.",
           "The robot sees seven bits through the authors' two-step table, with 5 % noise."),
)

#: What :func:`ros_hrc.tasks.get` returns for "fabric".
TASK = FABRIC
