"""Baseline robots that the robot process can run instead of the POMDP planner.

Both keep the exact Bayesian belief over the robot model's states (they are ``BeliefPlanner``
subclasses, updated like any planner), so experiments can plot every robot's belief that the
human needs help; only their *decisions* ignore that belief.

``ReactivePlanner``
    Treats the human's need for help as directly observable in the current observation and
    decides deterministically, by the first rule that applies (bits of :mod:`ros_hrc.tasks.seed`):

    1. ``warning``     WARNING (16) set                          -> rStop_all
    2. ``has_object``  HAS_OBJECT (8) set                        -> rIdle
    3. ``failed_grasp`` GRASP_ATTEMPT (4) set                    -> help
       (rule 2 has already excluded HAS_OBJECT: an attempt without the object has failed)
    4. ``not_detected`` neither VISIBLE (1) nor IN_RANGE (2)     -> help
    5. ``not_attending`` IN_RANGE (2) set but VISIBLE (1) clear  -> help
       (the object is within the human's reach and the human does not see it)
    6. ``budget``      ``budget`` > 0 observations since the last reset, the latest one
                       included, and none of them showed HAS_OBJECT -> help
    7. ``nothing``     otherwise                                 -> rIdle

    "help" is one fixed action, ``rGrasp_obj`` by default (``ReactiveConfig.help_action``): the
    reactive robot takes the object over; telling *which* help the human needs (point or fetch)
    is what the POMDP adds. Because rule 1 comes first the robot never helps while a warning
    holds. Before the first observation it idles (rule ``start``).

``ReactiveMdpPlanner``
    The ``fabric`` task's reactive robot, the seed authors' successor's: each observation
    names a state of their 6-state reactive MDP by the rules of
    :mod:`ros_hrc.tasks.fabric_reactive` (in order: ``waited`` -- ``wait`` simulated seconds
    since the episode's reset without success; ``attempt_failed`` -- a grasp attempt seen
    before, still no success; then by the observation), and the robot acts by that MDP's
    optimal policy (``models/fabric/robot/reactive.pomdpx``, value iteration at start-up:
    TaskHuman idle, HumanNeedsHelp grasp, WarningReceived cancel, TaskRobot grasp). The time
    comes with each observation (``observe_time``: the protocol's ``Observation.elapsed``).

Which reactive robot ``planner:=reactive`` is depends on the task's ``reactive_robot``
(:data:`REACTIVE_ROBOTS`).

``NoRobotPlanner``
    Always ``rIdle``: the human works alone.

``ExplorePlanner``
    A uniformly random action of the model at every step, from its own seeded stream (restarted
    by ``reseed``, at each episode's reset in the robot process): the
    exploring robot whose experience ``hrc_fit`` counts, so that every action is tried in every
    state the human reaches.

Actions and observations are looked up by name in the loaded model; a model that lacks one
the policy needs is refused with a ValueError naming it. No ROS, no PyBullet.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, Mapping, Optional, Tuple

import numpy as np

from ros_hrc import settings
from ros_hrc.tasks import seed as task
from ros_hrc.model_files import resolve_model
from ros_hrc.pomdp.io import load_model
from ros_hrc.pomdp.mdp import value_iteration
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.planner import BeliefPlanner, PlannerStats
from ros_hrc.tasks import fabric_reactive
from ros_hrc.tasks.definition import Task

IDLE_ACTION = "rIdle"
STOP_ACTION = "rStop_all"
DEFAULT_HELP_ACTION = "rGrasp_obj"
DEFAULT_REACTIVE_BUDGET: int = settings.default("reactive_budget")


@dataclass
class ReactiveConfig:
    """The reactive robot's parameters.

    ``budget``: observations since the last reset after which a human who has not yet got the
    object is helped (rule 6); 0 switches the rule off. ``help_action``: the model's action the
    reactive robot helps with.
    """

    budget: int = DEFAULT_REACTIVE_BUDGET
    help_action: str = DEFAULT_HELP_ACTION

    def __post_init__(self) -> None:
        if isinstance(self.budget, bool) or not isinstance(self.budget, int) or self.budget < 0:
            raise ValueError(f"reactive budget must be a whole number of steps >= 0, "
                             f"not {self.budget!r}")


@dataclass
class NoRobotConfig:
    """The no-robot baseline's one parameter: the model's name for doing nothing."""

    idle_action: str = IDLE_ACTION


def _action_indices(model: Model, names: Iterable[str], who: str) -> Dict[str, int]:
    """Model index of each action name; ValueError naming every missing one."""
    names = list(dict.fromkeys(names))
    missing = [n for n in names if n not in model.actions]
    if missing:
        raise ValueError(f"{who} needs action(s) {', '.join(missing)}, which model "
                         f"{model.name or model.source or '?'} lacks (its actions: "
                         f"{', '.join(model.actions)})")
    return {n: model.index("action", n) for n in names}


def _observation_bits(model: Model, who: str) -> np.ndarray:
    """Bit sum of each of the model's observations, indexed like ``model.observations``.

    The policy reads every observation, so the model must hold exactly the task's legal
    observations (named by ``task.observation_name``); ValueError names any it lacks or any
    it has that the task does not define.
    """
    bits_by_name = {task.observation_name(b): b for b in task.LEGAL_BITS}
    where = model.name or model.source or "?"
    missing = [n for n in bits_by_name if n not in model.observations]
    if missing:
        raise ValueError(f"{who} needs observation(s) {', '.join(missing)}, which model "
                         f"{where} lacks (its observations: {', '.join(model.observations)})")
    unknown = [n for n in model.observations if n not in bits_by_name]
    if unknown:
        raise ValueError(f"{who} cannot read observation(s) {', '.join(unknown)} of model "
                         f"{where}: the task defines only {', '.join(bits_by_name)}")
    return np.array([bits_by_name[n] for n in model.observations], dtype=int)


class ReactiveRobot(BeliefPlanner):
    """``planner:=reactive``: the task's reactive robot (:func:`reactive_planner`), the seed's
    rules (:class:`ReactivePlanner`, ``reactive_budget``) or fabric's reactive MDP
    (:class:`ReactiveMdpPlanner`, ``reactive_wait``), both of this kind."""

    @classmethod
    def settings_used(cls, task_: Any) -> Tuple[str, ...]:
        return (task_.reactive_parameter,) if task_.reactive_robot else ()

    @classmethod
    def from_settings(cls, model: Model, task_: Any, values: Mapping[str, Any]
                      ) -> "ReactiveRobot":
        return reactive_planner(task_, model, budget=values["reactive_budget"],
                                wait=values["reactive_wait"], seed=values.get("seed"))

    @classmethod
    def acts_by(cls, task_: Any) -> Optional[str]:
        return reactive_robot_model(task_) or None


class ReactivePlanner(ReactiveRobot):
    """Rule-based robot on the current observation; keeps the exact belief (module docstring).

    ``last_rule`` names the rule behind the latest ``act()``; ``steps`` counts observations
    since the last reset and ``human_succeeded`` says whether one of them showed HAS_OBJECT.
    """

    def __init__(self, model: Model, config: Optional[ReactiveConfig] = None,
                 seed: Optional[int] = None) -> None:
        self.config = config if config is not None else ReactiveConfig()
        who = "the reactive robot"
        self._actions = _action_indices(
            model, (IDLE_ACTION, STOP_ACTION, self.config.help_action), who)
        self._bits = _observation_bits(model, who)
        super().__init__(model, seed)  # exact belief: particles stay None
        self.reset()

    def reset(self, belief: Optional[np.ndarray] = None) -> None:
        super().reset(belief)
        self.steps = 0
        self.human_succeeded = False
        self.last_bits: Optional[int] = None
        self.last_rule = "start"

    def update(self, action: int, observation: int) -> None:
        super().update(action, observation)
        bits = int(self._bits[observation])
        self.steps += 1
        self.last_bits = bits
        # Success is remembered: the budget is for a human who has never had the object.
        self.human_succeeded = self.human_succeeded or bool(bits & task.HAS_OBJECT)

    def rule(self) -> str:
        """Which rule applies to the latest observation (names as in the module docstring)."""
        bits = self.last_bits
        if bits is None:
            return "start"
        if bits & task.WARNING:
            return "warning"
        if bits & task.HAS_OBJECT:
            return "has_object"
        if bits & task.GRASP_ATTEMPT:
            return "failed_grasp"
        if not bits & (task.VISIBLE | task.IN_RANGE):
            return "not_detected"
        if not bits & task.VISIBLE:
            return "not_attending"
        budget = self.config.budget
        if budget and self.steps >= budget and not self.human_succeeded:
            return "budget"
        return "nothing"

    def act(self) -> int:
        self.last_rule = self.rule()
        self.last_stats = PlannerStats()
        if self.last_rule == "warning":
            return self._actions[STOP_ACTION]
        if self.last_rule in ("start", "has_object", "nothing"):
            return self._actions[IDLE_ACTION]
        return self._actions[self.config.help_action]


@dataclass
class ReactiveMdpConfig:
    """FABRIC's reactive robot's parameter: ``wait``, the simulated seconds since the
    episode's reset after which a human without success is helped (rule ``waited``; 0: never
    for that reason)."""

    wait: float = fabric_reactive.DEFAULT_WAIT

    def __post_init__(self) -> None:
        fabric_reactive.ReactiveStateMap(self.wait)    # the one check of a wait


def mdp_policy(mdp: Model) -> Dict[str, str]:
    """The optimal policy of a fully observable MDP, by value iteration: state -> action."""
    solution = value_iteration(mdp)
    return {state: mdp.actions[int(a)] for state, a in zip(mdp.states, solution.policy)}


class ReactiveMdpPlanner(ReactiveRobot):
    """FABRIC's reactive robot (module docstring): the authors' rules name a state of the
    reactive MDP ``mdp`` from each observation, and the robot acts by the MDP's optimal
    policy; the exact belief over ``model``'s states is kept as by any planner.

    ``policy`` (MDP state -> action name) is computed here; ``mdp_state`` is the state the
    latest observation named, ``last_rule`` the rule that named it (``start`` before the first
    observation of an episode), ``elapsed`` the time given with it."""

    def __init__(self, model: Model, mdp: Model, config: Optional[ReactiveMdpConfig] = None,
                 seed: Optional[int] = None) -> None:
        self.config = config if config is not None else ReactiveMdpConfig()
        who = "the reactive MDP robot"
        where = mdp.name or mdp.source or "?"
        if set(mdp.states) != set(fabric_reactive.MDP_STATES):
            raise ValueError(f"{who} needs an MDP over {', '.join(fabric_reactive.MDP_STATES)}; "
                             f"{where} has states {', '.join(mdp.states)}")
        unread = [o for o in model.observations if o not in fabric_reactive.BY_OBSERVATION]
        missing = [o for o in fabric_reactive.BY_OBSERVATION if o not in model.observations]
        if unread or missing:
            raise ValueError(f"{who} reads observations {', '.join(fabric_reactive.BY_OBSERVATION)}"
                             f"; model {model.name or model.source or '?'} has "
                             f"{', '.join(model.observations)}")
        self.mdp = mdp
        self.policy = mdp_policy(mdp)
        self._actions = _action_indices(model, self.policy.values(), who)
        self._states = fabric_reactive.ReactiveStateMap(self.config.wait)
        super().__init__(model, seed)  # exact belief: particles stay None
        self.reset()

    reads_time = True

    def reset(self, belief: Optional[np.ndarray] = None) -> None:
        super().reset(belief)
        self._states.reset()
        self.elapsed: Optional[float] = None
        self.last_rule = "start"

    @property
    def mdp_state(self) -> str:
        return self._states.state

    def observe_time(self, elapsed: Optional[float]) -> None:
        """The simulated seconds since the episode's reset of the next observation (None:
        unknown, and rule ``waited`` cannot apply)."""
        self.elapsed = elapsed

    def update(self, action: int, observation: int) -> None:
        super().update(action, observation)
        self._states(self.model.observations[observation], self.elapsed)

    def act(self) -> int:
        self.last_rule = self._states.rule
        self.last_stats = PlannerStats()
        return self._actions[self.policy[self._states.state]]

    def policy_text(self) -> str:
        """The MDP's policy in one line, e.g. ``the reactive MDP's policy (value iteration):
        TaskHuman: idle, HumanNeedsHelp: grasp, ...``."""
        return "the reactive MDP's policy (value iteration): " + ", ".join(f"{state}: {action}" for state, action in self.policy.items())


def _rules_reactive(task_: Task, model: Model, budget: int, wait: float,
                   seed: Optional[int]) -> ReactiveRobot:
    return ReactivePlanner(model, ReactiveConfig(budget=budget), seed=seed)


def _reactive_mdp_file(task_: Task) -> Path:
    """The file of the reactive MDP the task's ``mdp`` reactive robot acts by."""
    return resolve_model(fabric_reactive.REACTIVE_MDP_MODEL, "robot", task_.model_dirs["robot"])


def _mdp_reactive(task_: Task, model: Model, budget: int, wait: float,
                     seed: Optional[int]) -> ReactiveRobot:
    return ReactiveMdpPlanner(model, load_model(_reactive_mdp_file(task_)),
                              ReactiveMdpConfig(wait=wait), seed=seed)


#: The reactive robots (``planner:=reactive``) by their kind, a task's ``reactive_robot``: the
#: seed's rules on its bits (``reactive_budget``), the successor's reactive MDP
#: (``reactive_wait``). A task of no kind has none (the pre-flight refuses ``planner:=reactive``).
REACTIVE_ROBOTS: Dict[str, Callable[..., ReactiveRobot]] = {
    "rules": _rules_reactive,
    "mdp": _mdp_reactive,
}


def reactive_robot_model(task_: Task) -> str:
    """What the task's reactive robot acts by, where a report names a policy's robot model
    (``/hrc/task_status.robot_model``): the reactive MDP's file (fabric's), else the robot by
    its name and kind (the seed's: ``reactive (rules)``); "" for a task without one."""
    if task_.reactive_robot == "mdp":
        return str(_reactive_mdp_file(task_))
    return f"reactive ({task_.reactive_robot})" if task_.reactive_robot else ""


def reactive_planner(task_: Task, model: Model, budget: int = DEFAULT_REACTIVE_BUDGET,
                     wait: float = fabric_reactive.DEFAULT_WAIT,
                     seed: Optional[int] = None) -> ReactiveRobot:
    """The task's reactive robot over ``model`` (``budget``: the seed's, ``wait``: fabric's);
    ValueError for a task without one."""
    if not task_.reactive_robot:
        raise ValueError(f"task {task_.name} has no reactive robot")
    return REACTIVE_ROBOTS[task_.reactive_robot](task_, model, budget, wait, seed)


class NoRobotPlanner(BeliefPlanner):
    """The robot never acts (always the idle action); keeps the exact belief."""

    @classmethod
    def from_settings(cls, model: Model, task_: Any, values: Mapping[str, Any]
                      ) -> "NoRobotPlanner":
        """Idle at the task's idle action."""
        return cls(model, NoRobotConfig(idle_action=task_.robot_idle_action),
                   seed=values.get("seed"))

    def __init__(self, model: Model, config: Optional[NoRobotConfig] = None,
                 seed: Optional[int] = None) -> None:
        self.config = config if config is not None else NoRobotConfig()
        self._idle = _action_indices(model, (self.config.idle_action,),
                                     "the no-robot baseline")[self.config.idle_action]
        super().__init__(model, seed)

    def act(self) -> int:
        self.last_stats = PlannerStats()
        return self._idle


class ExplorePlanner(BeliefPlanner):
    """A uniformly random action at every step (seeded); keeps the exact belief."""

    def __init__(self, model: Model, seed: Optional[int] = None) -> None:
        super().__init__(model, seed)
        # Its own stream, so the belief's sampling (if any) does not shift the actions.
        self._choices = np.random.default_rng(seed)

    def reseed(self, seed: int) -> None:
        super().reseed(seed)
        self._choices = np.random.default_rng(seed)

    def act(self) -> int:
        self.last_stats = PlannerStats()
        return int(self._choices.integers(self.model.n_actions))
