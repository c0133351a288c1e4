"""Text frames to messages and back: :func:`decode` turns whatever a peer sends into a
validated message or a :class:`~ros_hrc.link.refusals.MessageError` with a precise reason
(and nothing else, whatever it is given); :func:`encode` writes the one text frame of a
message. Pure: no socket here.

One text frame carries one JSON object with a ``"type"``. The JSON is strict: a key appears
once, numbers are finite (``NaN``, ``Infinity`` and overflowing literals are refused), text is
valid Unicode, and no frame is larger than :data:`MAX_MESSAGE_BYTES`.
"""
from __future__ import annotations

import json
import re
from typing import Any, Dict, List, Optional, Tuple, Union

from ros_hrc.link.messages import MESSAGE_TYPES, Error, Message, wire_fields
from ros_hrc.link.refusals import ERR_UNKNOWN_TYPE, MessageError
from ros_hrc.link.validation import (MAX_ENVELOPE_INT, MAX_UINT32, is_count, kind_of,
                                     preview)

#: Largest encoded message, in UTF-8 bytes. A whole step (a belief over a few dozen states
#: and its names) is under 2 KiB; 64 KiB leaves room for growth and still bounds memory.
MAX_MESSAGE_BYTES = 64 * 1024
#: Longest error text, in characters: a rejection's reason quotes what it can of a frame.
MAX_ERROR_CHARS = 1000
# A JSON escape of a UTF-16 surrogate: the only way a parsed string can hold a lone one.
_SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F]")
# How a frame that cannot be parsed still shows it is an error (never answered).
_ERROR_TYPE = re.compile(r'"type"\s*:\s*"error"')


def from_dict(obj: Any) -> Message:
    """Validate a decoded JSON value and build its message; raises :class:`MessageError`."""
    if not isinstance(obj, dict):
        raise MessageError(f"a message must be a JSON object, got {kind_of(obj)}")
    # What the rejection can name, read before anything else can fail.
    step, msg_id, epoch, reply_to = _envelope(obj)
    if "type" not in obj:
        raise MessageError('missing field "type"', None, step, msg_id, epoch,
                           reply_to=reply_to)
    msg_type = obj["type"]
    if not isinstance(msg_type, str):
        raise MessageError(f'field "type" must be a string, got {kind_of(msg_type)} '
                           f"{preview(msg_type)}", None, step, msg_id, epoch,
                           reply_to=reply_to)
    cls = MESSAGE_TYPES.get(msg_type)
    if cls is None:
        raise MessageError(f"unknown message type {preview(msg_type)} (known: "
                           f"{', '.join(sorted(MESSAGE_TYPES))})", msg_type, step, msg_id, epoch,
                           code=ERR_UNKNOWN_TYPE, reply_to=reply_to)
    kwargs: Dict[str, Any] = {}
    for name, required in wire_fields(cls):
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
    return (step if is_count(step, MAX_UINT32) else None,
            msg_id if is_count(msg_id, MAX_ENVELOPE_INT) else None,
            epoch if is_count(epoch, MAX_UINT32) else None,
            reply_to if is_count(reply_to, MAX_ENVELOPE_INT) else None)


def _no_constants(name: str) -> Any:
    raise MessageError(f"invalid JSON: {name} is not a JSON number")


def _no_duplicates(pairs: List[Tuple[str, Any]]) -> Dict[str, Any]:
    obj: Dict[str, Any] = {}
    for key, value in pairs:
        if key in obj:
            raise MessageError(f'invalid JSON: field "{preview(key)[1:-1]}" appears twice')
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
                           f"{str(exc)[:MAX_ERROR_CHARS]}",
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
        raise MessageError(f"invalid JSON: {what}"[:MAX_ERROR_CHARS]) from None
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
        raise MessageError(f"{msg.TYPE} message cannot be encoded: {exc}"[:MAX_ERROR_CHARS],
                           msg.TYPE, step, msg.id, msg.epoch) from None
    if size > MAX_MESSAGE_BYTES:
        raise MessageError(f"{msg.TYPE} message too large: {size} bytes, the limit is "
                           f"{MAX_MESSAGE_BYTES}", msg.TYPE, step, msg.id, msg.epoch)
    return text
