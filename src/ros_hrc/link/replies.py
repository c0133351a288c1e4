"""Replies: which message answers which request, the ``error`` that answers a rejected or
failed one, and :class:`DispatchTable`, which routes each message to its handler by type.
Pure: no socket here.

:func:`is_reply_to` says whether a message answers a request (by ``reply_to`` when the request
has an ``id``); :func:`as_reply` stamps a reply with its request's ``id`` and ``epoch``;
:func:`reply_error` builds the :class:`~ros_hrc.link.messages.Error` answering a request and
:func:`error_message` the one answering an exception. An ``error`` is never answered with an
``error``.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any, Callable, Dict, Optional, Tuple, Type, TypeVar

from ros_hrc.errors import ProtocolError
from ros_hrc.link.codec import MAX_ERROR_CHARS, encode
from ros_hrc.link.messages import (REPLY_TYPES, Ack, Decision, Error, Message, Observation,
                                   TaskEnd, TaskReport)
from ros_hrc.link.refusals import ERR_FAILED, ERR_INVALID, ERR_UNKNOWN_TYPE, MessageError
from ros_hrc.link.validation import (CONTROL_CHARACTERS, MAX_ENVELOPE_INT, MAX_UINT32,
                                     PREVIEW_CHARS, is_count)


def is_reply_to(reply: Message, request: Message) -> bool:
    """Whether ``reply`` answers ``request``.

    When the request has an ``id``: iff ``reply.reply_to == request.id`` and the reply is an
    ``ack``, ``error``, ``decision`` or ``task_report``. Without an id (a peer that does not stamp one), a
    reply with a ``reply_to`` answers something else; otherwise the version 1 rules hold: an
    ``ack`` of its step (and type, when the ack names one; a request without a step, such as
    ``reset``, needs an ack naming its type), a ``decision`` of its step answering an
    ``observation``, a ``task_report`` answering a ``task_end``, or an ``error`` naming its step or, lacking a step, its type."""
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
    if isinstance(reply, TaskReport):
        return isinstance(request, TaskEnd)
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
    text = CONTROL_CHARACTERS.sub(" ", text)
    return text.encode("utf-8", "replace").decode("utf-8")


def reply_error(request: Message, message: str, code: str) -> Error:
    """The :class:`Error` answering ``request``: ``message`` for a person, ``code`` (an
    ``ERR_*`` constant) for a program; ``reply_to``, ``epoch``, ``in_reply_to`` and ``step``
    come from the request."""
    step = getattr(request, "step", None)
    return Error(message=_clean_text(str(message), MAX_ERROR_CHARS) or code or "error",
                 code=code, in_reply_to=request.type or None,
                 step=step if is_count(step, MAX_UINT32) else None,
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
    text = _clean_text(str(text) or type(exc).__name__, MAX_ERROR_CHARS)
    # An echoed type name is whatever the peer sent: keep it short, and drop it if unusable,
    # so that building the reply can never fail.
    if not isinstance(in_reply_to, str) or not in_reply_to:
        in_reply_to = None
    else:
        in_reply_to = _clean_text(in_reply_to, PREVIEW_CHARS)
    if not isinstance(code, str) or not code:
        code = None
    else:
        code = _clean_text(code, PREVIEW_CHARS)
    return Error(message=text, in_reply_to=in_reply_to,
                 step=step if is_count(step, MAX_UINT32) else None,
                 code=code,
                 reply_to=reply_to if is_count(reply_to, MAX_ENVELOPE_INT) else None,
                 epoch=epoch if is_count(epoch, MAX_UINT32) else None)


def error_reply(exc: BaseException, in_reply_to: Optional[str] = None,
                step: Optional[int] = None, *, reply_to: Optional[int] = None,
                epoch: Optional[int] = None, code: Optional[str] = None) -> str:
    """The encoded ``error`` frame answering ``exc`` (see :func:`error_message`); never raises."""
    return encode(error_message(exc, in_reply_to, step, reply_to=reply_to, epoch=epoch,
                                code=code))


#: ``handler(message, peer) -> reply or None``; ``peer`` is whatever the caller passes (the
#: transport's :class:`~ros_hrc.link.transport.Peer`, or ``None`` in a test).
MessageHandler = Callable[[Any, Any], Optional[Message]]


class DispatchTable:
    """Routes each message to the handler registered for its exact type: one table per
    adapter, and the adapter's whole contract in one place. Pure: no I/O, no locks (the
    server serialises its calls).

    ::

        table = DispatchTable("despot_pomdp")
        table.on(Observation, decide)        # or: @table.on(Observation) above a function
        server = MessageServer(7070, table, name="despot_pomdp")

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
