"""What goes in and out of the episode coordinator (:mod:`ros_hrc.loop.coordinator`): the
words of its Sans-I/O interface, with no behaviour of their own.

* What the interfaces answer a call with: :class:`Outcome` (an action's), :class:`Snapshot`
  (the world at one instant), :class:`Decision` (the planner's, derived from the protocol's
  ``decision`` message, the one declaration of a decision), :class:`Fault` (the call failed).
* What the seated MDP asks for: :class:`StepRequest`, :class:`ReactionRequest`.
* The effects the coordinator emits: *calls* (:class:`Call` and its kinds, answered through
  ``Coordinator.call_done``) and *notices* (answers to the MDP, a finished reset, a line, a
  timer, a published step), fire and forget.
* A step's report (:class:`StepReport`: what the step block prints and ``/hrc/status``
  carries), the parts of its wall time (:data:`STEP_TIMINGS`), where it keeps a decision
  (:data:`DECISION_IN_REPORT`), and the codes of a refused step.
"""
from __future__ import annotations

import collections.abc
import typing
from dataclasses import dataclass, field, fields, make_dataclass
from typing import Any, Dict, List, Mapping, Optional, Tuple, Type

from ros_hrc.link import protocol
from ros_hrc.tasks.utility import TaskOutcome


# -- what comes back from the interfaces --------------------------------------------------------


@dataclass(frozen=True)
class Outcome:
    """What an action did (the world's or the robot executor's answer)."""
    success: bool
    message: str = ""


@dataclass(frozen=True)
class Snapshot:
    """The world at one instant, read atomically: the six predicates (by service name,
    ``is_ov`` ...), the simulated time, who holds the object, whether it left the belt."""
    predicates: Mapping[str, bool]
    sim_time: float = 0.0
    holder: str = "none"
    left_belt: bool = False


def _answer_of(message: Type[protocol.Message], name: str, doc: str) -> type:
    """The loop's form of the protocol's reply ``message``, so that what an answer carries
    is declared once, by the protocol: a frozen dataclass named ``name`` of the message's own
    fields but its ``step`` (the call it answers has that), in the message's order and of its
    types, sequences as tuples. The first field, what was answered, is required; each other
    one may be left out and is then the empty value of its type, as ``None`` (not given) is
    in the message: no ``None`` reaches a step's report. ``of(msg)`` converts a message."""
    hints = typing.get_type_hints(message)
    specs: List[tuple] = []
    for f in fields(message):
        if f.name in ("step", "extra") or f.name in protocol.ENVELOPE_FIELDS:
            continue
        kind = _without_none(hints[f.name])
        specs.append((f.name, kind) if not specs else (f.name, kind,
                                                       field(default=_empty(kind))))

    def tuples(self) -> None:
        for f in fields(self):
            if isinstance(getattr(self, f.name), list):
                object.__setattr__(self, f.name, tuple(getattr(self, f.name)))

    def of(cls, msg: protocol.Message) -> Any:
        given = {f.name: getattr(msg, f.name) for f in fields(cls)}
        return cls(**{key: value for key, value in given.items() if value is not None})

    answer = make_dataclass(name, specs, frozen=True, namespace={
        "__doc__": doc, "__post_init__": tuples, "of": classmethod(of)})
    answer.__module__ = __name__
    return answer


def _without_none(kind: Any) -> Any:
    """``Optional[X]`` as ``X``, and a sequence ``Sequence[X]`` as ``Tuple[X, ...]``."""
    if typing.get_origin(kind) is typing.Union:
        kind = next(arg for arg in typing.get_args(kind) if arg is not type(None))
    if typing.get_origin(kind) is collections.abc.Sequence:
        return Tuple[typing.get_args(kind)[0], ...]
    return kind


def _empty(kind: Any) -> Any:
    """The empty value of a field's type: ``()``, ``""``, ``0.0``, ``False``."""
    return () if typing.get_origin(kind) is tuple else kind()


Decision = _answer_of(protocol.Decision, "Decision", """The robot planner's answer to an
    observation (the answer to :class:`Decide`): the fields of the protocol's ``decision``
    (:class:`ros_hrc.link.protocol.Decision`, the one declaration of a decision) but its
    step. ``Decision.of(message)`` takes a received one.""")


TaskAnswer = _answer_of(protocol.TaskReport, "TaskAnswer", """The robot process's answer to a
    task's end (the answer to :class:`EndTask`): the fields of the protocol's ``task_report``
    (:class:`ros_hrc.link.protocol.TaskReport`): its selector, the policy it chose, that
    policy's robot model, its type belief, the task's signature and the policy's own
    discounted reward. ``TaskAnswer.of(message)`` takes a received one.""")


@dataclass(frozen=True)
class Fault:
    """A call failed: the interface could not be reached or answered nonsense."""
    message: str


@dataclass(frozen=True)
class ReactionRequest:
    """The seated MDP's reaction to step ``step`` of epoch ``epoch`` (a human who hears the
    robot): his ``state`` after the robot acted, chosen by ``rule``; the step's ``reward``;
    ``manual``: typed. ``reply`` as for :class:`StepRequest`."""
    epoch: Optional[int]
    step: int
    state: str
    rule: str = ""
    reward: float = 0.0
    manual: bool = False
    reply: Any = None


@dataclass(frozen=True)
class StepRequest:
    """The seated MDP's step: in epoch ``epoch`` step ``step`` the human takes ``action`` and
    ends in ``state``. ``reply`` is the adapter's handle to answer it (e.g. a request id)."""
    epoch: Optional[int]
    step: int
    action: str
    state: str
    reward: float = 0.0
    reply: Any = None


# -- effects: calls (answered through call_done) and notices (fire and forget) --------------------


@dataclass(frozen=True)
class Call:
    """An effect that the adapter carries out and answers with ``call_done(call.id, result)``."""
    id: int
    epoch: int
    step: Optional[int]


@dataclass(frozen=True)
class ActHuman(Call):
    """Carry out the human's action through the world's ``/human/<service>``."""
    service: str


@dataclass(frozen=True)
class ObserveWorld(Call):
    """One snapshot of the world (answer: :class:`Snapshot`). ``purpose``: ``observe`` (the
    robot's observation), ``outcome`` (after both acted), ``episode_start``."""
    purpose: str


@dataclass(frozen=True)
class Decide(Call):
    """Ask the robot planner for a decision on this observation (answer: :class:`Decision`).
    ``elapsed``: the world's simulated seconds since the episode's start when it was observed
    (a robot whose rules count time reads it; None: unknown)."""
    observation: str
    bits: int
    state: str
    elapsed: Optional[float] = None


@dataclass(frozen=True)
class ActRobot(Call):
    """Have the robot executor carry out ``action`` (answer: :class:`Outcome`)."""
    action: str


@dataclass(frozen=True)
class ResetWorld(Call):
    """Put human, robot and object back at their start (answer: :class:`Outcome`), for
    episode ``episode`` (the world reseeds its stream). ``interrupt``: only to stop actions
    still under way before the real reset."""
    interrupt: bool = False
    episode: int = 0


@dataclass(frozen=True)
class ResetPlanner(Call):
    """Put the robot's belief back to its initial belief, in epoch ``epoch``. In a sequence:
    ``task_index`` (from 1; 0: no sequence) starts that task, whose human the schedule
    labels ``true_type``."""
    episode: int = 0
    task_index: int = 0
    true_type: str = ""


@dataclass(frozen=True)
class EndTask(Call):
    """Tell the robot process that task ``task_index`` of the sequence ended, how
    (``outcome``), after ``steps`` steps, with its ``utility`` (answer: :class:`TaskAnswer`)."""
    task_index: int
    outcome: TaskOutcome
    steps: int
    utility: float


@dataclass(frozen=True)
class MdpReset:
    """Tell the seated MDP: a new episode starts, epoch ``epoch``, from step 0. In a sequence
    it is task ``task_index`` (0: no sequence), played by ``human_model`` (drifting to
    ``drift_to`` with weight ``drift``), labelled ``true_type``."""
    peer: Any
    epoch: int
    episode: int
    reason: str
    task_index: int = 0
    true_type: str = ""
    human_model: str = ""
    drift_to: str = ""
    drift: float = 0.0


@dataclass(frozen=True)
class MdpStepDone:
    """Answer the MDP's step: done, with the robot's action. ``episode_over``: the MDP stops
    stepping until the next reset; ``end_reason``: the episode ended at this step (also with
    ``on_episode_end`` continue, when the MDP goes on)."""
    peer: Any
    reply: Any
    epoch: int
    step: int
    robot_action: str
    success: bool
    result: str
    episode: int
    episode_over: bool
    end_reason: str


@dataclass(frozen=True)
class MdpRefused:
    """Answer the MDP's step (or, ``in_reply_to`` "reaction", its reaction): not carried out
    (``code`` as in the protocol's error codes)."""
    peer: Any
    reply: Any
    epoch: Optional[int]
    step: int
    code: str
    message: str
    in_reply_to: str = "step"


@dataclass(frozen=True)
class SeatRefused:
    """Refuse a second MDP client: one line, then close its connection."""
    peer: Any
    message: str


@dataclass(frozen=True)
class ResetDone:
    """Answer everyone who asked for this reset (``tokens``)."""
    tokens: Tuple[Any, ...]
    success: bool
    message: str


@dataclass(frozen=True)
class Note:
    """A line for the terminal (``level``: info, warn, error)."""
    level: str
    text: str


@dataclass(frozen=True)
class Timer:
    """Call ``timer_fired(id)`` after ``seconds``."""
    id: int
    seconds: float


@dataclass
class StepReport:
    """Everything one step did: what the step block prints and ``/hrc/status`` carries."""
    epoch: int
    episode: int
    step: int
    human_action: str
    human_state: str
    human_state_index: int = 0
    #: A human who hears the robot: the rule that chose ``human_state`` after the robot acted
    #: (``human_state`` is then that state; the step's request carried the one he acted in).
    reaction: str = ""
    human_reward: float = 0.0
    human_result: str = ""
    human_acted: bool = True
    human_observation: str = ""
    observation_bits: int = 0
    robot_observation: str = ""
    #: What the task's observation noise did to the robot's observation ("" when nothing).
    observation_noise: str = ""
    robot_state: str = ""
    robot_action: str = ""
    robot_result: str = ""
    robot_acted: bool = True
    belief: Tuple[float, ...] = ()
    belief_states: Tuple[str, ...] = ()
    decision_ms: float = 0.0
    surprise: bool = False
    rule: str = ""
    #: The planner's value of each action it compared, parallel lists (empty: a baseline robot,
    #: or a planner that sends none).
    action_names: Tuple[str, ...] = ()
    action_values: Tuple[float, ...] = ()
    #: A robot model of human types: its belief over the types, parallel lists (empty: a
    #: robot of no types); ``belief`` is then over the task's states, the types summed out.
    type_names: Tuple[str, ...] = ()
    type_belief: Tuple[float, ...] = ()
    #: A learning robot's figure of its learnt model (empty name: no learning robot).
    learnt_name: str = ""
    learnt_value: float = 0.0
    learnt_spread: float = 0.0
    #: In a sequence of tasks: the policy that decides the task (its selector's choice at
    #: the task's start; "": no sequence).
    policy: str = ""
    sim_time: float = 0.0
    episode_start_time: float = 0.0
    object_holder: str = "none"
    object_left_belt: bool = False
    episode_over: bool = False
    end_reason: str = ""
    fault: str = ""
    #: Wall milliseconds of the step's parts (:data:`STEP_TIMINGS`), filled in by the runner.
    timings_ms: Dict[str, float] = field(default_factory=dict)


#: Where a step's report keeps each field of the planner's :class:`Decision` (under its own
#: name but the action, which is the robot's); ``/hrc/status`` carries them under the same
#: names (test_decision_declaration.py checks msg/Status.msg against the declaration).
DECISION_IN_REPORT: Mapping[str, str] = {
    f.name: "robot_action" if f.name == "action" else f.name for f in fields(Decision)}

#: The parts of a step whose wall time a report carries: the whole step (from the MDP's
#: request to the report), then each call in order.
STEP_TIMINGS = ("step", "human", "observe", "decide", "robot", "outcome")


@dataclass
class TaskStatusReport:
    """One task of a sequence, as ``/hrc/task_status`` (``ros_hrc/TaskStatus``) carries it:
    the coordinator's part (which task, who played it, how it ended) and the robot process's
    (the selector, the policy, its belief, the signature), empty when the robot process sent
    none (an older one). Field names are the message's."""
    task_index: int
    tasks: int
    episode: int
    epoch: int
    human_model: str
    true_type: str
    outcome: str
    who_succeeded: str
    warnings: int
    preemptions: int
    steps: int
    duration: float
    utility: float
    end_reason: str
    #: The robot's grasps and points while a warning was in force (not in the utility: the
    #: studies require none).
    against_warning: int = 0
    selector: str = ""
    policy: str = ""
    robot_model: str = ""
    type_names: Tuple[str, ...] = ()
    type_belief: Tuple[float, ...] = ()
    estimation_correct: bool = False
    total_disc_reward: float = 0.0
    signature: Tuple[int, ...] = ()
    #: A learning robot's figure after learning from the task (empty name: none).
    learnt_name: str = ""
    learnt_value: float = 0.0
    learnt_spread: float = 0.0
    #: Why the robot's part is empty ("" when it answered).
    robot_problem: str = ""


@dataclass(frozen=True)
class PublishTask:
    """Publish and print one finished task of a sequence."""
    report: TaskStatusReport


@dataclass(frozen=True)
class PublishStep:
    """Publish and print one step's report (also a failed one: ``report.fault``)."""
    report: StepReport


Effect = Any

#: Error codes of refused steps (the protocol's ``error.code``).
STALE, BUSY, SEAT_TAKEN, INVALID, EPISODE_IS_OVER, FAILED, NOT_READY = (
    "stale", "busy", "seat_taken", "invalid", "episode_over", "failed", "not_ready")
