"""The websocket protocol of DESIGN §6 (version 2), Sans-I/O, in one import: messages,
encoding and decoding, validation, reply matching and dispatch. docs/protocol.md describes it.

No socket here (and no websocket library): every function is pure and tested without a
network. :mod:`ros_hrc.link.transport` moves the text frames it produces. The protocol lives in
files of one job each; this module gathers what a program speaking it imports:

  ros_hrc.link.messages    the message types (hello, step, reaction, observation, decision,
                           action, reset, next_state, ack, error, task_end,
                           task_report) and their envelope
  ros_hrc.link.validation  what each field may hold, and the checker every message uses
  ros_hrc.link.refusals    the error codes of an ``error`` and MessageError
  ros_hrc.link.codec       decode / encode: text frames to messages and back
  ros_hrc.link.replies     reply matching, error replies and the DispatchTable
"""
from ros_hrc.link.codec import MAX_MESSAGE_BYTES, decode, encode, from_dict
from ros_hrc.link.messages import (ENVELOPE_FIELDS, MESSAGE_TYPES, PROTOCOL_VERSION,
                                   REPLY_TYPES, Ack, Action, Configure, Decision, Error, Hello,
                                   Message,
                                   NextState, Observation, Reaction, Reset, Step, TaskEnd,
                                   TaskReport)
from ros_hrc.link.refusals import (ERR_BUSY, ERR_EPISODE_OVER, ERR_FAILED, ERR_INVALID,
                                   ERR_NOT_READY, ERR_REFUSED, ERR_SEAT_TAKEN, ERR_STALE,
                                   ERR_UNAUTHORIZED, ERR_UNKNOWN_TYPE, ERR_VERSION, ERROR_CODES,
                                   MessageError)
from ros_hrc.link.replies import (DispatchTable, MessageHandler, as_reply, error_message,
                                  error_reply, is_reply_to, reply_error)
from ros_hrc.link.validation import (AUTH_HEX_CHARS, BELIEF_TOLERANCE, MAX_BITS,
                                     MAX_ENVELOPE_INT, MAX_NAME_CHARS, MAX_SIGNATURE_CODE,
                                     MAX_STATE_INDEX,
                                     MAX_TEXT_CHARS, MAX_UINT32, MAX_VERSION, NONCE_HEX_RANGE)

__all__ = [
    # messages
    "PROTOCOL_VERSION", "ENVELOPE_FIELDS", "MESSAGE_TYPES", "REPLY_TYPES", "Message", "Hello",
    "Step", "Reaction", "Observation", "Decision", "Action", "Reset", "NextState", "Ack",
    "Error", "TaskEnd", "TaskReport", "Configure",
    # what a field may hold
    "BELIEF_TOLERANCE", "MAX_BITS", "MAX_ENVELOPE_INT", "MAX_UINT32", "MAX_STATE_INDEX",
    "MAX_SIGNATURE_CODE",
    "MAX_VERSION", "MAX_NAME_CHARS", "MAX_TEXT_CHARS", "NONCE_HEX_RANGE", "AUTH_HEX_CHARS",
    # refusals
    "ERR_STALE", "ERR_BUSY", "ERR_SEAT_TAKEN", "ERR_INVALID", "ERR_UNKNOWN_TYPE", "ERR_REFUSED",
    "ERR_FAILED", "ERR_VERSION", "ERR_EPISODE_OVER", "ERR_NOT_READY", "ERR_UNAUTHORIZED",
    "ERROR_CODES", "MessageError",
    # frames
    "MAX_MESSAGE_BYTES", "decode", "encode", "from_dict",
    # replies and dispatch
    "is_reply_to", "as_reply", "reply_error", "error_message", "error_reply", "MessageHandler",
    "DispatchTable",
]
