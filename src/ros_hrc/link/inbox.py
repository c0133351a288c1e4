"""What a client has received and what it waits for: the messages not yet taken, and the
requests in flight, each matched to its answer by correlation id. Sans-I/O: the client's
reader thread delivers every message here and its callers take them; the client's condition
guards every call (nothing here locks or waits).

An answer is taken only when it names its request in ``reply_to`` and carries the request's
epoch; an answer that fails those rules, or one the reader could not even decode, fails its
request at once (:meth:`Inbox.rejection`) rather than leaving it to wait out its timeout. A late
answer to a request that already failed is dropped when it comes.
"""
from __future__ import annotations

import collections
import itertools
import logging
from dataclasses import replace
from typing import Callable, Dict, List, Optional, Tuple

from ros_hrc.link.messages import REPLY_TYPES, Error, Message
from ros_hrc.link.replies import is_reply_to

# How many request ids that failed are remembered, so their late answers are dropped.
_ABANDONED_IDS = 1024


class Inbox:
    """The messages a client received and its requests in flight. ``name`` and ``log`` say
    whose, in the lines it logs about answers it refuses or drops."""

    def __init__(self, name: str, log: logging.Logger) -> None:
        self._name = name
        self._log = log
        self._messages: List[Message] = []
        self._next_id = itertools.count(1)
        self._pending: Dict[int, int] = {}  # id of a request in flight -> how many wait on it
        self._requests: Dict[int, Message] = {}   # id of a request in flight -> the request
        self._rejected: Dict[int, str] = {}   # id of a request in flight -> why its answer failed
        self._abandoned: "collections.OrderedDict[int, None]" = collections.OrderedDict()

    def next_id(self) -> int:
        """A fresh correlation id (a counter of this client's own)."""
        return next(self._next_id)

    def open_request(self, msg: Message) -> Message:
        """Wait for the answer to ``msg`` from now on; returns it stamped with a fresh ``id``
        when it has none."""
        if msg.id is None:
            msg = replace(msg, id=self.next_id())
        self._pending[msg.id] = self._pending.get(msg.id, 0) + 1
        self._requests[msg.id] = msg
        return msg

    def close_request(self, request_id: int, answered: bool) -> None:
        """One wait for the answer to request ``request_id`` ended; an answer that was not
        taken is dropped when it comes."""
        left = self._pending.pop(request_id) - 1
        if left:
            self._pending[request_id] = left
            return
        self._requests.pop(request_id, None)
        self._rejected.pop(request_id, None)
        if not answered:
            self._abandoned[request_id] = None
            while len(self._abandoned) > _ABANDONED_IDS:
                self._abandoned.popitem(last=False)

    def rejection(self, request_id: Optional[int]) -> Optional[str]:
        """Why the answer to request ``request_id`` was refused (``None``: it was not)."""
        return None if request_id is None else self._rejected.get(request_id)

    def take(self, match: Optional[Callable[[Message], bool]],
             own_id: Optional[int]) -> Optional[Message]:
        """The oldest message for which ``match`` is true (any, without one), leaving the
        others in order; an answer that a request in flight waits for is left to it (unless
        ``own_id`` names that request). ``None`` when there is none."""
        for i, msg in enumerate(self._messages):
            if (msg.reply_to is not None and msg.reply_to in self._pending
                    and msg.reply_to != own_id):
                continue  # kept for the request that waits for it
            if match is None or match(msg):
                return self._messages.pop(i)
        return None

    def drain(self) -> List[Message]:
        """Take every message waiting (e.g. stale ones after a reset)."""
        taken, self._messages = self._messages, []
        return taken

    def deliver(self, msg: Message) -> bool:
        """A message came: keep it, or refuse it as the answer to a request in flight, or
        drop it as the late answer to a request that failed. Whether anything changed that a
        waiter should see."""
        if msg.reply_to is not None and msg.reply_to in self._abandoned:
            del self._abandoned[msg.reply_to]
            self._log.debug("%s: dropped a late %s answering request %d", self._name,
                            msg.type, msg.reply_to)
            return False
        wrong = self._wrong_answer(msg)
        if wrong is not None:
            request_id, why = wrong
            self._log.warning("%s: %s", self._name, why)
            self._rejected[request_id] = why
            return True
        self._messages.append(msg)
        return True

    def reject(self, request_id: int, why: str) -> bool:
        """Fail the request in flight ``request_id`` at once with ``why`` (its answer came
        and could not be read); whether it was in flight."""
        if request_id not in self._requests:
            return False
        self._rejected[request_id] = why
        return True

    def _wrong_answer(self, msg: Message) -> Optional[Tuple[int, str]]:
        """(request id, why) when ``msg`` answers a request in flight but may not be taken
        as its answer: of another epoch than the request's, or (a reply without ``reply_to``)
        answering it only by the version 1 rules."""
        if not isinstance(msg, REPLY_TYPES):
            return None
        if msg.reply_to is not None:
            request = self._requests.get(msg.reply_to)
            if request is None or request.epoch is None or msg.epoch == request.epoch:
                return None
            return msg.reply_to, (
                f"the {msg.type} answering {request.type} {msg.reply_to} is of epoch "
                f"{msg.epoch}, the request of epoch {request.epoch}: a reply carries its "
                "request's epoch, so it was dropped")
        for request_id, request in self._requests.items():
            if is_reply_to(msg, replace(request, id=None)):
                return request_id, (
                    f"a {msg.type} answered {request.type} {request_id} without reply_to "
                    f"(version 2 replies carry their request's id): dropped"
                    + (f" ({msg.message})" if isinstance(msg, Error) else ""))
        return None
