"""What a collaboration task is, as data (DESIGN §13): the one structure the loop reads.

A :class:`Task` holds everything the loop knows of the task it runs, and nothing outside it
knows the task by name:

* the human: his states (in the order manual mode numbers them) and actions, and which
  world service (``/human/<service>``) carries out each action;
* the robot: its model's states, actions and observations, and which ``/robot/<service>``
  carries out each action (``None``: it stays idle and keeps observing);
* the world's bits -> the robot's observation (:class:`Observations`; per episode a map,
  :meth:`Task.observation_map`, which may remember the episode's previous observation), from
  one snapshot (:attr:`Task.raw_bits`), with the task's observation noise (:attr:`Task.noise`);
* the robot model's true state, labelled from the human's state and its history
  (:attr:`Task.new_tracker`, given the human model's name; reported and scored, never shown
  to the robot);
* success and failure: the human's goal state (``end_on_goal``) and the states in which
  the human "needs help" (for scoring intrusions);
* the human's reaction to the robot (:class:`ReactionRules`; ``None``: he does not react);
* the models shipped for it (the defaults of ``human_model`` and ``robot_model``, and the
  folders where a scenario name is looked up).

The tasks shipped are in :mod:`ros_hrc.tasks` (``seed``, ``fabric``); ``docs/tasks.md``
says where a third goes. No ROS, no sockets, no PyBullet: data and small pure functions.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import (Any, Callable, Dict, FrozenSet, Iterable, Mapping, Optional, Protocol,
                    Sequence, Tuple)

__all__ = ["Task", "Observations", "ObservationMap", "NearestObservation", "Tracker",
           "Reaction", "ReactionRules", "Draw", "Noise"]


class Tracker(Protocol):
    """Labels the robot model's true state from the human's state and its history."""

    label: str

    def reset(self) -> None:
        """A new episode: no history."""

    def update(self, human_state: str, human_action: Optional[str] = None) -> str:
        """Account for the human's state (reached by ``human_action``; None: not known) and
        return the robot's true state."""

    # Optional: ``begin_episode(rng)``, called at each episode's start with the episode's
    # "observation" stream (:mod:`ros_hrc.streams`), before any noise is drawn from it,
    # for what the labels take as given per episode (fabric: does this human trust the robot).


#: ``draw(state, action)``: a next state drawn from the human model's row T(. | state,
#: action), restricted to the states the task's rules allow (the agent provides it: it holds
#: the model and the human's random stream).
Draw = Callable[[str, str], str]

#: ``noise(bits, rng) -> (bits, what)``: the bits the robot sees instead of the true ones,
#: and what the noise did ("" when nothing). It draws a fixed number of numbers per call, so
#: a stream stays aligned whatever the bits were.
Noise = Callable[[int, Any], Tuple[int, str]]


@dataclass(frozen=True)
class Reaction:
    """The human's next state after the robot acted, and the rule that chose it."""

    state: str
    rule: str
    #: What the rule says, for the MDP's terminal (e.g. "the robot grasped: interfered").
    text: str = ""


class ReactionRules(Protocol):
    """How a human who hears the robot chooses his next state (the task's rules, in order).

    One step of a reacting human: he acts in his state; the step shows
    :meth:`acting_state` with his action (a grasp's outcome is drawn before the robot acts);
    after the robot acted (and the step may have ended the task), :meth:`next_state` gives
    the state of his next step."""

    def acting_state(self, state: str, action: str, draw: Draw) -> str:
        """The state the step shows with ``action`` taken in ``state``."""

    def next_state(self, acting: str, action: str, robot_action: str, end_reason: str,
                   draw: Draw) -> Reaction:
        """The human's next state: he showed ``acting`` with ``action``, the robot did
        ``robot_action``; ``end_reason`` is the loop's (``success``, ``object_left_belt``,
        ... or "" while the task goes on)."""

    def allowed(self, state: str, action: str, next_state: str) -> bool:
        """Whether a draw from the model's row may give ``next_state`` (the others are
        drawn again, i.e. the row is renormalised over the allowed ones)."""

    def row(self, probabilities: Sequence[float], states: Sequence[str]) -> Sequence[float]:
        """The model's row T(. | state, action) as the draw uses it (over ``states``)."""


class ObservationMap(Protocol):
    """One episode's bits -> observation map: ``map(raw)`` is (the bit pattern the robot's
    observation stands for, the observation's name)."""

    def __call__(self, raw: int) -> Tuple[int, str]:
        ...


class Observations:
    """The bits -> observation map of a task.

    Each observation of the robot model is one or more bit patterns (``patterns``: name ->
    patterns, in the model's order). A pattern that is none of them maps to the nearest
    listed one: fewest differing bits; among equally near ones, the one that agrees on the
    most important bit first (``priority``, most important first), then the smaller.
    ``bit_names``: (bit, name) of every bit, for describing a pattern. ``max_bits``: the
    largest pattern the world can give (larger ones are refused)."""

    def __init__(self, patterns: Sequence[Tuple[str, Iterable[int]]],
                 bit_names: Sequence[Tuple[int, str]], priority: Sequence[int],
                 max_bits: int) -> None:
        self.names: Tuple[str, ...] = tuple(name for name, _ in patterns)
        self.bit_names: Tuple[Tuple[int, str], ...] = tuple(bit_names)
        self.priority: Tuple[int, ...] = tuple(priority)
        self.max_bits = int(max_bits)
        self._name_of: Dict[int, str] = {}
        self._first: Dict[str, int] = {}
        for name, bits in patterns:
            bits = list(bits)
            if not bits:
                raise ValueError(f"observation {name} has no bit pattern")
            self._first[name] = bits[0]
            for b in bits:
                if b in self._name_of:
                    raise ValueError(f"bit pattern {b} is both {self._name_of[b]} and {name}")
                if not 0 <= b <= self.max_bits:
                    raise ValueError(f"bit pattern {b} of {name} outside 0..{self.max_bits}")
                self._name_of[b] = name
        if len(set(self.names)) != len(self.names):
            raise ValueError("observation names must differ")
        #: Every listed pattern, smallest first.
        self.patterns: Tuple[int, ...] = tuple(sorted(self._name_of))

    def nearest(self, bits: int) -> int:
        """The listed pattern nearest to ``bits`` (``bits`` itself when listed)."""
        if not 0 <= bits <= self.max_bits:
            raise ValueError(f"observation bits {bits} outside 0..{self.max_bits}")
        if bits in self._name_of:
            return bits

        def rank(candidate: int):
            agreement = tuple(0 if (candidate & b) == (bits & b) else 1 for b in self.priority)
            return (bin(candidate ^ bits).count("1"), agreement, candidate)

        return min(self.patterns, key=rank)

    def name_of(self, pattern: int) -> str:
        """The observation a listed pattern is."""
        try:
            return self._name_of[pattern]
        except KeyError:
            raise ValueError(f"{pattern} is not a bit pattern of the robot model's "
                             f"observations {self.patterns}") from None

    def pattern_of(self, name: str) -> int:
        """The first listed pattern of an observation (what it typically shows)."""
        try:
            return self._first[name]
        except KeyError:
            raise ValueError(f"unknown observation {name!r}; the task's are "
                             f"{', '.join(self.names)}") from None

    def describe(self, bits: int) -> str:
        """Human-readable list of the bits set, e.g. ``visible+in_range+idle``."""
        return "+".join(n for b, n in self.bit_names if bits & b) or "nothing"


class NearestObservation:
    """The stateless map: raw bits -> the nearest listed pattern and its observation."""

    def __init__(self, observations: Observations) -> None:
        self.observations = observations

    def __call__(self, raw: int) -> Tuple[int, str]:
        pattern = self.observations.nearest(raw)
        return pattern, self.observations.name_of(pattern)


#: The world facts (``ros_hrc.world.config.TASK_WORLD_FACTS``) that are simulated seconds a
#: robot action spends besides moving: :attr:`Task.robot_action_seconds`.
ROBOT_TIME_FACTS = ("robot_plan_time", "robot_delivery_time")


@dataclass(frozen=True)
class Task:
    """One collaboration task: see the module docstring for what each part is."""

    name: str
    #: One line: what the task is and where it comes from (credit).
    title: str
    # -- the human
    human_states: Tuple[str, ...]
    #: Human action -> its /human/<service> (None: nothing to call).
    human_action_services: Mapping[str, Optional[str]]
    #: The human's grasp, and the state whose grasp takes the object (``/human/grasp``
    #: instead of the action's service).
    human_grasp_action: str
    goal_state: str
    # -- the robot
    robot_states: Tuple[str, ...]
    #: Robot action -> its /robot/<service> (None: it stays idle and keeps observing).
    robot_action_services: Mapping[str, Optional[str]]
    #: The robot's action before its first decision, and the no-robot baseline's only one.
    robot_idle_action: str
    #: Robot states in which the human needs (or may need) help: scores intrusive actions.
    needs_help_states: FrozenSet[str]
    # -- observing
    observations: Observations
    #: Predicate services of the world (``is_ov`` ...) -> the bit each sets.
    predicate_bits: Mapping[str, int]
    #: The raw bits of one world snapshot (``.predicates``, ``.holder``, ``.left_belt``).
    raw_bits: Callable[[Any], int]
    #: A new labeller of the robot's true state for a human model (its name or path; one
    #: per loop, reset per episode).
    new_tracker: Callable[[str], Tracker]
    #: A new episode's bits -> observation map (None: :class:`NearestObservation`).
    new_observation_map: Optional[Callable[[Observations], ObservationMap]] = None
    # -- the human's reaction and the robot's noise
    reaction: Optional[ReactionRules] = None
    noise: Optional[Noise] = None
    # -- the models shipped for it
    default_human_model: str = ""
    default_robot_model: str = ""
    #: The world's away_time for this task (hrc.launch away_time:=auto): how long a walk away
    #: lasts when the human is already away (0: no time).
    away_time: float = 0.0
    #: The robot state that labels a success (someone holds the object): where hrc_fit ends a
    #: successful episode's last transition.
    robot_success_state: str = ""
    #: The robot state of a human who has just failed once and may recover alone (the seed's
    #: S2): where a learning robot's figure starts (``recovery_steps`` steps of the idle
    #: action to the success state; docs/learning.md). "" for none.
    recovery_state: str = ""
    recovery_steps: int = 3
    #: The robot model the learning robot's study starts from (its prior: a pooled fit priced
    #: by the task's utility, ``hrc_fit --rewards utility``); "" for none yet.
    learning_prior: str = ""
    #: The learning robot's exploration bonus on this task (``learning_bonus:=auto``), chosen
    #: on streams it is not judged on (docs/learning.md): the seed's on its fit set, fabric's
    #: on its ten types' tuning seed.
    learning_bonus: float = 0.0
    #: The robot state of a human who warned the robot: acting in it is acting against a
    #: warning, which a model of the task's utility prices (ros_hrc.tasks.utility.
    #: utility_rewards). "" for none.
    robot_warned_state: str = ""
    # -- its study (hrc_experiment --task): what a grid runs when not told otherwise
    #: The robot policies of its study (empty: the experiment's default, the seed's).
    study_policies: Tuple[str, ...] = ()
    #: Steps before an episode ends (a task whose episodes end in the world: a safety net).
    study_step_limit: int = 15
    #: The hrc.launch argument a ``reactive@N`` policy sets to N: how its reactive robot is
    #: tuned (the seed's helps after N observations).
    reactive_parameter: str = "reactive_budget"
    #: The kind of the task's reactive robot (``planner:=reactive``), built by
    #: :func:`ros_hrc.agents.robots.reactive_planner`: "rules" (the seed's rules on the
    #: observation's bits, tuned by reactive_budget), "mdp" (the successor's reactive MDP, its
    #: observations mapped by the task's rules, tuned by reactive_wait); "" for none.
    reactive_robot: str = ""
    #: Where a scenario name is looked up, by kind ("human", "robot").
    model_dirs: Mapping[str, Path] = field(default_factory=dict)
    #: A longer description of the rules (docs and ``hrc_check --task NAME``).
    notes: Tuple[str, ...] = ()
    #: A task of a sequence (``tasks:=N``) still running after this many simulated seconds
    #: since its start ends with outcome ``timeout`` (``task_timeout:=auto``). 80 s is
    #: FABRIC's: their task manager's 1 Hz timer forces the task's reset at 80 s
    #: (cangorur/human_robot_collaboration, TaskManager.cpp, L634-737).
    task_timeout: float = 80.0
    #: The human's action that warns the robot: a sequence's task counts them (its outcome's
    #: ``warnings``).
    human_warning_action: str = "warnRobot"
    #: The probability the task's model files give each next state a row leaves open but does
    #: not mean (FABRIC's: the authors' 0.01, which its human's draw folds into the row's
    #: largest entry, ``FabricReaction.row``; ``tools/make_fabric_models.py`` writes it). A
    #: perturbed human (``hrc_perturb_humans``) keeps these entries as they are. 0: none (the
    #: seed's rows hold only what they mean).
    model_floor: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.model_floor < 1.0:
            raise ValueError(f"task {self.name}: model_floor must be in [0, 1)")
        if not self.task_timeout > 0:
            raise ValueError(f"task {self.name}: task_timeout must be > 0")
        if not 0.0 <= self.learning_bonus < float("inf"):
            raise ValueError(f"task {self.name}: learning_bonus must be a finite number >= 0")
        if self.human_warning_action not in self.human_action_services:
            raise ValueError(f"task {self.name}: warning {self.human_warning_action} is not a "
                             "human action")
        for name in self.needs_help_states:
            if name not in self.robot_states:
                raise ValueError(f"task {self.name}: needs-help state {name} is not a robot state")
        if self.goal_state not in self.human_states:
            raise ValueError(f"task {self.name}: goal {self.goal_state} is not a human state")
        if self.human_grasp_action not in self.human_action_services:
            raise ValueError(f"task {self.name}: grasp {self.human_grasp_action} is not a "
                             "human action")
        if self.robot_success_state and self.robot_success_state not in self.robot_states:
            raise ValueError(f"task {self.name}: success {self.robot_success_state} is not a "
                             "robot state")
        for label, name, names in (("recovery", self.recovery_state, self.robot_states),
                                   ("warned", self.robot_warned_state, self.robot_states)):
            if name and name not in names:
                raise ValueError(f"task {self.name}: {label} {name} is not one of its robot's")
        if self.robot_idle_action not in self.robot_action_services:
            raise ValueError(f"task {self.name}: idle {self.robot_idle_action} is not a "
                             "robot action")

    # -- the human ------------------------------------------------------------------------------
    @property
    def human_actions(self) -> Tuple[str, ...]:
        return tuple(self.human_action_services)

    @property
    def reacts(self) -> bool:
        """Whether the human chooses his next state after the robot acted."""
        return self.reaction is not None

    def human_service_for(self, action: str, state: str) -> Optional[str]:
        """The /human/* service that carries out the human's ``action`` shown with ``state``
        (a grasp whose state is the goal takes the object: ``grasp``)."""
        if action not in self.human_action_services:
            raise ValueError(f"unknown human action {action!r}; known: "
                             f"{', '.join(self.human_action_services)}")
        if action == self.human_grasp_action and state == self.goal_state:
            return "grasp"
        return self.human_action_services[action]

    def human_world_services(self) -> Tuple[str, ...]:
        """Every /human/* service the human's actions may call, sorted."""
        return tuple(sorted({s for s in self.human_action_services.values() if s} | {"grasp"}))

    # -- the robot ------------------------------------------------------------------------------
    @property
    def robot_actions(self) -> Tuple[str, ...]:
        return tuple(self.robot_action_services)

    @property
    def robot_action_seconds(self) -> float:
        """The simulated seconds a robot action of this task's world takes beyond its motion:
        the facts of its world (``world_facts``, a task with a world of its own) that are
        times the robot spends, :data:`ROBOT_TIME_FACTS` (FABRIC's robot plans 4 s before a
        grasp and carries the object 4.2 s to its tray: 8.2 s; the seed's robot, 0)."""
        facts = getattr(self, "world_facts", {})
        return float(sum(facts.get(name, 0.0) for name in ROBOT_TIME_FACTS))

    def robot_world_services(self) -> Tuple[str, ...]:
        """Every /robot/* service the robot's actions may call, sorted."""
        return tuple(sorted({s for s in self.robot_action_services.values() if s}))

    def robot_actions_calling(self, *services: str) -> FrozenSet[str]:
        """The robot's actions carried by any of these /robot/* services (e.g. ``"grasp"``:
        the seed's rGrasp_obj, fabric's grasp): how task-agnostic code names an action."""
        return frozenset(a for a, s in self.robot_action_services.items() if s in services)

    @property
    def helping_actions(self) -> FrozenSet[str]:
        """The robot's actions that take the task over or show the way (its grasp and its
        point): the ones that intrude on a human who needs no help."""
        return self.robot_actions_calling("grasp", "point_to_obj")

    def warning_in_force(self, in_force: bool, bits: int) -> bool:
        """Whether a warning is in force after an observation of ``bits``, given whether one
        was before: from the observation that carries the warning bit (the robot decides
        after it, so its action then counts) until the robot sees the human act on the object
        again (a grasp attempt, or holding it). Idling, looking round or walking away do not
        lift it: the human said "stop" and has not taken the task back. A reset lifts it."""
        if bits & self.bit("warning"):
            return True
        if bits & (self.bit("grasp_attempt") | self.bit("has_object", "object_taken")):
            return False
        return in_force

    def bit(self, *names: str) -> int:
        """The observation bit of the first of ``names`` the task has (e.g. ``"has_object"``
        or fabric's ``"object_taken"``); ValueError when it has none of them."""
        by_name = {name: bit for bit, name in self.observations.bit_names}
        for name in names:
            if name in by_name:
                return by_name[name]
        raise ValueError(f"task {self.name} has no observation bit {' or '.join(names)}")

    # -- observing ------------------------------------------------------------------------------
    def observation_map(self) -> ObservationMap:
        """A fresh bits -> observation map, for one episode."""
        make = self.new_observation_map or NearestObservation
        return make(self.observations)

    def predicates_text(self, predicates: Mapping[str, bool]) -> str:
        """The predicates as the step block prints them, e.g. ``ov=1 oir=1 a0=0 ...``."""
        return " ".join(f"{name[3:]}={int(bool(predicates.get(name)))}"
                        for name in self.predicate_bits)

    def describe_bits(self, bits: int) -> str:
        return self.observations.describe(bits)

    # -- model names ----------------------------------------------------------------------------
    def names(self, kind: str) -> Dict[str, Tuple[str, ...]]:
        """The names, in the task's order, of each list a ``kind`` ("human" or "robot")
        model must name: states and actions (and observations for the robot)."""
        if kind == "human":
            return {"states": self.human_states, "actions": self.human_actions}
        if kind == "robot":
            return {"states": self.robot_states, "actions": self.robot_actions,
                    "observations": self.observations.names}
        raise ValueError(f"unknown model kind {kind!r}: expected human or robot")

    def default_model(self, kind: str) -> str:
        return {"human": self.default_human_model, "robot": self.default_robot_model}[kind]
