"""The message types of the protocol (version 2), each a frozen dataclass that validates
itself when it is built, so an invalid message can be neither sent nor received.

Types and their fields (``?`` marks an optional field, left out of the JSON when ``None``)::

    hello        who, version, nonce?, auth?               first frame of a client, answered by
                                                           the server's own hello
    step         step, action, state, reward?, state_index?, belief? {state: p}, manual?
                                                           MDP -> human node (9090)
    reaction     step, state, state_index?, rule?, reward?, manual?
                                                           MDP -> human node: a human who hears
                                                           the robot, his state after it acted
    observation  step, observation, bits, state, elapsed?  coordinator -> POMDP (7070)
    decision     step, action, belief [p...], belief_states?, decision_ms?, surprise?, rule?,
                 action_names?, action_values?, type_names?, type_belief?,
                 learnt_name?, learnt_value?, learnt_spread?, policy?
                                                           POMDP -> coordinator: answers observation
    action       step, action, belief? [p...], belief_states?, decision_ms?
                                                           "carry out this action" (no link
                                                           takes it since the robot node was
                                                           folded into hrc_human: refused)
    reset        reason?, episode?, task_index?, true_type?, human_model?, drift_to?, drift?
                                                           start again from step 0 (a task of a
                                                           sequence: which one, who plays it)
    task_end     task_index, outcome, who_succeeded?, warnings, preemptions, steps, duration,
                 utility                                   coordinator -> POMDP: a task of a
                                                           sequence ended, how
    task_report  selector, policy, robot_model?, type_names?, type_belief?, signature?,
                 total_disc_reward?, learnt_name?, learnt_value?, learnt_spread?
                                                           POMDP -> coordinator: answers
                                                           task_end
    next_state   state (int, or null: let the model choose)  human node -> MDP (9090)
    configure    reason?                                   human node -> each solver process:
                                                           take the launch's settings as they are
                                                           now (a warm stack's next cell)
    ack          step, of?, action?, success?, result?, episode?, episode_over?, end_reason?
                                                           "done"; may carry what was done
    error        message, code?, in_reply_to?, step?       answer to a rejected or failed message

Every message also carries the optional **envelope** (keyword-only, omitted when ``None``):
``epoch`` (the loop's epoch, minted once per reset by the coordinator), ``id`` (the
correlation id of a request) and ``reply_to`` (the ``id`` of the request a reply answers).

Names never change; fields may grow: unknown extra fields are kept in ``Message.extra`` and
sent on again. What each field may hold: :mod:`ros_hrc.link.validation`.
"""
from __future__ import annotations

from dataclasses import MISSING, dataclass, field, fields
from typing import Any, ClassVar, Dict, Mapping, Optional, Sequence, Tuple, Type

from ros_hrc.link.validation import (AUTH_HEX_CHARS, MAX_BITS, MAX_ENVELOPE_INT,
                                     MAX_SIGNATURE_CODE, MAX_STATE_INDEX, MAX_UINT32,
                                     MAX_VERSION, NONCE_HEX_RANGE, Checker, check_extra, kind_of)

PROTOCOL_VERSION = 2
#: The envelope fields every message type has, in wire order.
ENVELOPE_FIELDS = ("epoch", "id", "reply_to")


_FIELD_CACHE: Dict[type, Tuple[Tuple[str, bool], ...]] = {}


def wire_fields(cls: type) -> Tuple[Tuple[str, bool], ...]:
    """(name, required) of a message class's wire fields in wire order (the type's own fields,
    then the envelope); cached, since ``dataclasses.fields`` is the slowest part of building
    a message."""
    cached = _FIELD_CACHE.get(cls)
    if cached is None:
        own = tuple((f.name, f.default is MISSING and f.default_factory is MISSING)
                    for f in fields(cls) if f.name != "extra" and f.name not in ENVELOPE_FIELDS)
        cached = own + tuple((name, False) for name in ENVELOPE_FIELDS)
        _FIELD_CACHE[cls] = cached
    return cached


@dataclass(frozen=True)
class Message:
    """Base of every message. ``type`` is the wire name; ``extra`` holds fields this version
    does not know (kept, and sent on again by :func:`~ros_hrc.link.codec.encode`).

    The envelope, on every type (keyword-only, optional): ``epoch`` (the loop's epoch: minted
    once per reset by the coordinator; a message of an older epoch is stale), ``id`` (the
    correlation id of a request; :meth:`MessageClient.request
    <ros_hrc.link.transport.MessageClient.request>` stamps a fresh one) and ``reply_to`` (the
    ``id`` of the request this message answers).

    Constructing a message validates it (raising :class:`MessageError`), so an invalid
    message can be neither sent nor received."""

    TYPE: ClassVar[str] = ""
    extra: Mapping[str, Any] = field(default_factory=dict, kw_only=True)
    epoch: Optional[int] = field(default=None, kw_only=True)
    id: Optional[int] = field(default=None, kw_only=True)
    reply_to: Optional[int] = field(default=None, kw_only=True)

    def __post_init__(self) -> None:
        check = Checker(self.TYPE)
        if not isinstance(self.extra, Mapping):
            raise check.fail("extra", f"must be a mapping, got {kind_of(self.extra)}")
        clash = sorted(name for name in self.extra
                       if name == "type" or any(name == f for f, _ in wire_fields(type(self))))
        if clash:
            raise check.fail(clash[0], "is a named field and cannot also be an extra field")
        object.__setattr__(self, "extra", dict(self.extra))
        for name in ENVELOPE_FIELDS:
            value = getattr(self, name)
            if value is not None:
                check.integer(name, value,
                              maximum=MAX_UINT32 if name == "epoch" else MAX_ENVELOPE_INT)
        check_extra(check, self.extra)
        self._validate(check)

    @property
    def type(self) -> str:
        """The wire name of this message's type."""
        return self.TYPE

    def _validate(self, check: Checker) -> None:
        """Check and normalise the fields (subclasses)."""

    def _set(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)

    def to_dict(self) -> Dict[str, Any]:
        """The JSON object of this message: ``type`` first, then required fields (even a null
        ``next_state.state``), optional fields only when set, the envelope when set, then the
        extras."""
        out: Dict[str, Any] = {"type": self.TYPE}
        for name, required in wire_fields(type(self)):
            value = getattr(self, name)
            if value is None and not required:
                continue
            out[name] = list(value) if isinstance(value, tuple) else value
        out.update(self.extra)
        return out


@dataclass(frozen=True)
class Hello(Message):
    """First frame of a client: who it is (a role name, e.g. ``despot_mdp``) and the protocol
    version it speaks. The server answers with a hello of its own. On a link with a token
    (:mod:`ros_hrc.link.token`) the client's hello carries a fresh ``nonce`` and ``auth``, its
    proof of the token; the server's answer carries ``auth``, the server's proof."""

    TYPE: ClassVar[str] = "hello"
    who: str
    version: int = PROTOCOL_VERSION
    nonce: Optional[str] = None
    auth: Optional[str] = None

    def _validate(self, check: Checker) -> None:
        self._set("who", check.text("who", self.who))
        self._set("version", check.integer("version", self.version, minimum=1,
                                           maximum=MAX_VERSION))
        if self.nonce is not None:
            self._set("nonce", check.hex_text("nonce", self.nonce, NONCE_HEX_RANGE))
        if self.auth is not None:
            self._set("auth", check.hex_text("auth", self.auth,
                                             (AUTH_HEX_CHARS, AUTH_HEX_CHARS)))


@dataclass(frozen=True)
class Step(Message):
    """MDP -> human node: in step ``step`` the human takes ``action`` in ``state`` (a state
    name). Optional: the step's ``reward``, the state's number ``state_index``, the MDP's
    ``belief`` over its states, and ``manual`` (the state was typed by the user)."""

    TYPE: ClassVar[str] = "step"
    step: int
    action: str
    state: str
    reward: Optional[float] = None
    state_index: Optional[int] = None
    belief: Optional[Mapping[str, float]] = None
    manual: Optional[bool] = None

    def _validate(self, check: Checker) -> None:
        self._set("step", check.integer("step", self.step, maximum=MAX_UINT32))
        self._set("action", check.text("action", self.action))
        self._set("state", check.text("state", self.state))
        if self.reward is not None:
            self._set("reward", check.number("reward", self.reward))
        if self.state_index is not None:
            self._set("state_index", check.integer("state_index", self.state_index,
                                                              maximum=MAX_STATE_INDEX))
        if self.belief is not None:
            self._set("belief", check.belief_map("belief", self.belief))
        if self.manual is not None:
            self._set("manual", check.flag("manual", self.manual))


@dataclass(frozen=True)
class Reaction(Message):
    """MDP -> human node, after the ``ack`` of step ``step``, from a human who hears the robot
    (a task with reaction rules, :mod:`ros_hrc.tasks`): the ``state`` he is in after the
    robot's action (the step's ``state`` was the one he acted in). Optional: its number
    ``state_index``, the ``rule`` of the task that chose it, the step's ``reward`` and
    ``manual`` (the state was typed). Not answered unless refused (an ``error``)."""

    TYPE: ClassVar[str] = "reaction"
    step: int
    state: str
    state_index: Optional[int] = None
    rule: Optional[str] = None
    reward: Optional[float] = None
    manual: Optional[bool] = None

    def _validate(self, check: Checker) -> None:
        self._set("step", check.integer("step", self.step, maximum=MAX_UINT32))
        self._set("state", check.text("state", self.state))
        if self.state_index is not None:
            self._set("state_index", check.integer("state_index", self.state_index,
                                                   maximum=MAX_STATE_INDEX))
        if self.rule is not None:
            self._set("rule", check.text("rule", self.rule))
        if self.reward is not None:
            self._set("reward", check.number("reward", self.reward))
        if self.manual is not None:
            self._set("manual", check.flag("manual", self.manual))


@dataclass(frozen=True)
class Observation(Message):
    """Observer -> POMDP: the robot's observation after step ``step`` (its name, e.g. ``O35``,
    and the raw predicate ``bits`` 0..127, which may differ when the pattern was mapped to the
    nearest legal one) and the robot model's true ``state`` (e.g. ``S2``, for reporting).
    Optional: ``elapsed``, the simulated seconds since the episode's reset when the world was
    observed (a finite number >= 0; absent: unknown), for a robot whose rules count time.
    Answered with a :class:`Decision` (or an :class:`Error`)."""

    TYPE: ClassVar[str] = "observation"
    step: int
    observation: str
    bits: int
    state: str
    elapsed: Optional[float] = None

    def _validate(self, check: Checker) -> None:
        self._set("step", check.integer("step", self.step, maximum=MAX_UINT32))
        self._set("observation", check.text("observation", self.observation))
        self._set("bits", check.integer("bits", self.bits, maximum=MAX_BITS))
        self._set("state", check.text("state", self.state))
        if self.elapsed is not None:
            self._set("elapsed", check.number("elapsed", self.elapsed, minimum=0.0))


#: A learning robot's figure, in a decision and a task report: all three or none.
LEARNT_FIELDS = ("learnt_name", "learnt_value", "learnt_spread")


def _validate_learnt(message: Message, check: Checker) -> None:
    """A learning robot's figure (:class:`Decision`, :class:`TaskReport`): ``learnt_name``
    (one line saying what it is), ``learnt_value`` (a probability) and ``learnt_spread`` (its
    standard deviation over the posterior), all three or none."""
    missing = [f for f in LEARNT_FIELDS if getattr(message, f) is None]
    if len(missing) == len(LEARNT_FIELDS):
        return
    if missing:
        raise check.fail(missing[0], "must come with the other learnt_ fields")
    message._set("learnt_name", check.prose("learnt_name", message.learnt_name))
    value = check.number("learnt_value", message.learnt_value, minimum=0.0)
    if value > 1.0:
        raise check.fail("learnt_value", f"must be a probability (<= 1), got {value}")
    message._set("learnt_value", value)
    message._set("learnt_spread", check.number("learnt_spread", message.learnt_spread,
                                               minimum=0.0))


@dataclass(frozen=True)
class Decision(Message):
    """The robot planner's answer to an :class:`Observation` (observer <- POMDP): the
    ``action`` it chose for step ``step`` and its ``belief`` after the observation (a
    probability per model state, in model order). Optional: ``belief_states`` (the states'
    names, same length), ``decision_ms`` (planning time), ``surprise`` (the observation had
    probability 0 under the belief: the planner fell back to a documented belief), ``rule``
    (which rule of a baseline robot chose the action), and ``action_names`` with
    ``action_values`` (the planner's value of each action it compared, one number per name,
    the chosen action's the best: why it chose; both or neither, e.g. a baseline robot has
    none), and ``type_names`` with ``type_belief`` (a robot model of human types,
    :mod:`ros_hrc.pomdp.typed`: its belief over the types; ``belief`` is then over the task's
    states, the types summed out; both or neither), and a learning robot's figure of its
    learnt model (``learnt_name``, ``learnt_value``, ``learnt_spread``: all or none), and in
    a sequence of tasks ``policy``, the policy that decides the task (the one its selector
    chose when the task started). A reply: it carries ``reply_to`` and ``epoch`` of the
    observation."""

    TYPE: ClassVar[str] = "decision"
    step: int
    action: str
    belief: Sequence[float]
    belief_states: Optional[Sequence[str]] = None
    decision_ms: Optional[float] = None
    surprise: Optional[bool] = None
    rule: Optional[str] = None
    action_names: Optional[Sequence[str]] = None
    action_values: Optional[Sequence[float]] = None
    type_names: Optional[Sequence[str]] = None
    type_belief: Optional[Sequence[float]] = None
    learnt_name: Optional[str] = None
    learnt_value: Optional[float] = None
    learnt_spread: Optional[float] = None
    policy: Optional[str] = None

    def _validate(self, check: Checker) -> None:
        _validate_learnt(self, check)
        self._set("step", check.integer("step", self.step, maximum=MAX_UINT32))
        self._set("action", check.text("action", self.action))
        self._set("belief", check.belief_list("belief", self.belief))
        if self.policy is not None:
            self._set("policy", check.text("policy", self.policy))
        if self.action_names is not None or self.action_values is not None:
            names, values = check.named_numbers("action_names", self.action_names,
                                                "action_values", self.action_values)
            self._set("action_names", names)
            self._set("action_values", values)
        if self.type_names is not None or self.type_belief is not None:
            names, belief = check.named_belief("type_names", self.type_names,
                                               "type_belief", self.type_belief)
            self._set("type_names", names)
            self._set("type_belief", belief)
        if self.belief_states is not None:
            self._set("belief_states", check.belief_names(self.belief, self.belief_states))
        if self.decision_ms is not None:
            self._set("decision_ms", check.number("decision_ms", self.decision_ms, minimum=0.0))
        if self.surprise is not None:
            self._set("surprise", check.flag("surprise", self.surprise))
        if self.rule is not None:
            self._set("rule", check.text("rule", self.rule))


@dataclass(frozen=True)
class Action(Message):
    """"Carry out this action": the robot's ``action`` for step ``step``, once the
    coordinator's order to the robot node on 8080. That node is folded into hrc_human, which
    calls the world's /robot/* services itself, so no link takes this message today (each
    refuses it); it stays a type of the protocol for a robot executor of one's own. Optional:
    the ``belief`` it was chosen with (a probability per model state, in model order),
    ``belief_states`` (the
    states' names, same length, only with a belief) and ``decision_ms`` (planning time)."""

    TYPE: ClassVar[str] = "action"
    step: int
    action: str
    belief: Optional[Sequence[float]] = None
    belief_states: Optional[Sequence[str]] = None
    decision_ms: Optional[float] = None

    def _validate(self, check: Checker) -> None:
        self._set("step", check.integer("step", self.step, maximum=MAX_UINT32))
        self._set("action", check.text("action", self.action))
        if self.belief is not None:
            self._set("belief", check.belief_list("belief", self.belief))
        if self.belief_states is not None:
            self._set("belief_states", check.belief_names(self.belief, self.belief_states))
        if self.decision_ms is not None:
            self._set("decision_ms", check.number("decision_ms", self.decision_ms, minimum=0.0))


@dataclass(frozen=True)
class Reset(Message):
    """Start again: world, beliefs and step counter go back to step 0. ``reason`` is for logs;
    ``episode`` is the number of the episode that starts.

    In a sequence (``tasks:=N``) the episode is a task, and the reset says which and who
    plays it: ``task_index`` (from 1; to the POMDP process a new index is a new task, for
    which its selector chooses a policy), ``true_type`` (the schedule's label of the human,
    for the oracle and the reports), and to the MDP ``human_model`` (the model that plays
    it), ``drift_to`` with ``drift`` (the model it drifts to and that model's weight, 0..1).
    A peer that knows none of them (an older one) resets as before."""

    TYPE: ClassVar[str] = "reset"
    reason: Optional[str] = None
    episode: Optional[int] = None
    task_index: Optional[int] = None
    true_type: Optional[str] = None
    human_model: Optional[str] = None
    drift_to: Optional[str] = None
    drift: Optional[float] = None

    def _validate(self, check: Checker) -> None:
        if self.reason is not None:
            self._set("reason", check.prose("reason", self.reason))
        if self.episode is not None:
            self._set("episode", check.integer("episode", self.episode, maximum=MAX_UINT32))
        if self.task_index is not None:
            self._set("task_index", check.integer("task_index", self.task_index, minimum=1,
                                                  maximum=MAX_UINT32))
        for name in ("true_type", "human_model", "drift_to"):
            if getattr(self, name) is not None:   # a model may be a path: prose's length
                self._set(name, check.prose(name, getattr(self, name)))
        if self.drift is not None:
            if self.drift_to is None:
                raise check.fail("drift", "is given without drift_to")
            self._set("drift", check.probability("drift", self.drift))


@dataclass(frozen=True)
class Configure(Message):
    """Human node -> a solver process: read the launch's resolved settings again (the
    session's settings file, which the experiment worker rewrote for its next cell) and
    start from them as a freshly started process would: models, planner or agent, selector,
    seed. Settings a process cannot take in place (its port, its task: any setting outside
    :data:`ros_hrc.settings.IN_PLACE`) must not change: it refuses. Answered with an
    ``ack`` (``of: "configure"``) or an ``error`` saying why; a refused configure changes
    nothing. ``reason`` is for the logs."""

    TYPE: ClassVar[str] = "configure"
    reason: Optional[str] = None

    def _validate(self, check: Checker) -> None:
        if self.reason is not None:
            self._set("reason", check.prose("reason", self.reason))


@dataclass(frozen=True)
class TaskEnd(Message):
    """Coordinator -> POMDP process: task ``task_index`` of a sequence ended. How: its
    ``outcome`` (``success``, ``fail``, ``timeout``), ``who_succeeded`` (``human``,
    ``robot``; absent: no one), the human's ``warnings``, the robot's ``preemptions``, its
    ``steps``, its ``duration`` (simulated s) and its ``utility`` (docs/sequences.md).
    Answered with a :class:`TaskReport` (or an :class:`Error`)."""

    TYPE: ClassVar[str] = "task_end"
    task_index: int
    outcome: str
    warnings: int
    preemptions: int
    steps: int
    duration: float
    utility: float
    who_succeeded: Optional[str] = None

    def _validate(self, check: Checker) -> None:
        self._set("task_index", check.integer("task_index", self.task_index, minimum=1,
                                              maximum=MAX_UINT32))
        self._set("outcome", check.text("outcome", self.outcome))
        for name in ("warnings", "preemptions", "steps"):
            self._set(name, check.integer(name, getattr(self, name), maximum=MAX_UINT32))
        self._set("duration", check.number("duration", self.duration, minimum=0.0))
        self._set("utility", check.number("utility", self.utility))
        if self.who_succeeded is not None:
            self._set("who_succeeded", check.text("who_succeeded", self.who_succeeded))


@dataclass(frozen=True)
class TaskReport(Message):
    """POMDP process -> coordinator, the answer to a :class:`TaskEnd`: the robot's
    ``selector`` and the ``policy`` it chose for the task. Optional: that policy's
    ``robot_model`` (its file; absent for a policy without one), the selector's
    ``type_names`` with its ``type_belief`` after the task (both or neither; a selector
    without a type belief sends neither), the task's ``signature`` (one code 0..63 per
    step: the human observables the robot saw), ``total_disc_reward`` (the policy's own
    discounted reward over the task's true states: FABRIC's figure, not the utility) and a
    learning robot's figure after learning from the task (``learnt_*``, as a decision's)."""

    TYPE: ClassVar[str] = "task_report"
    selector: str
    policy: str
    robot_model: Optional[str] = None
    type_names: Optional[Sequence[str]] = None
    type_belief: Optional[Sequence[float]] = None
    signature: Optional[Sequence[int]] = None
    total_disc_reward: Optional[float] = None
    learnt_name: Optional[str] = None
    learnt_value: Optional[float] = None
    learnt_spread: Optional[float] = None

    def _validate(self, check: Checker) -> None:
        _validate_learnt(self, check)
        self._set("selector", check.text("selector", self.selector))
        self._set("policy", check.text("policy", self.policy))
        if self.robot_model is not None:
            self._set("robot_model", check.prose("robot_model", self.robot_model))
        if self.type_names is not None or self.type_belief is not None:
            names, belief = check.named_belief("type_names", self.type_names,
                                               "type_belief", self.type_belief)
            self._set("type_names", names)
            self._set("type_belief", belief)
        if self.signature is not None:
            self._set("signature", check.codes("signature", self.signature,
                                               MAX_SIGNATURE_CODE))
        if self.total_disc_reward is not None:
            self._set("total_disc_reward", check.number("total_disc_reward",
                                                        self.total_disc_reward))


@dataclass(frozen=True)
class NextState(Message):
    """Human node -> MDP: the human's next state by number (0..7 for the seed's models), or
    ``None`` (JSON null) to let the model choose. The key is required even when null."""

    TYPE: ClassVar[str] = "next_state"
    state: Optional[int]

    def _validate(self, check: Checker) -> None:
        if self.state is not None:
            self._set("state", check.integer("state", self.state, maximum=MAX_STATE_INDEX))


@dataclass(frozen=True)
class Ack(Message):
    """Step ``step`` is done. ``of`` names the acknowledged type when it is not obvious (a
    reset is acknowledged with ``step=0, of="reset"``); ``action``, ``success`` and ``result``
    carry what was done (the human node acks the MDP with the robot's action); ``episode``
    (the episode's number), ``episode_over`` (the step ended the episode) and ``end_reason``
    (why it ended) tell where the loop stands."""

    TYPE: ClassVar[str] = "ack"
    step: int
    of: Optional[str] = None
    action: Optional[str] = None
    success: Optional[bool] = None
    result: Optional[str] = None
    episode: Optional[int] = None
    episode_over: Optional[bool] = None
    end_reason: Optional[str] = None

    def _validate(self, check: Checker) -> None:
        self._set("step", check.integer("step", self.step, maximum=MAX_UINT32))
        if self.of is not None:
            self._set("of", check.text("of", self.of))
        if self.action is not None:
            self._set("action", check.text("action", self.action))
        if self.success is not None:
            self._set("success", check.flag("success", self.success))
        if self.result is not None:
            self._set("result", check.any_text("result", self.result))
        if self.episode is not None:
            self._set("episode", check.integer("episode", self.episode, maximum=MAX_UINT32))
        if self.episode_over is not None:
            self._set("episode_over", check.flag("episode_over", self.episode_over))
        if self.end_reason is not None:
            self._set("end_reason", check.text("end_reason", self.end_reason))


@dataclass(frozen=True)
class Error(Message):
    """The answer to a message that was rejected or failed: ``message`` says why, for a person;
    ``code`` says it for a program (``ERR_*``: ``stale``, ``busy``, ``seat_taken``,
    ``invalid``, ``unknown_type``, ``refused``, ``failed``, ``version``); ``in_reply_to`` is
    the answered message's type and ``step`` its step, when known (and ``reply_to`` its
    ``id``). A message, not an exception: :class:`MessageError` is the exception."""

    TYPE: ClassVar[str] = "error"
    message: str
    in_reply_to: Optional[str] = None
    step: Optional[int] = None
    code: Optional[str] = None

    def _validate(self, check: Checker) -> None:
        self._set("message", check.prose("message", self.message))
        if self.in_reply_to is not None:
            self._set("in_reply_to", check.text("in_reply_to", self.in_reply_to))
        if self.step is not None:
            self._set("step", check.integer("step", self.step, maximum=MAX_UINT32))
        if self.code is not None:
            self._set("code", check.text("code", self.code))


#: Wire name -> message class.
MESSAGE_TYPES: Dict[str, Type[Message]] = {
    cls.TYPE: cls for cls in (Hello, Step, Reaction, Observation, Decision, Action, Reset,
                              NextState, Ack, Error, TaskEnd, TaskReport, Configure)
}
#: The types that answer a request (what :func:`~ros_hrc.link.replies.is_reply_to` can match).
REPLY_TYPES: Tuple[Type[Message], ...] = (Ack, Error, Decision, TaskReport)
