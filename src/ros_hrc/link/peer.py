"""One client connected to a :class:`~ros_hrc.link.server.MessageServer`, as the server's
handler sees it: :class:`Peer`, with an outbox that a writer thread of its own drains, so that a
send never blocks the server.

A client that reads slowly is served, however many frames wait for it; one that stops reading
is cut off by time: when its outbox has not moved for ``link_read_timeout`` seconds (the
server's watchdog, :meth:`Peer._stalled_for`). The outbox's size in bytes is the last resort
(:data:`OUTBOX_BYTES`), a bound on the memory one client can hold, never the usual way out."""
from __future__ import annotations

import collections
import itertools
import logging
import socket
import threading
import time
from typing import Any, Callable, Deque, Optional, Tuple

from websockets.exceptions import ConnectionClosed
from websockets.frames import CloseCode
from websockets.sync.server import ServerConnection

from ros_hrc.link.codec import encode
from ros_hrc.link.messages import Message
from ros_hrc.link.session import CLOSE_REFUSED, Session
from ros_hrc import settings

#: The bytes (UTF-8) a peer's outbox may hold: one frame more and the peer is disconnected.
#: A memory bound, the last resort: a client that reads, however slowly, is never near it
#: (the fuzzer's 20,000 replies are about 3 MB), and one that stops reading is cut off by
#: time first unless it is flooded. The same bound as 1024 frames of the largest message.
OUTBOX_BYTES = 64 * 1024 * 1024
#: Seconds a peer's outbox may go without a frame sent before the peer is disconnected as not
#: reading: the launch's ``link_read_timeout`` (settings.py).
READ_TIMEOUT = settings.default("link_read_timeout")
# A websocket close reason is at most 123 bytes of UTF-8.
_MAX_CLOSE_REASON = 123

_log = logging.getLogger("ros_hrc.link")


def _close_reason(reason: str) -> str:
    data = reason.encode("utf-8", "replace")[:_MAX_CLOSE_REASON]
    return data.decode("utf-8", "ignore")


class Peer:
    """One client connected to a :class:`~ros_hrc.link.server.MessageServer`, as its handler
    sees it.

    ``who`` is the name the client gave in its hello (``"?"`` before that), ``address`` its
    (host, port), ``session`` its handshake. Calling the peer, or :meth:`send`, queues a frame
    for that client only and returns at once: a writer thread of the peer's own sends the
    queue in order.

    Why an outbox of our own: a send on websockets' threaded connection blocks in the socket
    (holding the connection's lock) for as long as the peer does not read, and the library
    has no send timeout or write limit there. Queuing here keeps every handler and callback
    from ever waiting on one peer. A peer that does not read is disconnected when its outbox
    has not moved for the server's ``read_timeout`` (the server's watchdog asks
    :meth:`_stalled_for`), or, the last resort, when it holds ``outbox_bytes``."""

    _ids = itertools.count(1)

    def __init__(self, connection: ServerConnection, session: Session, *,
                 server_name: str = "server", outbox_bytes: int = OUTBOX_BYTES,
                 log: logging.Logger = _log,
                 on_writer_exit: Optional[Callable[["Peer"], None]] = None) -> None:
        self.id = next(Peer._ids)
        self.session = session
        try:
            self.address: Tuple[Any, ...] = tuple(connection.remote_address or ())
        except OSError:  # the socket already failed (e.g. a first frame over the limit)
            self.address = ()
        self._connection = connection
        self._server_name = server_name
        self._limit = max(1, int(outbox_bytes))
        self._log = log
        self._on_writer_exit = on_writer_exit
        self._cond = threading.Condition()     # guards the six below
        self._outbox: Deque[Tuple[str, int]] = collections.deque()   # frames and their bytes
        self._queued_bytes = 0
        self._open = True                      # takes new frames
        self._close_args: Optional[Tuple[int, str]] = None  # close() was called
        self._gone = False                     # connection lost or aborted: send nothing more
        self._aborted = False
        # When the outbox last moved (a frame went out, or the first one came into an empty
        # outbox); None while nothing waits to be sent.
        self._moved_at: Optional[float] = None
        self._writer = threading.Thread(target=self._write_loop, daemon=True,
                                        name=f"link-{server_name}-peer{self.id}")

    @property
    def who(self) -> str:
        """The name the client said in its hello (``"?"`` before that)."""
        return self.session.who

    @property
    def connected(self) -> bool:
        """Whether frames can still be queued for this client (not closed, not gone)."""
        with self._cond:
            return self._open and not self._gone

    @property
    def stopped(self) -> bool:
        """Whether the client ended the connection itself with a normal close (1000, or 1001
        going away): it was asked to stop. False while connected, and when it vanished (a
        crash, a cut link: no close frame) or this server closed or cut it off."""
        if self._close_args is not None or self._aborted:
            return False
        return self._connection.close_code in (CloseCode.NORMAL_CLOSURE, CloseCode.GOING_AWAY)

    @property
    def queued(self) -> int:
        """Frames waiting in the outbox now."""
        with self._cond:
            return len(self._outbox)

    def send(self, msg: Message) -> bool:
        """Queue a message for this client; ``False`` if it is gone or closing (the message is
        then dropped). Never blocks. Raises :class:`MessageError` if ``msg`` cannot be
        encoded."""
        return self.send_text(encode(msg))

    __call__ = send

    def send_text(self, text: str) -> bool:
        """Queue an already encoded frame; ``False`` if the client is gone or closing. An
        outbox that would hold more than its bytes disconnects the client (the last resort
        against a client that does not read) and also gives ``False``."""
        size = len(text.encode("utf-8"))
        with self._cond:
            if not self._open:
                return False
            if self._queued_bytes + size <= self._limit:
                if self._moved_at is None:
                    self._moved_at = time.monotonic()
                self._outbox.append((text, size))
                self._queued_bytes += size
                self._cond.notify()
                return True
            unsent = len(self._outbox)
        self.abort(f"its outbox is full ({unsent} frames, {self._queued_bytes} bytes unsent, "
                   f"the limit is {self._limit}): it does not read")
        return False

    def close(self, code: int = CLOSE_REFUSED, reason: str = "") -> None:
        """Send what is queued (e.g. an ``error`` refusing this client), then close this
        connection with ``code`` (default 1008, policy violation) and ``reason``. Returns at
        once; later sends to this peer give ``False``. Idempotent."""
        with self._cond:
            if not self._open:
                return
            self._open = False
            self._close_args = (int(code), _close_reason(reason))
            self._cond.notify()

    def abort(self, why: str) -> None:
        """Disconnect this client now, dropping what is queued (its socket is shut down, so a
        send blocked in it fails at once); logs ``why`` once, as a warning."""
        with self._cond:
            if self._aborted or self._gone:
                self._open, self._gone = False, True
                return
            self._aborted, self._open, self._gone = True, False, True
            dropped = len(self._outbox)
            self._drop_outbox()
            self._cond.notify()
        self._log.warning("%s: disconnecting %r: %s (%d queued frames dropped)",
                          self._server_name, self, why, dropped)
        sock = getattr(self._connection, "socket", None)
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def __repr__(self) -> str:
        return f"Peer({self.who!r} #{self.id} at {self.address})"

    # -- for the server ----------------------------------------------------------------------

    @property
    def _closing(self) -> bool:
        """Refused, closing or gone: nothing it sends acts any more."""
        return self._close_args is not None or self._gone

    def _start(self) -> None:
        self._writer.start()

    def _lost(self) -> None:
        """The connection ended: drop what is queued and let the writer go."""
        with self._cond:
            self._open, self._gone = False, True
            self._drop_outbox()
            self._cond.notify()

    def _drop_outbox(self) -> None:
        """Forget every queued frame (the caller holds ``_cond``)."""
        self._outbox.clear()
        self._queued_bytes = 0
        self._moved_at = None

    def _stalled_for(self, now: float) -> float:
        """Seconds the outbox has gone without a frame sent while frames wait (0 if none
        waits): how long this client has read nothing it was sent."""
        since = self._moved_at
        return 0.0 if since is None else now - since

    def _write_loop(self) -> None:
        try:
            while True:
                with self._cond:
                    while not self._outbox and self._open and not self._gone:
                        self._cond.wait()
                    if self._gone:
                        return
                    if not self._outbox:  # closing, and everything queued went out
                        assert self._close_args is not None
                        code, reason = self._close_args
                        break
                    text, size = self._outbox[0]     # still counted while it is sent
                try:
                    self._connection.send(text)
                except ConnectionClosed:
                    return
                except Exception as exc:  # e.g. OSError after abort(): the socket is shut
                    if not self._aborted:
                        self._log.warning("%s: sending to %r failed: %s", self._server_name,
                                          self, exc)
                    return
                with self._cond:
                    if self._gone:
                        return
                    self._outbox.popleft()
                    self._queued_bytes -= size
                    self._moved_at = time.monotonic() if self._outbox else None
            # The close handshake is bounded by the connection's close_timeout.
            try:
                self._connection.close(code, reason)
            except Exception as exc:
                self._log.debug("%s: closing %r: %s", self._server_name, self, exc)
        finally:
            with self._cond:
                self._open, self._gone = False, True
                self._drop_outbox()
            if self._on_writer_exit is not None:
                self._on_writer_exit(self)
