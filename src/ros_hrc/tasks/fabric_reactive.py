"""``fabric``'s reactive robot as data: the authors' observation -> MDP-state rules.

FABRIC's reactive robot (``docs/tasks_fabric_facts.md``, "The reactive robot") is a fully
observable MDP of six states whose state is not seen but *named by rules* from each
observation (the authors' ``MapObservationsToMDP``); it then acts by the MDP's policy
(``models/fabric/robot/reactive.pomdpx``, solved at start-up by
:class:`ros_hrc.agents.robots.ReactiveMdpPlanner`). The rules, in order, for each
observation:

1. ``waited``: the previous state was not HumanNeedsHelp, at least ``wait`` simulated seconds
   have passed since the episode's reset, and no product reached a tray (the observation
   shows neither success nor failure) -> HumanNeedsHelp;
2. ``attempt_failed``: the previous state was not HumanNeedsHelp, the "human attempted" flag
   is set (a grasp attempt was seen at an earlier step) and no product reached a tray ->
   HumanNeedsHelp, and the flag is cleared;
3. by the observation (:data:`BY_OBSERVATION`): not detected (O0) -> HumanNeedsHelp
   (TaskRobot after TaskRobot); detected, looking or idling (O2, O3, O34, O35) -> the previous
   state; a grasp attempt (O6, O7) -> TaskHuman, and the flag is set; success (O8, O40) ->
   GlobalSuccess; idle and not detected (O32) -> HumanNeedsHelp; a warning (O16) ->
   WarningReceived; failure (O64) -> GlobalFail.

Time is the world's simulated seconds since the episode's reset (the authors counted wall
seconds with a 1 Hz timer from the task's start; our world runs as fast as it can, so only
its own clock means the same in every run). An unknown time (a planner not told it) never
satisfies rule 1; a wait of 0 switches rule 1 off. No ROS, no numpy: data and one small class.
"""
from __future__ import annotations

from typing import Dict, Optional, Tuple

from ros_hrc.tasks.fabric import FAILURE, OBSERVATIONS, SUCCESS

__all__ = ["MDP_STATES", "START_STATE", "NEEDS_HELP", "DEFAULT_WAIT", "REACTIVE_MDP_MODEL",
           "BY_OBSERVATION", "PREVIOUS", "ReactiveStateMap"]

#: The reactive MDP's states, in the model's order.
MDP_STATES: Tuple[str, ...] = ("TaskHuman", "GlobalSuccess", "HumanNeedsHelp",
                               "WarningReceived", "TaskRobot", "GlobalFail")
#: The state after a reset (the task is the human's; TaskRobot when the robot's).
START_STATE = "TaskHuman"
NEEDS_HELP = "HumanNeedsHelp"
#: Simulated seconds after which a human without success is helped (the authors' 15 s).
DEFAULT_WAIT = 15.0
#: The reactive MDP, a model name in the task's robot folder (models/fabric/robot/).
REACTIVE_MDP_MODEL = "reactive"

#: Rule 3's "the previous state".
PREVIOUS = ""

#: Rule 3: observation -> (the rule's name, the MDP state; PREVIOUS: the previous state).
#: O0 is "HumanNeedsHelp, but TaskRobot after TaskRobot" (:meth:`ReactiveStateMap.__call__`).
BY_OBSERVATION: Dict[str, Tuple[str, str]] = {
    "O0": ("not_detected", NEEDS_HELP),
    "O2": ("no_change", PREVIOUS),
    "O3": ("no_change", PREVIOUS),
    "O6": ("grasp_attempt", "TaskHuman"),
    "O7": ("grasp_attempt", "TaskHuman"),
    "O8": ("success", "GlobalSuccess"),
    "O16": ("warning", "WarningReceived"),
    "O32": ("idle_not_detected", NEEDS_HELP),
    "O34": ("no_change", PREVIOUS),
    "O35": ("no_change", PREVIOUS),
    "O40": ("success", "GlobalSuccess"),
    "O64": ("failure", "GlobalFail"),
}

#: Observations that show a product in a tray: the object held (success) or off the belt.
_TRAY = frozenset(name for name in OBSERVATIONS.names
                  if OBSERVATIONS.pattern_of(name) & (SUCCESS | FAILURE))


class ReactiveStateMap:
    """One episode's observation -> MDP state (the module docstring's rules, in order).

    ``wait``: simulated seconds for rule 1 (0 switches rule 1 off, as ``reactive_budget:=0``
    does the seed's). ``state`` is the latest state, ``attempted`` the flag, ``rule`` the rule
    that named the state."""

    def __init__(self, wait: float = DEFAULT_WAIT, start: str = START_STATE) -> None:
        if isinstance(wait, bool) or not isinstance(wait, (int, float)) or not 0 <= wait < \
                float("inf"):
            raise ValueError(f"reactive wait must be a finite number of seconds >= 0, "
                             f"not {wait!r}")
        self.wait = float(wait)
        self.reset(start)

    def reset(self, start: str = START_STATE) -> None:
        """A new episode: the start state, the flag cleared (time restarts with the episode)."""
        if start not in MDP_STATES:
            raise ValueError(f"unknown reactive MDP state {start!r}; its states: "
                             f"{', '.join(MDP_STATES)}")
        self.state = start
        self.attempted = False
        self.rule = "start"

    def __call__(self, observation: str, elapsed: Optional[float] = None) -> Tuple[str, str]:
        """The MDP state after ``observation``, seen ``elapsed`` simulated seconds after the
        episode's reset (None: unknown), and the rule that named it."""
        try:
            named_rule, named_state = BY_OBSERVATION[observation]
        except KeyError:
            raise ValueError(f"unknown observation {observation!r}; the reactive robot reads "
                             f"{', '.join(BY_OBSERVATION)}") from None
        previous = self.state
        in_tray = observation in _TRAY
        if (previous != NEEDS_HELP and self.wait > 0 and elapsed is not None
                and elapsed >= self.wait and not in_tray):
            state, rule = NEEDS_HELP, "waited"
        elif previous != NEEDS_HELP and self.attempted and not in_tray:
            self.attempted = False
            state, rule = NEEDS_HELP, "attempt_failed"
        else:
            rule = named_rule
            if named_state == PREVIOUS:
                state = previous
            elif observation == "O0" and previous == "TaskRobot":
                state = "TaskRobot"
            else:
                state = named_state
            if rule == "grasp_attempt":
                self.attempted = True
        self.state, self.rule = state, rule
        return state, rule
