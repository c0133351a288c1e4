"""What a person watching the collaboration is shown of each step, in words and bars (no ROS).

One source for the PyBullet window's overlay and RViz's markers: :func:`status_lines` turns a
step (anything with the fields of ``ros_hrc/Status``) into a few short lines, and
:func:`belief_bars` into the robot's belief per state with the true state marked. The task a
step belongs to (:mod:`ros_hrc.tasks`: whose bits, which states need help) is the one whose
robot states the step's belief is over (the seed's when none is).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

from ros_hrc import tasks
from ros_hrc.command_line import counted
from ros_hrc.pomdp.type_names import ranked_types
from ros_hrc.tasks.definition import Task


@dataclass(frozen=True)
class BeliefBar:
    """One state's bar: its name, the robot's belief in it, and whether it is the true state."""
    state: str
    probability: float
    true_state: bool
    needs_help: bool


def task_of(belief_states: Sequence[str]) -> Task:
    """The task whose robot states ``belief_states`` are (the default task's otherwise)."""
    return tasks.of_robot_states(belief_states)


def needs_help_probability(belief_states: Sequence[str], belief: Sequence[float]) -> float:
    """The robot's belief that the human needs help (the seed's: the mass on S2..S5)."""
    helped = task_of(belief_states).needs_help_states
    return float(sum(p for s, p in zip(belief_states, belief) if s in helped))


def holder_text(holder: str) -> str:
    return {"human": "the human holds the object", "robot": "the robot holds the object"}.get(
        holder, "nobody holds the object")


def ranked_action_values(status) -> List[Tuple[str, float]]:
    """The robot planner's value of each action it compared in a step (``action_names``,
    ``action_values``), best first, ties in the model's order; empty for a baseline robot."""
    pairs = list(zip(getattr(status, "action_names", ()), getattr(status, "action_values", ())))
    order = sorted(range(len(pairs)), key=lambda i: (-pairs[i][1], i))
    return [(pairs[i][0], float(pairs[i][1])) for i in order]


def value_text(value: float) -> str:
    """An action's value in four significant digits, to four decimals at most (``12.35``,
    ``-64.1``, ``0``): a planner's numerical slack (DESPOT's few 1e-7) reads as 0."""
    rounded = round(value, 4)
    return f"{rounded:.4g}" if rounded != 0 else "0"


def chosen_value_text(status) -> str:
    """The chosen action's value and the next best action's, short, for the caption's robot
    line (``value 12.35 vs rIdle 11.9``); "" when the planner sent no values."""
    ranked = ranked_action_values(status)
    chosen = [value for name, value in ranked if name == status.robot_action]
    if not chosen:
        return ""
    others = [(name, value) for name, value in ranked if name != status.robot_action]
    text = f"value {value_text(chosen[0])}"
    return text + (f" vs {others[0][0]} {value_text(others[0][1])}" if others else "")


def action_values_text(status, width: int = 80) -> str:
    """Every action the planner valued, best first, the chosen one marked, in at most about
    ``width`` characters (those that do not fit are counted at the end), e.g.
    ``rGrasp_obj 12.35 (chosen) > rIdle 11.9 > rPoint_obj 4.1 (+2 more)``; "" without values."""
    ranked = ranked_action_values(status)
    text = ""
    for i, (name, value) in enumerate(ranked):
        item = f"{name} {value_text(value)}" + (" (chosen)" if name == status.robot_action else "")
        if i:
            same = value_text(value) == value_text(ranked[i - 1][1])
            item = (" = " if same else " > ") + item
        rest = len(ranked) - i - 1
        more = f" (+{rest} more)" if rest else ""
        if i and len(text) + len(item) + len(more) > width:
            return text + f" (+{len(ranked) - i} more)"
        text += item
    return text


#: The step block's label column ("robot belief      : "): what a line's text has left of a
#: terminal's 80 columns.
BELIEF_LINE_WIDTH = 80 - len("robot belief      : ")


def belief_text(belief_states: Sequence[str], belief: Sequence[float],
                width: int = BELIEF_LINE_WIDTH) -> str:
    """The robot's belief over its model's states in at most ``width`` characters, for the
    step block: every state in the model's order when they all fit (a model of 5 states),
    else the most likely first (ties in the model's order), as many as fit, and the rest
    summed, e.g. ``NeedsHelp 0.612 | MayBeTired 0.201 | +9 others 0.187`` (fabric's eleven);
    states that would show as 0.000 are only summed. "" without a belief."""
    items = [f"{name} {p:.3f}" for name, p in zip(belief_states, belief)]
    whole = " | ".join(items)
    if len(whole) <= width:
        return whole
    order = sorted(range(len(items)), key=lambda i: (-belief[i], i))
    shown: List[int] = []
    for i in order:
        if f"{belief[i]:.3f}" == "0.000":
            break
        rest = len(order) - len(shown) - 1
        tail = f" | +{rest} others 0.000" if rest else ""    # the widest a tail can be
        if shown and len(" | ".join(items[j] for j in shown + [i]) + tail) > width:
            break
        shown.append(i)
    rest = [i for i in order if i not in shown]
    text = " | ".join(items[i] for i in shown)
    if rest:
        others = f"+{len(rest)} {'other' if len(rest) == 1 else 'others'}"
        text += f"{' | ' if text else ''}{others} {sum(belief[i] for i in rest):.3f}"
    return text


def status_lines(status) -> List[str]:
    """The step in four lines: which step, what the human did and is, what the robot saw and
    did (with the planner's value of its action and of the next best one, when it sent
    values), and what it believes; e.g. ::

        episode 2, step 3
        human: graspAttempt -> failed_to_grasp
        robot: sees O7 (...), does rGrasp_obj (value 12.35 vs rIdle 11.9; true state S2)
        P(human needs help) = 0.87; nobody holds the object
    """
    bits = int(getattr(status, "observation_bits", 0))
    task = task_of(getattr(status, "belief_states", ()))
    why = chosen_value_text(status)
    lines = [f"episode {getattr(status, 'episode', 0)}, step {status.step}",
             f"human: {status.human_action or '-'} -> {status.human_state or '-'}",
             f"robot: sees {status.robot_observation or '-'} ({task.describe_bits(bits)}), "
             f"does {status.robot_action or '-'} ({why + '; ' if why else ''}true state "
             f"{status.robot_state or '-'})"]
    help_p = needs_help_probability(status.belief_states, status.belief)
    tail = holder_text(getattr(status, "object_holder", "none"))
    if getattr(status, "episode_over", False):
        tail += f"; episode over: {getattr(status, 'end_reason', '') or '?'}"
    lines.append(f"P(human needs help) = {help_p:.2f}; {tail}")
    return lines


def belief_bars(status) -> List[BeliefBar]:
    """The robot's belief over its model's states, in the model's order, the true one marked."""
    helped = task_of(status.belief_states).needs_help_states
    return [BeliefBar(state=s, probability=float(p), true_state=(s == status.robot_state),
                      needs_help=s in helped)
            for s, p in zip(status.belief_states, status.belief)]


#: The world's services that make an agent act (``/human/<action>``, ``/robot/<action>``), in
#: the words of the caption.
_ACTION_WORDS = {"walk_away": "walks away", "look_around": "looks around",
                 "warn_robot": "warns the robot", "attempt_grasp": "tries to grasp the object",
                 "grasp": "reaches for the object", "idle": "stays idle", "reset": "resets",
                 "point_to_obj": "points at the object", "cancel_action": "stops",
                 "grasp_planning": "plans a grasp over the object"}


#: How a caption after a reset begins its only line (after the episode's number).
RESET_WORDS = "the world was reset"


def is_reset_caption(text: str) -> bool:
    """True if ``text`` (a caption's lines, joined) is the caption of a reset."""
    first = text.split("\n", 1)[0]
    return "\n" not in text and RESET_WORDS in first


class StepCaption:
    """The lines over the scene while a step is played, for PyBullet's window and RViz.

    The loop reports a step (``/hrc/status``) only once both agents have acted, so a caption
    made of reports alone describes the step before the one on screen. This one also hears
    the world's own news: an action starts (:meth:`action_started`), it ends
    (:meth:`action_finished`), the world is reset (:meth:`reset`). The caption therefore reads,
    over the life of a step::

        episode 2, step 4: playing             (the step after the last one reported)
        human: tries to grasp the object ...   (under way; then "-> <what the world said>")
        robot: waits for the human             (then "decides", "reaches for the object ...")
        before this step: P(human needs help) = 0.87; nobody holds the object

    and, once the step is reported, :func:`status_lines` with ``: done`` on the first line and
    what became of the robot's action under the robot's line (``  -> cannot grasp: ...``). A
    reset clears it (``episode 3: the world was reset; waiting for step 0``). A report that
    comes after the next step began (its human action started) does not take the caption back:
    it stays on the step being played, the report its "before this step" line. Each call
    answers a whole caption, the lines of one step, to be shown all at once. Not thread-safe:
    one caller at a time.
    """

    def __init__(self) -> None:
        self._last = None              # the last step reported (a Status), None after a reset
        self._episode = 0              # the episode of the step under way (0: none yet)
        self._step = 0                 # the step under way
        self._human: Optional[str] = None   # its human line (None: the human has not acted)
        self._robot: Optional[str] = None
        self._under_way: Dict[str, str] = {}   # agent -> action running now
        self._lines: List[str] = ["the scene is ready; waiting for the first step"]

    def lines(self) -> List[str]:
        """What the caption says now."""
        return list(self._lines)

    def step_done(self, status) -> List[str]:
        """The loop reported a step (anything with ``ros_hrc/Status``'s fields): its outcome."""
        self._last = status
        self._episode = int(getattr(status, "episode", 0))
        if self._step > int(status.step) and (self._human is not None or self._robot is not None):
            # A late report: the next step's agents have acted already (a second human action
            # began it). The caption stays on it, never back on the step this report closes.
            return self._playing()
        self._step = int(status.step) + 1
        self._human = self._robot = None
        if self._under_way:
            # The next step's action started before this report came: keep showing it.
            for agent, action in self._under_way.items():
                self._set(agent, f"{_words(action)} ...")
            return self._playing()
        lines = status_lines(status)
        fault = getattr(status, "fault", "")
        lines[0] += f": failed ({fault})" if fault else ": done"
        result = getattr(status, "robot_result", "")
        if result and not fault:
            lines.insert(3, f"  -> {result}")   # what became of the robot's action
        self._lines = lines
        return self.lines()

    def action_started(self, agent: str, action: str) -> List[str]:
        """The world started ``agent``'s ``action`` (the name of its service)."""
        if agent not in ("human", "robot"):
            return self.lines()
        if agent == "human" and self._human is not None and agent not in self._under_way:
            # A second human action without a report between: a new step (e.g. a hand-run one).
            self._step += 1
            self._robot = None
        self._under_way[agent] = action
        self._set(agent, f"{_words(action)} ...")
        return self._playing()

    def action_finished(self, agent: str, action: str, success: bool, message: str) -> List[str]:
        """The world ended ``agent``'s ``action``: ``success`` and what the world said."""
        if agent not in ("human", "robot"):
            return self.lines()
        self._under_way.pop(agent, None)
        self._set(agent, f"{_words(action)} -> {message or ('done' if success else 'failed')}")
        return self._playing()

    def reset(self) -> List[str]:
        """The world was reset: nothing of the last episode stays on screen."""
        self._episode = (self._episode or 0) + 1 if self._last is not None else max(self._episode, 1)
        self._last = None
        self._step = 0
        self._human = self._robot = None
        self._under_way.clear()
        self._lines = [f"episode {self._episode}: {RESET_WORDS}; waiting for step 0"]
        return self.lines()

    def _set(self, agent: str, text: str) -> None:
        if agent == "human":
            self._human = text
        else:
            self._robot = text

    def _playing(self) -> List[str]:
        episode = f"episode {self._episode}, " if self._episode else ""
        lines = [f"{episode}step {self._step}: playing",
                 f"human: {self._human or 'about to act'}"]
        if self._robot is not None:
            lines.append(f"robot: {self._robot}")
        elif "human" in self._under_way or self._human is None:
            lines.append("robot: waits for the human")
        else:
            lines.append("robot: decides")
        if self._last is not None:
            help_p = needs_help_probability(self._last.belief_states, self._last.belief)
            holder = holder_text(getattr(self._last, "object_holder", "none"))
            lines.append(f"before this step: P(human needs help) = {help_p:.2f}; {holder}")
        self._lines = lines
        return self.lines()


def _words(action: str) -> str:
    return _ACTION_WORDS.get(action, action.replace("_", " "))


#: How many of the selector's types the task's line names (the most likely first).
TASK_LINE_TYPES = 3
#: How many of a robot model of types' types a step block's "robot types" line names.
STEP_BLOCK_TYPES = 5


def learnt_text(status) -> str:
    """A learning robot's figure in a step's or a task's status: ``0.41 ± 0.15``."""
    return f"{status.learnt_value:.2f} \u00b1 {status.learnt_spread:.2f}"


def task_line(status) -> str:
    """The terminal's one line for a finished task of a sequence (anything with the fields of
    ``ros_hrc/TaskStatus``), e.g. ``task 3/5 (expert_tired_noncollaborative): success (robot)
    in 12 steps, 21.4 s, utility 0.77; policy policy3; belief: expert_tired_noncollaborative
    0.71, ...``."""
    who = f" ({status.who_succeeded})" if status.who_succeeded else ""
    steps = counted(status.steps, "step")
    line = (f"task {status.task_index}/{status.tasks} ({status.true_type}): {status.outcome}"
            f"{who} in {steps}, {status.duration:.1f} s, utility {status.utility:.2f}")
    if status.warnings or status.preemptions:
        line += (f", {counted(status.warnings, 'warning')}, "
                 f"{counted(status.preemptions, 'pre-emption')}")
    if status.policy:
        line += f"; policy {status.policy}"
    if status.type_names:
        line += f"; belief: {ranked_types(status.type_names, status.type_belief, TASK_LINE_TYPES)}"
    if status.learnt_name:
        line += f"; learnt {learnt_text(status)}"
    return line
