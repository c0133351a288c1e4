"""How a message is refused: the error codes an ``error`` message carries, and
:class:`MessageError`, the exception of a frame that was rejected.

Exception tree (the first two live in :mod:`ros_hrc.errors`)::

    LinkError
    └── ProtocolError          a message is malformed, of an unknown type or too large
        └── MessageError       carries .reason and .code, and .msg_type / .step / .msg_id /
                               .epoch / .reply_to when they could be read, so an error reply
                               can say what it answers
"""
from __future__ import annotations

from typing import FrozenSet, Optional

from ros_hrc.errors import ProtocolError

# Error codes (Error.code): machine-readable and stable; Error.message is for people.
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

