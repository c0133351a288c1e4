"""The websocket protocol of DESIGN §6, Sans-I/O: messages, encoding, decoding, validation.

No socket here (and no websocket library): every function is pure and tested without a
network. :mod:`ros_hrc.link.transport` moves the text frames this module produces.

One text frame carries one JSON object with a ``"type"``. Message types and their fields
(``?`` marks an optional field, omitted from the JSON when ``None``)::

    hello        who, version                              first frame of a client, answered by
                                                           the server's own hello
    step         step, action, state, reward?, state_index?, belief? {state: p}, manual?
                                                           MDP -> human node (9090)
    observation  step, observation, bits, state            observer -> POMDP (7070)
    action       step, action, belief [p...], belief_states?, decision_ms?
                                                           POMDP -> robot node (8080)
    reset        reason?                                   start again from step 0
    next_state   state (int, or null: let the model choose)  human node -> MDP (9090)
    ack          step, of?, action?, success?, result?     "done"; may carry what was done
    error        message, in_reply_to?, step?              answer to a rejected message

Names never change; fields may grow: unknown extra fields are kept in ``Message.extra`` and
sent on again by :func:`encode`. ``docs/protocol.md`` is the full description.

Exception tree (the first two live in :mod:`ros_hrc.errors`)::

    LinkError
    └── ProtocolError          a message is malformed, of an unknown type or too large
        └── MessageError       raised here; carries .reason, and .msg_type / .step when they
                               could be read, so an error reply can say what it answers
"""
from __future__ import annotations

import json
import math
from dataclasses import MISSING, dataclass, field, fields
from typing import Any, ClassVar, Dict, List, Mapping, Optional, Sequence, Tuple, Type, Union

from ros_hrc.errors import ProtocolError

PROTOCOL_VERSION = 1
#: Largest encoded message, in UTF-8 bytes. A whole step (a belief over a few dozen states
#: and its names) is under 2 KiB; 64 KiB leaves room for growth and still bounds memory.
MAX_MESSAGE_BYTES = 64 * 1024
#: A belief must sum to one within this; it tolerates beliefs printed with 6 significant
#: digits by a foreign (e.g. C++) solver, and still catches an unnormalised one.
BELIEF_TOLERANCE = 1e-4
#: Bit patterns of an observation (DESIGN §4: six bits).
MAX_BITS = 63
# Error texts quote at most this much of an offending value, so a reply stays small.
_PREVIEW_CHARS = 40
_MAX_ERROR_CHARS = 1000


class MessageError(ProtocolError):
    """A frame was rejected. ``reason`` says why; ``msg_type`` and ``step`` say which
    message it was, when they could be read (else ``None``)."""

    def __init__(self, reason: str, msg_type: Optional[str] = None,
                 step: Optional[int] = None) -> None:
        super().__init__(reason)
        self.reason = reason
        self.msg_type = msg_type
        self.step = step


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
        text = repr(value)
    return text if len(text) <= _PREVIEW_CHARS else text[:_PREVIEW_CHARS] + "..."


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
            raise self.fail(name, f"must be {bounds}, got {value}")
        return value

    def number(self, name: str, value: Any, minimum: Optional[float] = None) -> float:
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise self.fail(name, f"must be a number, {self._got(value)}")
        if not math.isfinite(value):
            raise self.fail(name, f"must be finite, got {value}")
        if minimum is not None and value < minimum:
            raise self.fail(name, f"must be >= {minimum}, got {value}")
        return float(value)

    def text(self, name: str, value: Any) -> str:
        if not isinstance(value, str):
            raise self.fail(name, f"must be a string, {self._got(value)}")
        if not value:
            raise self.fail(name, "must not be empty")
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
            probs[key] = self.probability(f"{name}.{key}", p)
        self._probability_sum(name, math.fsum(probs.values()))
        return probs

    def probability(self, name: str, value: Any) -> float:
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise self.fail(name, f"must be a number, {self._got(value)}")
        if not math.isfinite(value):
            raise self.fail(name, f"must be finite, got {value}")
        if value < 0:
            raise self.fail(name, f"must not be negative, got {value}")
        return float(value)

    def names(self, name: str, value: Any) -> Tuple[str, ...]:
        if not isinstance(value, (list, tuple)):
            raise self.fail(name, f"must be an array of strings, {self._got(value)}")
        items = tuple(self.text(f"{name}[{i}]", v) for i, v in enumerate(value))
        if len(set(items)) != len(items):
            raise self.fail(name, "must not repeat a name")
        return items


_FIELD_CACHE: Dict[type, Tuple[Tuple[str, bool], ...]] = {}


def _wire_fields(cls: type) -> Tuple[Tuple[str, bool], ...]:
    """(name, required) of a message class's wire fields, in order; cached, since
    ``dataclasses.fields`` is the slowest part of building a message."""
    cached = _FIELD_CACHE.get(cls)
    if cached is None:
        cached = tuple((f.name, f.default is MISSING and f.default_factory is MISSING)
                       for f in fields(cls) if f.name != "extra")
        _FIELD_CACHE[cls] = cached
    return cached


@dataclass(frozen=True)
class Message:
    """Base of every message. ``type`` is the wire name; ``extra`` holds fields this version
    does not know (kept, and sent on again by :func:`encode`).

    Constructing a message validates it (raising :class:`MessageError`), so an invalid
    message can be neither sent nor received."""

    TYPE: ClassVar[str] = ""
    extra: Mapping[str, Any] = field(default_factory=dict, kw_only=True)

    def __post_init__(self) -> None:
        check = _Checker(self.TYPE)
        if not isinstance(self.extra, Mapping):
            raise check.fail("extra", f"must be a mapping, got {_kind(self.extra)}")
        clash = sorted(name for name in self.extra
                       if name == "type" or any(name == f for f, _ in _wire_fields(type(self))))
        if clash:
            raise check.fail(clash[0], "is a named field and cannot also be an extra field")
        object.__setattr__(self, "extra", dict(self.extra))
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
        ``next_state.state``), optional fields only when set, then the extras."""
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
    version it speaks. The server answers with a hello of its own."""

    TYPE: ClassVar[str] = "hello"
    who: str
    version: int = PROTOCOL_VERSION

    def _validate(self, check: _Checker) -> None:
        self._set("who", check.text("who", self.who))
        self._set("version", check.integer("version", self.version, minimum=1))


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
        self._set("step", check.integer("step", self.step))
        self._set("action", check.text("action", self.action))
        self._set("state", check.text("state", self.state))
        if self.reward is not None:
            self._set("reward", check.number("reward", self.reward))
        if self.state_index is not None:
            self._set("state_index", check.integer("state_index", self.state_index))
        if self.belief is not None:
            self._set("belief", check.belief_map("belief", self.belief))
        if self.manual is not None:
            self._set("manual", check.flag("manual", self.manual))


@dataclass(frozen=True)
class Observation(Message):
    """Observer -> POMDP: the robot's observation after step ``step`` (its name, e.g. ``O35``,
    and the raw predicate ``bits`` 0..63, which may differ when the pattern was mapped to the
    nearest legal one) and the robot model's true ``state`` (e.g. ``S2``, for reporting)."""

    TYPE: ClassVar[str] = "observation"
    step: int
    observation: str
    bits: int
    state: str

    def _validate(self, check: _Checker) -> None:
        self._set("step", check.integer("step", self.step))
        self._set("observation", check.text("observation", self.observation))
        self._set("bits", check.integer("bits", self.bits, maximum=MAX_BITS))
        self._set("state", check.text("state", self.state))


@dataclass(frozen=True)
class Action(Message):
    """POMDP -> robot node: the robot's ``action`` for step ``step`` and its ``belief`` (a
    probability per model state, in model order). Optional: ``belief_states`` (the states'
    names, same length) and ``decision_ms`` (planning time)."""

    TYPE: ClassVar[str] = "action"
    step: int
    action: str
    belief: Sequence[float]
    belief_states: Optional[Sequence[str]] = None
    decision_ms: Optional[float] = None

    def _validate(self, check: _Checker) -> None:
        self._set("step", check.integer("step", self.step))
        self._set("action", check.text("action", self.action))
        self._set("belief", check.belief_list("belief", self.belief))
        if self.belief_states is not None:
            names = check.names("belief_states", self.belief_states)
            if len(names) != len(self.belief):
                raise check.fail("belief_states", f"has {len(names)} names for "
                                                  f"{len(self.belief)} probabilities")
            self._set("belief_states", names)
        if self.decision_ms is not None:
            self._set("decision_ms", check.number("decision_ms", self.decision_ms, minimum=0.0))


@dataclass(frozen=True)
class Reset(Message):
    """Start again: world, beliefs and step counter go back to step 0. ``reason`` is for logs."""

    TYPE: ClassVar[str] = "reset"
    reason: Optional[str] = None

    def _validate(self, check: _Checker) -> None:
        if self.reason is not None:
            self._set("reason", check.text("reason", self.reason))


@dataclass(frozen=True)
class NextState(Message):
    """Human node -> MDP: the human's next state by number (0..7 for the seed's models), or
    ``None`` (JSON null) to let the model choose. The key is required even when null."""

    TYPE: ClassVar[str] = "next_state"
    state: Optional[int]

    def _validate(self, check: _Checker) -> None:
        if self.state is not None:
            self._set("state", check.integer("state", self.state))


@dataclass(frozen=True)
class Ack(Message):
    """Step ``step`` is done. ``of`` names the acknowledged type when it is not obvious (a
    reset is acknowledged with ``step=0, of="reset"``); ``action``, ``success`` and ``result``
    carry what was done (the human node acks the MDP with the robot's action)."""

    TYPE: ClassVar[str] = "ack"
    step: int
    of: Optional[str] = None
    action: Optional[str] = None
    success: Optional[bool] = None
    result: Optional[str] = None

    def _validate(self, check: _Checker) -> None:
        self._set("step", check.integer("step", self.step))
        if self.of is not None:
            self._set("of", check.text("of", self.of))
        if self.action is not None:
            self._set("action", check.text("action", self.action))
        if self.success is not None:
            self._set("success", check.flag("success", self.success))
        if self.result is not None and not isinstance(self.result, str):
            raise check.fail("result", f"must be a string, got {_kind(self.result)}")


@dataclass(frozen=True)
class Error(Message):
    """The answer to a message that was rejected or failed: ``message`` says why;
    ``in_reply_to`` is the rejected message's type and ``step`` its step, when known.
    A message, not an exception: :class:`MessageError` is the exception."""

    TYPE: ClassVar[str] = "error"
    message: str
    in_reply_to: Optional[str] = None
    step: Optional[int] = None

    def _validate(self, check: _Checker) -> None:
        self._set("message", check.text("message", self.message))
        if self.in_reply_to is not None:
            self._set("in_reply_to", check.text("in_reply_to", self.in_reply_to))
        if self.step is not None:
            self._set("step", check.integer("step", self.step))


#: Wire name -> message class.
MESSAGE_TYPES: Dict[str, Type[Message]] = {
    cls.TYPE: cls for cls in (Hello, Step, Observation, Action, Reset, NextState, Ack, Error)
}


def from_dict(obj: Any) -> Message:
    """Validate a decoded JSON value and build its message; raises :class:`MessageError`."""
    if not isinstance(obj, dict):
        raise MessageError(f"a message must be a JSON object, got {_kind(obj)}")
    if "type" not in obj:
        raise MessageError('missing field "type"')
    msg_type = obj["type"]
    if not isinstance(msg_type, str):
        raise MessageError(f'field "type" must be a string, got {_kind(msg_type)} '
                           f"{_preview(msg_type)}")
    step = obj.get("step")
    step = step if isinstance(step, int) and not isinstance(step, bool) and step >= 0 else None
    cls = MESSAGE_TYPES.get(msg_type)
    if cls is None:
        raise MessageError(f"unknown message type {_preview(msg_type)} (known: "
                           f"{', '.join(sorted(MESSAGE_TYPES))})", msg_type, step)
    kwargs: Dict[str, Any] = {}
    for name, required in _wire_fields(cls):
        if name in obj:
            kwargs[name] = obj[name]
        elif required:
            raise MessageError(f'{msg_type} message: missing field "{name}"', msg_type, step)
    extra = {k: v for k, v in obj.items() if k != "type" and k not in kwargs}
    try:
        return cls(**kwargs, extra=extra)
    except MessageError as exc:
        exc.step = step
        raise


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
    (a :class:`~ros_hrc.errors.ProtocolError`) with a precise reason."""
    if isinstance(frame, (bytes, bytearray, memoryview)):
        raise MessageError(f"binary frame of {len(frame)} bytes: this protocol uses text "
                           "frames, one JSON object each")
    if not isinstance(frame, str):
        raise MessageError(f"a frame must be text, got {type(frame).__name__}")
    # The transport bounds a frame's size, so measuring its UTF-8 length is cheap.
    size = len(frame.encode("utf-8", "surrogatepass"))
    if size > MAX_MESSAGE_BYTES:
        raise MessageError(f"message too large: {size} bytes, the limit is {MAX_MESSAGE_BYTES}")
    try:
        obj = json.loads(frame, parse_constant=_no_constants, object_pairs_hook=_no_duplicates)
    except json.JSONDecodeError as exc:
        raise MessageError(f"invalid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") \
            from None
    except RecursionError:
        raise MessageError("invalid JSON: nested too deeply") from None
    return from_dict(obj)


def encode(msg: Message) -> str:
    """The text frame of a message: compact JSON, ``type`` first. Raises
    :class:`MessageError` if it is not a message, holds a non-JSON extra value, or is too large."""
    if not isinstance(msg, Message) or type(msg) is Message:
        raise MessageError(f"only protocol messages can be encoded, got {type(msg).__name__}")
    try:
        text = json.dumps(msg.to_dict(), separators=(",", ":"), ensure_ascii=False,
                          allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise MessageError(f"{msg.TYPE} message cannot be encoded: {exc}", msg.TYPE,
                           getattr(msg, "step", None)) from None
    size = len(text.encode("utf-8"))
    if size > MAX_MESSAGE_BYTES:
        raise MessageError(f"{msg.TYPE} message too large: {size} bytes, the limit is "
                           f"{MAX_MESSAGE_BYTES}", msg.TYPE, getattr(msg, "step", None))
    return text


def error_message(exc: BaseException, in_reply_to: Optional[str] = None,
                  step: Optional[int] = None) -> Error:
    """The :class:`Error` answering ``exc``. A :class:`MessageError` fills in the rejected
    message's type and step itself; other exceptions are named by their class."""
    if isinstance(exc, MessageError):
        text = exc.reason
        in_reply_to = in_reply_to if in_reply_to is not None else exc.msg_type
        step = step if step is not None else exc.step
    elif isinstance(exc, ProtocolError):
        text = str(exc)
    else:
        text = f"{type(exc).__name__}: {exc}"
    text = text or type(exc).__name__
    if len(text) > _MAX_ERROR_CHARS:
        text = text[:_MAX_ERROR_CHARS] + "..."
    # An echoed type name is whatever the peer sent: keep it short, and drop it if unusable,
    # so that building the reply can never fail.
    if not isinstance(in_reply_to, str) or not in_reply_to:
        in_reply_to = None
    elif len(in_reply_to) > _PREVIEW_CHARS:
        in_reply_to = in_reply_to[:_PREVIEW_CHARS] + "..."
    if not isinstance(step, int) or isinstance(step, bool) or step < 0:
        step = None
    return Error(message=text, in_reply_to=in_reply_to, step=step)


def error_reply(exc: BaseException, in_reply_to: Optional[str] = None,
                step: Optional[int] = None) -> str:
    """The encoded ``error`` frame answering ``exc`` (see :func:`error_message`); never raises."""
    return encode(error_message(exc, in_reply_to, step))
