"""The websocket protocol of DESIGN §6 (version 2), Sans-I/O: messages, encoding, decoding,
validation, reply matching and dispatch.

No socket here (and no websocket library): every function is pure and tested without a
network. :mod:`ros_hrc.link.transport` moves the text frames this module produces.

One text frame carries one JSON object with a ``"type"``. Message types and their fields
(``?`` marks an optional field, omitted from the JSON when ``None``)::

    hello        who, version                              first frame of a client, answered by
                                                           the server's own hello
    step         step, action, state, reward?, state_index?, belief? {state: p}, manual?
                                                           MDP -> human node (9090)
    reaction     step, state, state_index?, rule?, reward?, manual?
                                                           MDP -> human node: a human who hears
                                                           the robot, his state after it acted
    observation  step, observation, bits, state            observer -> POMDP (7070)
    decision     step, action, belief [p...], belief_states?, decision_ms?, surprise?, rule?
                                                           POMDP -> observer: answers observation
    action       step, action, belief? [p...], belief_states?, decision_ms?
                                                           "carry out this action" -> robot node
    reset        reason?, episode?                         start again from step 0
    next_state   state (int, or null: let the model choose)  human node -> MDP (9090)
    ack          step, of?, action?, success?, result?, episode?, episode_over?, end_reason?
                                                           "done"; may carry what was done
    error        message, code?, in_reply_to?, step?       answer to a rejected or failed message

Every message also carries the optional **envelope** (keyword-only, omitted when ``None``):
``epoch`` (the loop's epoch, minted once per reset by the coordinator), ``id`` (the
correlation id of a request) and ``reply_to`` (the ``id`` of the request a reply answers).
Each is an integer in ``0..MAX_ENVELOPE_INT`` (2**53 - 1: exact in every JSON reader).

Names never change; fields may grow: unknown extra fields are kept in ``Message.extra`` and
sent on again by :func:`encode`. ``docs/protocol.md`` is the full description.

Replies: :func:`is_reply_to` says whether a message answers a request (by ``reply_to`` when
the request has an ``id``); :func:`as_reply` stamps a reply with its request's ``id`` and
``epoch``; :func:`reply_error` builds the :class:`Error` answering a request;
:class:`DispatchTable` routes a message to its handler by type and refuses the types it does
not take. An ``error`` is never answered with an ``error``.

Exception tree (the first two live in :mod:`ros_hrc.errors`)::

    LinkError
    └── ProtocolError          a message is malformed, of an unknown type or too large
        └── MessageError       raised here; carries .reason and .code, and .msg_type / .step /
                               .msg_id / .epoch when they could be read, so an error reply
                               can say what it answers
"""
from __future__ import annotations

import json
import math
import re
from dataclasses import MISSING, dataclass, field, fields, replace
from typing import (Any, Callable, ClassVar, Dict, FrozenSet, List, Mapping, Optional, Sequence,
                    Tuple, Type, TypeVar, Union)

from ros_hrc.errors import ProtocolError

PROTOCOL_VERSION = 2
#: Largest encoded message, in UTF-8 bytes. A whole step (a belief over a few dozen states
#: and its names) is under 2 KiB; 64 KiB leaves room for growth and still bounds memory.
MAX_MESSAGE_BYTES = 64 * 1024
#: A belief must sum to one within this; it tolerates beliefs printed with 6 significant
#: digits by a foreign (e.g. C++) solver, and still catches an unnormalised one.
BELIEF_TOLERANCE = 1e-4
#: Bit patterns of an observation: the seed's six bits (DESIGN §4) and a seventh, 64 (the
#: object left the belt), that a task may observe (``fabric``: the authors' "failure" bit).
MAX_BITS = 127
#: Largest ``epoch`` / ``id`` / ``reply_to``: 2**53 - 1, the largest integer every JSON reader
#: (a double) holds exactly.
MAX_ENVELOPE_INT = 2 ** 53 - 1
#: Largest ``epoch``, ``step``, ``episode``: each reaches a ``uint32`` of a ROS message
#: (``/hrc/status``, the Decide and ResetPlanner services), so a larger one is refused here,
#: before anything acts on it.
MAX_UINT32 = 2 ** 32 - 1
#: Largest ``state_index`` and ``next_state.state``: a ``uint8`` of ``/hrc/status``.
MAX_STATE_INDEX = 255
#: Largest protocol ``version`` a hello may name.
MAX_VERSION = 2 ** 31 - 1
#: Longest name (``who``, an action, a state, an observation, ``of``, ``code``, ``rule``, ...),
#: in characters; the seed's longest is 15.
MAX_NAME_CHARS = 128
#: Longest free text (``reason``, ``result``, ``message``), in characters.
MAX_TEXT_CHARS = 1024
#: A hello's ``nonce``: 32 to 128 lowercase hex digits; its ``auth``: exactly 64.
NONCE_HEX_RANGE = (32, 128)
AUTH_HEX_CHARS = 64
#: The envelope fields every message type has, in wire order.
ENVELOPE_FIELDS = ("epoch", "id", "reply_to")

# -- error codes (Error.code): machine-readable, stable; Error.message is for people -------------
#: The message belongs to an older epoch (sent before the latest reset): dropped, not applied.
ERR_STALE = "stale"
#: The receiver is still working on an earlier request and takes one at a time.
ERR_BUSY = "busy"
#: The role is already taken by another connected client: this connection is refused.
ERR_SEAT_TAKEN = "seat_taken"
#: The frame or message is malformed (not JSON, a missing or bad field, too large, ...).
ERR_INVALID = "invalid"
#: The receiver does not take messages of this type (unknown to the protocol, or not for it).
ERR_UNKNOWN_TYPE = "unknown_type"
#: Well formed but not acceptable now (an unknown action name, a next_state in auto mode, ...).
ERR_REFUSED = "refused"
#: Taking the message failed (an exception in the handler, a world fault, ...).
ERR_FAILED = "failed"
#: The peer speaks another protocol version (answers a ``hello``).
ERR_VERSION = "version"
#: (answers a ``step``) The episode is over: no step until the next reset.
ERR_EPISODE_OVER = "episode_over"
#: (answers a ``step``) The loop is resetting or recovering: wait for the reset message.
ERR_NOT_READY = "not_ready"
#: The client did not prove it belongs to this launch (no valid ``auth`` in its hello, or a
#: frame before the hello): refused and closed.
ERR_UNAUTHORIZED = "unauthorized"
#: Every code this module defines (a receiver must accept others too: fields may grow).
ERROR_CODES: FrozenSet[str] = frozenset((ERR_STALE, ERR_BUSY, ERR_SEAT_TAKEN, ERR_INVALID,
                                         ERR_UNKNOWN_TYPE, ERR_REFUSED, ERR_FAILED, ERR_VERSION,
                                         ERR_EPISODE_OVER, ERR_NOT_READY, ERR_UNAUTHORIZED))

# Error texts quote at most this much of an offending value, so a reply stays small.
_PREVIEW_CHARS = 40
_MAX_ERROR_CHARS = 1000
# A JSON escape of a UTF-16 surrogate: the only way a parsed string can hold a lone one.
_SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F]")
# Control characters (C0, DEL, C1): no text field may hold one, so nothing a peer sends can
# break a log line in two or drive a terminal.
_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f]")
_LOWER_HEX = re.compile("[0-9a-f]*")
# How a frame that cannot be parsed still shows it is an error (never answered).
_ERROR_TYPE = re.compile(r'"type"\s*:\s*"error"')


class MessageError(ProtocolError):
    """A frame was rejected. ``reason`` says why and ``code`` how (:data:`ERR_INVALID`, or
    :data:`ERR_UNKNOWN_TYPE` for a type this protocol does not have); ``msg_type``, ``step``,
    ``msg_id``, ``epoch`` and ``reply_to`` say which message it was, when they could be read
    (else ``None``): a rejected reply's ``reply_to`` lets a client fail the request it was
    meant to answer at once, rather than wait for an answer that will not come."""

    def __init__(self, reason: str, msg_type: Optional[str] = None,
                 step: Optional[int] = None, msg_id: Optional[int] = None,
                 epoch: Optional[int] = None, code: str = ERR_INVALID,
                 reply_to: Optional[int] = None) -> None:
        super().__init__(reason)
        self.reason = reason
        self.msg_type = msg_type
        self.step = step
        self.msg_id = msg_id
        self.epoch = epoch
        self.code = code
        self.reply_to = reply_to


def _kind(value: Any) -> str:
    """The JSON name of a value's type, for error texts."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "string"
    if isinstance(value, (list, tuple)):
        return "array"
    if isinstance(value, dict):
        return "object"
    return type(value).__name__


def _preview(value: Any) -> str:
    try:
        text = json.dumps(value, ensure_ascii=False)
    except (TypeError, ValueError):
        try:
            text = repr(value)
        except ValueError:  # an int too long for str()
            text = f"<{_kind(value)}>"
    return text if len(text) <= _PREVIEW_CHARS else text[:_PREVIEW_CHARS] + "..."


def _is_count(value: Any, maximum: Optional[int] = None) -> bool:
    """A JSON integer >= 0 (and <= ``maximum``): not a bool, not a float."""
    return (isinstance(value, int) and not isinstance(value, bool) and value >= 0
            and (maximum is None or value <= maximum))


class _Checker:
    """Validates and normalises one message's fields; every complaint names the type and field."""

    def __init__(self, msg_type: str) -> None:
        self.msg_type = msg_type

    def fail(self, name: str, problem: str) -> MessageError:
        return MessageError(f'{self.msg_type} message: field "{name}" {problem}', self.msg_type)

    def _got(self, value: Any) -> str:
        return f"got {_kind(value)} {_preview(value)}"

    def integer(self, name: str, value: Any, minimum: int = 0,
                maximum: Optional[int] = None) -> int:
        # bool is an int in Python but not in JSON: true is not a step number.
        if not isinstance(value, int) or isinstance(value, bool):
            raise self.fail(name, f"must be an integer, {self._got(value)}")
        if value < minimum or (maximum is not None and value > maximum):
            bounds = f"in {minimum}..{maximum}" if maximum is not None else f">= {minimum}"
            raise self.fail(name, f"must be {bounds}, got {_preview(value)}")
        return value

    def number(self, name: str, value: Any, minimum: Optional[float] = None) -> float:
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise self.fail(name, f"must be a number, {self._got(value)}")
        try:
            value = float(value)
        except OverflowError:  # an integer too large for a double
            raise self.fail(name, "must be finite, got a number too large") from None
        if not math.isfinite(value):
            raise self.fail(name, f"must be finite, got {value}")
        if minimum is not None and value < minimum:
            raise self.fail(name, f"must be >= {minimum}, got {value}")
        return value

    def _string(self, name: str, value: Any, limit: int) -> str:
        if not isinstance(value, str):
            raise self.fail(name, f"must be a string, {self._got(value)}")
        if len(value) > limit:
            raise self.fail(name, f"must be at most {limit} characters, has {len(value)}")
        bad = _CONTROL.search(value)
        if bad:
            raise self.fail(name, f"must not hold control characters, has U+{ord(bad.group()):04X} "
                                  f"at character {bad.start()}")
        return value

    def text(self, name: str, value: Any) -> str:
        """A name: not empty, at most :data:`MAX_NAME_CHARS`, no control characters."""
        value = self._string(name, value, MAX_NAME_CHARS)
        if not value:
            raise self.fail(name, "must not be empty")
        return value

    def prose(self, name: str, value: Any) -> str:
        """Free text for people: not empty, at most :data:`MAX_TEXT_CHARS`, no control
        characters."""
        value = self._string(name, value, MAX_TEXT_CHARS)
        if not value:
            raise self.fail(name, "must not be empty")
        return value

    def any_text(self, name: str, value: Any) -> str:
        """Free text that may be empty."""
        return self._string(name, value, MAX_TEXT_CHARS)

    def hex_text(self, name: str, value: Any, lengths: Tuple[int, int]) -> str:
        """Lowercase hex digits, between ``lengths[0]`` and ``lengths[1]`` of them."""
        if not isinstance(value, str):
            raise self.fail(name, f"must be a string, {self._got(value)}")
        low, high = lengths
        if not (low <= len(value) <= high) or not _LOWER_HEX.fullmatch(value):
            size = f"{low}" if low == high else f"{low} to {high}"
            raise self.fail(name, f"must be {size} lowercase hex digits")
        return value

    def flag(self, name: str, value: Any) -> bool:
        if not isinstance(value, bool):
            raise self.fail(name, f"must be true or false, {self._got(value)}")
        return value

    def _probability_sum(self, name: str, total: float) -> None:
        if abs(total - 1.0) > BELIEF_TOLERANCE:
            raise self.fail(name, f"must sum to 1 (within {BELIEF_TOLERANCE:g}), sums to {total:.9g}")

    def belief_list(self, name: str, value: Any) -> Tuple[float, ...]:
        if not isinstance(value, (list, tuple)):
            raise self.fail(name, f"must be an array of probabilities, {self._got(value)}")
        if not value:
            raise self.fail(name, "must not be empty")
        probs = tuple(self.probability(f"{name}[{i}]", p) for i, p in enumerate(value))
        self._probability_sum(name, math.fsum(probs))
        return probs

    def belief_map(self, name: str, value: Any) -> Dict[str, float]:
        if not isinstance(value, Mapping):
            raise self.fail(name, f"must be an object {{state: probability}}, {self._got(value)}")
        if not value:
            raise self.fail(name, "must not be empty")
        probs: Dict[str, float] = {}
        for key, p in value.items():
            if not isinstance(key, str) or not key:
                raise self.fail(name, f"must have non-empty state names as keys, got {_preview(key)}")
            self.text(f"{name} key", key)
            probs[key] = self.probability(f"{name}.{key}", p)
        self._probability_sum(name, math.fsum(probs.values()))
        return probs

    def probability(self, name: str, value: Any) -> float:
        value = self.number(name, value)
        if value < 0:
            raise self.fail(name, f"must not be negative, got {value}")
        if value > 1.0 + BELIEF_TOLERANCE:   # and so a sum can never overflow
            raise self.fail(name, f"must be at most 1, got {value:.9g}")
        return value

    def names(self, name: str, value: Any) -> Tuple[str, ...]:
        if not isinstance(value, (list, tuple)):
            raise self.fail(name, f"must be an array of strings, {self._got(value)}")
        items = tuple(self.text(f"{name}[{i}]", v) for i, v in enumerate(value))
        if len(set(items)) != len(items):
            raise self.fail(name, "must not repeat a name")
        return items

    def belief_names(self, belief: Optional[Tuple[float, ...]], value: Any) -> Tuple[str, ...]:
        """``belief_states``: names for the probabilities of ``belief``, same length."""
        names = self.names("belief_states", value)
        if belief is None:
            raise self.fail("belief_states", "is given without a belief")
        if len(names) != len(belief):
            raise self.fail("belief_states", f"has {len(names)} names for "
                                             f"{len(belief)} probabilities")
        return names


def _check_extra(check: _Checker, extra: Mapping[str, Any]) -> None:
    """Fields this version does not know are sent on as they came, so each must be one that
    can be sent: names are names, and every number in them is finite (``1e999`` reads as
    infinity)."""
    stack: List[Tuple[str, Any]] = []
    for key, value in extra.items():
        check.text("extra field name", key)
        stack.append((key, value))
    while stack:
        name, value = stack.pop()
        if isinstance(value, float) and not math.isfinite(value):
            raise check.fail(name, f"must be finite, got {value}")
        if isinstance(value, dict):
            stack.extend((f"{name}.{k}", v) for k, v in value.items())
        elif isinstance(value, (list, tuple)):
            stack.extend((f"{name}[{i}]", v) for i, v in enumerate(value))


_FIELD_CACHE: Dict[type, Tuple[Tuple[str, bool], ...]] = {}


def _wire_fields(cls: type) -> Tuple[Tuple[str, bool], ...]:
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
    does not know (kept, and sent on again by :func:`encode`).

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
        check = _Checker(self.TYPE)
        if not isinstance(self.extra, Mapping):
            raise check.fail("extra", f"must be a mapping, got {_kind(self.extra)}")
        clash = sorted(name for name in self.extra
                       if name == "type" or any(name == f for f, _ in _wire_fields(type(self))))
        if clash:
            raise check.fail(clash[0], "is a named field and cannot also be an extra field")
        object.__setattr__(self, "extra", dict(self.extra))
        for name in ENVELOPE_FIELDS:
            value = getattr(self, name)
            if value is not None:
                check.integer(name, value,
                              maximum=MAX_UINT32 if name == "epoch" else MAX_ENVELOPE_INT)
        _check_extra(check, self.extra)
        self._validate(check)

    @property
    def type(self) -> str:
        """The wire name of this message's type."""
        return self.TYPE

    def _validate(self, check: _Checker) -> None:
        """Check and normalise the fields (subclasses)."""

    def _set(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)

    def to_dict(self) -> Dict[str, Any]:
        """The JSON object of this message: ``type`` first, then required fields (even a null
        ``next_state.state``), optional fields only when set, the envelope when set, then the
        extras."""
        out: Dict[str, Any] = {"type": self.TYPE}
        for name, required in _wire_fields(type(self)):
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

    def _validate(self, check: _Checker) -> None:
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

    def _validate(self, check: _Checker) -> None:
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

    def _validate(self, check: _Checker) -> None:
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

    def _validate(self, check: _Checker) -> None:
        self._set("step", check.integer("step", self.step, maximum=MAX_UINT32))
        self._set("observation", check.text("observation", self.observation))
        self._set("bits", check.integer("bits", self.bits, maximum=MAX_BITS))
        self._set("state", check.text("state", self.state))
        if self.elapsed is not None:
            self._set("elapsed", check.number("elapsed", self.elapsed, minimum=0.0))


@dataclass(frozen=True)
class Decision(Message):
    """The robot planner's answer to an :class:`Observation` (observer <- POMDP): the
    ``action`` it chose for step ``step`` and its ``belief`` after the observation (a
    probability per model state, in model order). Optional: ``belief_states`` (the states'
    names, same length), ``decision_ms`` (planning time), ``surprise`` (the observation had
    probability 0 under the belief: the planner fell back to a documented belief) and
    ``rule`` (which rule of a baseline robot chose the action). A reply: it carries
    ``reply_to`` and ``epoch`` of the observation."""

    TYPE: ClassVar[str] = "decision"
    step: int
    action: str
    belief: Sequence[float]
    belief_states: Optional[Sequence[str]] = None
    decision_ms: Optional[float] = None
    surprise: Optional[bool] = None
    rule: Optional[str] = None

    def _validate(self, check: _Checker) -> None:
        self._set("step", check.integer("step", self.step, maximum=MAX_UINT32))
        self._set("action", check.text("action", self.action))
        self._set("belief", check.belief_list("belief", self.belief))
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
    """"Carry out this action": the coordinator's order to the robot node, the robot's
    ``action`` for step ``step``. Optional: the ``belief`` it was chosen with (a probability
    per model state, in model order; the robot node needs none), ``belief_states`` (the
    states' names, same length, only with a belief) and ``decision_ms`` (planning time)."""

    TYPE: ClassVar[str] = "action"
    step: int
    action: str
    belief: Optional[Sequence[float]] = None
    belief_states: Optional[Sequence[str]] = None
    decision_ms: Optional[float] = None

    def _validate(self, check: _Checker) -> None:
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
    ``episode`` is the number of the episode that starts."""

    TYPE: ClassVar[str] = "reset"
    reason: Optional[str] = None
    episode: Optional[int] = None

    def _validate(self, check: _Checker) -> None:
        if self.reason is not None:
            self._set("reason", check.prose("reason", self.reason))
        if self.episode is not None:
            self._set("episode", check.integer("episode", self.episode, maximum=MAX_UINT32))


@dataclass(frozen=True)
class NextState(Message):
    """Human node -> MDP: the human's next state by number (0..7 for the seed's models), or
    ``None`` (JSON null) to let the model choose. The key is required even when null."""

    TYPE: ClassVar[str] = "next_state"
    state: Optional[int]

    def _validate(self, check: _Checker) -> None:
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

    def _validate(self, check: _Checker) -> None:
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

    def _validate(self, check: _Checker) -> None:
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
                              NextState, Ack, Error)
}
#: The types that answer a request (what :func:`is_reply_to` can match).
REPLY_TYPES: Tuple[Type[Message], ...] = (Ack, Error, Decision)


def from_dict(obj: Any) -> Message:
    """Validate a decoded JSON value and build its message; raises :class:`MessageError`."""
    if not isinstance(obj, dict):
        raise MessageError(f"a message must be a JSON object, got {_kind(obj)}")
    # What the rejection can name, read before anything else can fail.
    step, msg_id, epoch, reply_to = _envelope(obj)
    if "type" not in obj:
        raise MessageError('missing field "type"', None, step, msg_id, epoch,
                           reply_to=reply_to)
    msg_type = obj["type"]
    if not isinstance(msg_type, str):
        raise MessageError(f'field "type" must be a string, got {_kind(msg_type)} '
                           f"{_preview(msg_type)}", None, step, msg_id, epoch,
                           reply_to=reply_to)
    cls = MESSAGE_TYPES.get(msg_type)
    if cls is None:
        raise MessageError(f"unknown message type {_preview(msg_type)} (known: "
                           f"{', '.join(sorted(MESSAGE_TYPES))})", msg_type, step, msg_id, epoch,
                           code=ERR_UNKNOWN_TYPE, reply_to=reply_to)
    kwargs: Dict[str, Any] = {}
    for name, required in _wire_fields(cls):
        if name in obj:
            kwargs[name] = obj[name]
        elif required:
            raise MessageError(f'{msg_type} message: missing field "{name}"', msg_type, step,
                               msg_id, epoch, reply_to=reply_to)
    extra = {k: v for k, v in obj.items() if k != "type" and k not in kwargs}
    try:
        return cls(**kwargs, extra=extra)
    except MessageError as exc:
        exc.step, exc.msg_id, exc.epoch, exc.reply_to = step, msg_id, epoch, reply_to
        raise


def _envelope(obj: Dict[str, Any]) -> Tuple[Optional[int], Optional[int], Optional[int],
                                            Optional[int]]:
    """``step``, ``id``, ``epoch`` and ``reply_to`` of a JSON object, each ``None`` when it is
    missing or not a valid value: what a rejection can name."""
    step = obj.get("step")
    msg_id = obj.get("id")
    epoch = obj.get("epoch")
    reply_to = obj.get("reply_to")
    return (step if _is_count(step, MAX_UINT32) else None,
            msg_id if _is_count(msg_id, MAX_ENVELOPE_INT) else None,
            epoch if _is_count(epoch, MAX_UINT32) else None,
            reply_to if _is_count(reply_to, MAX_ENVELOPE_INT) else None)


def _no_constants(name: str) -> Any:
    raise MessageError(f"invalid JSON: {name} is not a JSON number")


def _no_duplicates(pairs: List[Tuple[str, Any]]) -> Dict[str, Any]:
    obj: Dict[str, Any] = {}
    for key, value in pairs:
        if key in obj:
            raise MessageError(f'invalid JSON: field "{_preview(key)[1:-1]}" appears twice')
        obj[key] = value
    return obj


def decode(frame: Union[str, bytes, bytearray, memoryview]) -> Message:
    """Decode one websocket frame into a validated message; raises :class:`MessageError`
    (a :class:`~ros_hrc.errors.ProtocolError`) with a precise reason, and nothing else,
    whatever it is given. When the frame shows it is an ``error`` (even one that is not valid
    JSON), the exception's ``msg_type`` says so, so that it is not answered."""
    try:
        return _decode(frame)
    except MessageError as exc:
        if exc.msg_type is None and _looks_like_error(frame):
            exc.msg_type = Error.TYPE
        raise
    except Exception as exc:  # a safety net: no input may raise anything but MessageError
        raise MessageError(f"cannot decode the frame: {type(exc).__name__}: "
                           f"{str(exc)[:_MAX_ERROR_CHARS]}",
                           Error.TYPE if _looks_like_error(frame) else None) from None


def _too_large(frame: str, size: int) -> MessageError:
    """The rejection of a frame over :data:`MAX_MESSAGE_BYTES`, naming its type and envelope
    when they can be read cheaply (a frame of at most :data:`_ENVELOPE_READ_BYTES`): so that a
    too-large reply still fails the request it answers at once."""
    error = MessageError(f"message too large: {size} bytes, the limit is {MAX_MESSAGE_BYTES}")
    if size <= _ENVELOPE_READ_BYTES:
        try:
            obj = json.loads(frame, parse_constant=_no_constants)
        except (ValueError, RecursionError, MessageError):
            obj = None
        if isinstance(obj, dict):
            error.step, error.msg_id, error.epoch, error.reply_to = _envelope(obj)
            msg_type = obj.get("type")
            if isinstance(msg_type, str) and msg_type in MESSAGE_TYPES:
                error.msg_type = msg_type
    return error


#: Largest too-large frame whose envelope is still read (the transport reads no larger frame).
_ENVELOPE_READ_BYTES = 4 * MAX_MESSAGE_BYTES


def _looks_like_error(frame: Any) -> bool:
    """Whether a rejected frame says ``"type": "error"`` anywhere: then it is never answered,
    even when it could not be parsed (answering might start two peers answering each other)."""
    if isinstance(frame, (bytes, bytearray, memoryview)):
        frame = bytes(frame).decode("utf-8", "replace")
    return isinstance(frame, str) and _ERROR_TYPE.search(frame) is not None


def _decode(frame: Any) -> Message:
    if isinstance(frame, (bytes, bytearray, memoryview)):
        raise MessageError(f"binary frame of {len(frame)} bytes: this protocol uses text "
                           "frames, one JSON object each")
    if not isinstance(frame, str):
        raise MessageError(f"a frame must be text, got {type(frame).__name__}")
    # The transport bounds a frame's size, so measuring its UTF-8 length is cheap.
    try:
        size = len(frame.encode("utf-8"))
    except UnicodeEncodeError as exc:
        raise MessageError(f"the frame is not valid Unicode text: a lone surrogate at "
                           f"character {exc.start}") from None
    if size > MAX_MESSAGE_BYTES:
        raise _too_large(frame, size)
    try:
        obj = json.loads(frame, parse_constant=_no_constants, object_pairs_hook=_no_duplicates)
    except json.JSONDecodeError as exc:
        raise MessageError(f"invalid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") \
            from None
    except RecursionError:
        raise MessageError("invalid JSON: nested too deeply") from None
    except ValueError as exc:
        # int() refuses literals of more than 4300 digits (CPython's guard against
        # quadratic-time conversion).
        what = "a number has too many digits" if "digits" in str(exc) else str(exc)
        raise MessageError(f"invalid JSON: {what}"[:_MAX_ERROR_CHARS]) from None
    if _SURROGATE_ESCAPE.search(frame):
        # An escaped surrogate that is not half of a pair leaves a string no UTF-8 frame can
        # carry: the message could never be sent on. Rare, so only then check the whole value.
        try:
            json.dumps(obj, ensure_ascii=False).encode("utf-8")
        except UnicodeEncodeError:
            raise MessageError("invalid JSON: a \\u escape of a lone surrogate "
                               "(not valid Unicode)") from None
    return from_dict(obj)


def encode(msg: Message) -> str:
    """The text frame of a message: compact JSON, ``type`` first. Raises
    :class:`MessageError` if it is not a message, holds a non-JSON extra value, or is too large."""
    if not isinstance(msg, Message) or type(msg) is Message:
        raise MessageError(f"only protocol messages can be encoded, got {type(msg).__name__}")
    step = getattr(msg, "step", None)
    try:
        text = json.dumps(msg.to_dict(), separators=(",", ":"), ensure_ascii=False,
                          allow_nan=False)
        size = len(text.encode("utf-8"))
    except (TypeError, ValueError) as exc:  # UnicodeEncodeError is a ValueError
        raise MessageError(f"{msg.TYPE} message cannot be encoded: {exc}"[:_MAX_ERROR_CHARS],
                           msg.TYPE, step, msg.id, msg.epoch) from None
    if size > MAX_MESSAGE_BYTES:
        raise MessageError(f"{msg.TYPE} message too large: {size} bytes, the limit is "
                           f"{MAX_MESSAGE_BYTES}", msg.TYPE, step, msg.id, msg.epoch)
    return text


# -- replies ---------------------------------------------------------------------------------

def is_reply_to(reply: Message, request: Message) -> bool:
    """Whether ``reply`` answers ``request``.

    When the request has an ``id``: iff ``reply.reply_to == request.id`` and the reply is an
    ``ack``, ``error`` or ``decision``. Without an id (a peer that does not stamp one), a
    reply with a ``reply_to`` answers something else; otherwise the version 1 rules hold: an
    ``ack`` of its step (and type, when the ack names one; a request without a step, such as
    ``reset``, needs an ack naming its type), a ``decision`` of its step answering an
    ``observation``, or an ``error`` naming its step or, lacking a step, its type."""
    if not isinstance(reply, REPLY_TYPES):
        return False
    if request.id is not None:
        return reply.reply_to == request.id
    if reply.reply_to is not None:
        return False
    step = getattr(request, "step", None)
    if isinstance(reply, Ack):
        if step is None:  # e.g. a reset: only an ack that names it answers it
            return reply.of == request.type
        return reply.step == step and reply.of in (None, request.type)
    if isinstance(reply, Decision):
        return isinstance(request, Observation) and reply.step == step
    if reply.in_reply_to is not None and reply.in_reply_to != request.type:
        return False
    if reply.step is not None:
        return reply.step == step
    return reply.in_reply_to == request.type


M = TypeVar("M", bound=Message)


def as_reply(reply: M, request: Message) -> M:
    """``reply`` stamped as the answer to ``request``: its ``reply_to`` and ``epoch`` filled in
    from the request's ``id`` and ``epoch`` where ``reply`` leaves them ``None`` (a value the
    reply already has is kept). Returns ``reply`` itself when there is nothing to fill."""
    changes: Dict[str, Any] = {}
    if reply.reply_to is None and request.id is not None:
        changes["reply_to"] = request.id
    if reply.epoch is None and request.epoch is not None:
        changes["epoch"] = request.epoch
    return replace(reply, **changes) if changes else reply


def _clean_text(text: str, limit: int) -> str:
    """Cut to ``limit`` characters, control characters (line breaks too) made spaces, and make
    sure it encodes as UTF-8 (no lone surrogate): a text every receiver takes."""
    if len(text) > limit:
        text = text[:limit] + "..."
    text = _CONTROL.sub(" ", text)
    return text.encode("utf-8", "replace").decode("utf-8")


def reply_error(request: Message, message: str, code: str) -> Error:
    """The :class:`Error` answering ``request``: ``message`` for a person, ``code`` (an
    ``ERR_*`` constant) for a program; ``reply_to``, ``epoch``, ``in_reply_to`` and ``step``
    come from the request."""
    step = getattr(request, "step", None)
    return Error(message=_clean_text(str(message), _MAX_ERROR_CHARS) or code or "error",
                 code=code, in_reply_to=request.type or None,
                 step=step if _is_count(step, MAX_UINT32) else None,
                 reply_to=request.id, epoch=request.epoch)


def error_message(exc: BaseException, in_reply_to: Optional[str] = None,
                  step: Optional[int] = None, *, reply_to: Optional[int] = None,
                  epoch: Optional[int] = None, code: Optional[str] = None) -> Error:
    """The :class:`Error` answering ``exc``. A :class:`MessageError` fills in the rejected
    message's type, step, id (as ``reply_to``), epoch and code itself; another
    :class:`~ros_hrc.errors.ProtocolError` gets :data:`ERR_INVALID` and any other exception
    :data:`ERR_FAILED`, named by its class. Arguments given win. Never raises: values that
    cannot be sent are cut short or left out."""
    if isinstance(exc, MessageError):
        text = exc.reason
        in_reply_to = in_reply_to if in_reply_to is not None else exc.msg_type
        step = step if step is not None else exc.step
        reply_to = reply_to if reply_to is not None else exc.msg_id
        epoch = epoch if epoch is not None else exc.epoch
        code = code if code is not None else exc.code
    elif isinstance(exc, ProtocolError):
        text = str(exc)
        code = code if code is not None else ERR_INVALID
    else:
        text = f"{type(exc).__name__}: {exc}"
        code = code if code is not None else ERR_FAILED
    text = _clean_text(str(text) or type(exc).__name__, _MAX_ERROR_CHARS)
    # An echoed type name is whatever the peer sent: keep it short, and drop it if unusable,
    # so that building the reply can never fail.
    if not isinstance(in_reply_to, str) or not in_reply_to:
        in_reply_to = None
    else:
        in_reply_to = _clean_text(in_reply_to, _PREVIEW_CHARS)
    if not isinstance(code, str) or not code:
        code = None
    else:
        code = _clean_text(code, _PREVIEW_CHARS)
    return Error(message=text, in_reply_to=in_reply_to,
                 step=step if _is_count(step, MAX_UINT32) else None,
                 code=code,
                 reply_to=reply_to if _is_count(reply_to, MAX_ENVELOPE_INT) else None,
                 epoch=epoch if _is_count(epoch, MAX_UINT32) else None)


def error_reply(exc: BaseException, in_reply_to: Optional[str] = None,
                step: Optional[int] = None, *, reply_to: Optional[int] = None,
                epoch: Optional[int] = None, code: Optional[str] = None) -> str:
    """The encoded ``error`` frame answering ``exc`` (see :func:`error_message`); never raises."""
    return encode(error_message(exc, in_reply_to, step, reply_to=reply_to, epoch=epoch,
                                code=code))


# -- dispatch --------------------------------------------------------------------------------

#: ``handler(message, peer) -> reply or None``; ``peer`` is whatever the caller passes (the
#: transport's :class:`~ros_hrc.link.transport.Peer`, or ``None`` in a test).
MessageHandler = Callable[[Any, Any], Optional[Message]]


class DispatchTable:
    """Routes each message to the handler registered for its exact type: one table per
    adapter, and the adapter's whole contract in one place. Pure: no I/O, no locks (the
    server serialises its calls).

    ::

        table = DispatchTable("hrc_robot")
        table.on(Action, carry_out)          # or: @table.on(Action) above a function
        server = MessageServer(8080, table, name="hrc_robot")

    Calling ``table(msg, peer)`` runs ``handler(msg, peer)`` and returns its reply stamped
    with :func:`as_reply` (``reply_to`` and ``epoch`` of ``msg``). A type with no handler is
    refused with an :class:`Error` of code :data:`ERR_UNKNOWN_TYPE` (``"<name> does not take
    <type> messages"``), except an ``error``: an error is never answered with an error, so an
    unhandled one is dropped (``None``), and so is an ``error`` a handler returns for one. A
    handler's exception propagates (the server turns it into an ``error`` reply)."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._handlers: Dict[Type[Message], MessageHandler] = {}

    def on(self, cls: Type[Message], handler: Optional[MessageHandler] = None) -> Any:
        """Register ``handler`` for messages of type ``cls`` (a :class:`Message` subclass);
        without ``handler``, a decorator. One handler per type: registering a second raises
        ``ValueError``. Returns the handler."""
        if not (isinstance(cls, type) and issubclass(cls, Message) and cls is not Message):
            raise TypeError(f"{self.name}: handlers are registered for message classes, "
                            f"got {cls!r}")
        if handler is None:
            return lambda fn: self.on(cls, fn)
        if not callable(handler):
            raise TypeError(f"{self.name}: the handler for {cls.TYPE} must be callable")
        if cls in self._handlers:
            raise ValueError(f"{self.name}: a handler for {cls.TYPE} messages is already "
                             "registered")
        self._handlers[cls] = handler
        return handler

    def handles(self, cls: Type[Message]) -> bool:
        """Whether a handler is registered for ``cls``."""
        return cls in self._handlers

    @property
    def types(self) -> Tuple[str, ...]:
        """The wire names of the types this table takes, sorted."""
        return tuple(sorted(cls.TYPE for cls in self._handlers))

    def __call__(self, msg: Message, peer: Any = None) -> Optional[Message]:
        handler = self._handlers.get(type(msg))
        if handler is None:
            if isinstance(msg, Error):
                return None
            return reply_error(msg, f"{self.name} does not take {msg.type} messages",
                               ERR_UNKNOWN_TYPE)
        reply = handler(msg, peer)
        if reply is None or (isinstance(msg, Error) and isinstance(reply, Error)):
            return None
        return as_reply(reply, msg)

    def __repr__(self) -> str:
        return f"DispatchTable({self.name!r}: {', '.join(self.types) or 'nothing'})"
