"""The protocol's client, on websockets' threaded client: the MDP process's link to hrc_human
and the coordinator's (hrc_human's) link to the POMDP process.

It connects in a background thread and keeps connecting until it is closed: servers may start
later, and roslaunch respawns a process that dies, so the links reconnect by themselves
(websockets' ``reconnect``). Each connection opens with the hello of a
:class:`~ros_hrc.link.session.Session`: with a link token, a server is taken only once its own
hello proves the token. :meth:`MessageClient.request` stamps a fresh correlation ``id`` and
waits for the reply with that ``reply_to``; the :class:`~ros_hrc.link.inbox.Inbox` keeps what
came and matches each answer to its request.

Exception tree (the first two live in :mod:`ros_hrc.errors`)::

    LinkError                  the link failed: cannot bind, connection lost while sending
    ├── ProtocolError          a message is malformed, unknown or too large
    │   └── MessageError       (protocol) a message was rejected; .reason, .code, .msg_type
    ├── LinkTimeout            nothing came before the deadline (also a TimeoutError)
    ├── LinkDropped            the connection a reply was awaited on broke: it cannot come
    ├── ReplyRejected          the request's answer came but was rejected (malformed, too
    │                          large, of another epoch, without reply_to): it fails at once
    └── LinkClosed             the client was closed meanwhile

Threads: every public method is thread-safe. ``on_connect`` and ``on_disconnect`` run on the
client's reader thread: they may ``send`` but must not ``receive`` or ``request``.
"""
from __future__ import annotations

import logging
import threading
import urllib.parse
from typing import Any, Callable, Iterator, List, Optional, Tuple

from websockets.exceptions import ConnectionClosed, InvalidStatus, WebSocketException
from websockets.frames import CloseCode
from websockets.sync.client import ClientConnection, reconnect

from ros_hrc.errors import LinkError
from ros_hrc.link.codec import decode, encode
from ros_hrc.link.inbox import Inbox
from ros_hrc.link.messages import Error, Hello, Message
from ros_hrc.link.refusals import MessageError
from ros_hrc.link.replies import error_reply, is_reply_to
from ros_hrc.link.session import (CLOSE_GOING_AWAY, CLOSE_REFUSED, HELLO_TIMEOUT, Session,
                                  deadline_after, time_left, version_mismatch,
                                  websocket_settings)

_log = logging.getLogger("ros_hrc.link")


class LinkTimeout(LinkError, TimeoutError):
    """A deadline passed: no connection, no message, or no reply in time."""


class LinkClosed(LinkError):
    """The client was closed while waiting."""


class LinkDropped(LinkError):
    """The connection a reply was awaited on broke. The server that would have answered has
    lost its state (it died, or restarted), so the reply will never come."""


class ReplyRejected(LinkError):
    """The answer to a request came and was rejected: a malformed or too large frame naming
    the request in its ``reply_to``, a reply of another epoch than the request's, or a reply
    that answers it by the version 1 rules but without the ``reply_to`` version 2 requires.
    The request fails at once with the reason (no other answer will come)."""


def connect_failure(exc: BaseException) -> str:
    """Why a connection attempt failed, in a few plain words: a refused handshake names its
    HTTP status only, 503 says the server is stopping."""
    if isinstance(exc, InvalidStatus):
        status = exc.response.status_code
        return "the server is stopping (HTTP 503)" if status == 503 else \
            f"the server refused the handshake (HTTP {status})"
    text = " ".join(str(exc).split())
    return text[:200] or type(exc).__name__


class MessageClient:
    """A protocol client of the server at ``url``, saying hello as ``name``.

    It connects in a background thread, retrying with exponential backoff (``backoff`` =
    first and longest pause, in seconds) until :meth:`close`; after a drop it reconnects the
    same way and says hello again, then calls ``on_connect()``. ``on_disconnect()`` is called
    when a connection is lost (not when :meth:`close` ends it); :attr:`last_close` tells the
    close code and reason the server gave, if any. A server that refuses the client (close
    code 1008, or a hello that does not prove ``token``) is retried with growing pauses.

    Received messages wait in an inbox until :meth:`receive` takes them (a reply that a
    :meth:`request` in flight waits for is kept for it); the server's hello is kept in
    :attr:`server_hello` instead. A malformed frame from the server is answered with an
    ``error`` and dropped; an ``error`` is never answered. Use :meth:`connect` /
    :meth:`close`, or ``with`` (which connects)."""

    def __init__(self, url: str, name: str, *, connect_timeout: float = 30.0,
                 send_timeout: float = 10.0, backoff: Tuple[float, float] = (0.05, 1.0),
                 on_connect: Optional[Callable[[], None]] = None,
                 on_disconnect: Optional[Callable[[], None]] = None,
                 token: Optional[str] = None) -> None:
        self.url = url
        self.name = name
        self._token = token
        self._port = urllib.parse.urlsplit(url).port or 80
        self.connect_timeout = connect_timeout
        self.send_timeout = send_timeout
        self._backoff = backoff
        self._pause = backoff[0]        # the next pause between attempts
        self._quiet = False             # an outage was said already: say no more of it
        self._token_refused = False     # said once per outage that the server refused us
        self._on_connect = on_connect
        self._on_disconnect = on_disconnect
        self._cond = threading.Condition()  # guards everything below
        self._opening: Optional[ClientConnection] = None  # saying hello, or in use
        self._ws: Optional[ClientConnection] = None       # in use: sends go out on it
        self._connections = 0
        self._closed = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self.server_hello: Optional[Hello] = None
        #: (code, reason) of the last connection the server closed (code None: no close frame).
        self.last_close: Optional[Tuple[Optional[int], str]] = None
        self._log = _log.getChild(name)
        self._inbox = Inbox(name, self._log)

    # -- connection state --------------------------------------------------------------------

    @property
    def connected(self) -> bool:
        """Whether a connection is open now."""
        with self._cond:
            return self._ws is not None

    @property
    def connections(self) -> int:
        """How many times a connection was opened (more than 1: it reconnected)."""
        with self._cond:
            return self._connections

    def start(self) -> "MessageClient":
        """Start connecting in the background; returns at once."""
        with self._cond:
            if self._closed.is_set():
                raise LinkClosed(f"{self.name}: client is closed")
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name=f"link-{self.name}",
                                                daemon=True)
                self._thread.start()
        return self

    def connect(self, timeout: Optional[float] = None) -> "MessageClient":
        """Start, and wait until connected (``timeout`` defaults to ``connect_timeout``).
        Raises :class:`LinkTimeout` if the server did not answer in time; the client keeps
        trying in the background, so calling again waits more."""
        self.start()
        self._wait_connected(deadline_after(self.connect_timeout if timeout is None else timeout))
        return self

    def close(self) -> None:
        """Close the connection (code 1000) and stop reconnecting; wakes every waiter with
        :class:`LinkClosed`. Idempotent."""
        with self._cond:
            self._closed.set()
            connection = self._opening
            self._cond.notify_all()
        if connection is not None:
            # The close handshake is bounded by the close timeout; the reader then ends.
            connection.close()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join()

    def __enter__(self) -> "MessageClient":
        return self.connect()

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # -- sending and receiving ---------------------------------------------------------------

    def send(self, msg: Message, timeout: Optional[float] = None) -> int:
        """Send a message, waiting up to ``timeout`` (default ``send_timeout``) for a
        connection. If the connection breaks during the send, the frame is sent again once on
        the next connection (a half-written frame is discarded by the server). Returns the
        number of the connection it went out on (see :attr:`connections`), for
        ``receive(connection=...)``. Raises :class:`MessageError` for an invalid message,
        :class:`LinkTimeout`, :class:`LinkClosed`."""
        text = encode(msg)
        self.start()
        deadline = deadline_after(self.send_timeout if timeout is None else timeout)
        for attempt in (1, 2):
            ws = self._wait_connected(deadline)
            with self._cond:
                number = self._connections
            try:
                ws.send(text)
                return number
            except (WebSocketException, OSError) as exc:
                self._log.warning("%s: send failed (%s), reconnecting", self.name, exc)
                # The reader notices too; wait for a new connection.
                self._forget(ws)
                if attempt == 2:
                    raise LinkError(f"{self.name}: could not send {msg.type}: {exc}") from exc
        raise AssertionError("unreachable")  # pragma: no cover

    def receive(self, timeout: Optional[float] = None,
                match: Optional[Callable[[Message], bool]] = None,
                connection: Optional[int] = None) -> Message:
        """The oldest received message (the oldest one for which ``match`` is true, leaving
        the others in order); a reply that a :meth:`request` in flight waits for is left to
        it. Waits up to ``timeout`` seconds (``None``: until one comes or the client is
        closed). With ``connection`` (a number :meth:`send` returned), stop waiting as soon as
        that connection is gone: raises :class:`LinkDropped`. Raises :class:`LinkTimeout` or
        :class:`LinkClosed`."""
        return self._receive(timeout, match, connection, None)

    def request(self, msg: Message, timeout: Optional[float] = None) -> Message:
        """Send ``msg`` and wait for its answer, all within ``timeout`` (default
        ``send_timeout``). A message without an ``id`` gets a fresh one (a per-client
        counter); the answer is the ``ack``, ``error`` or ``decision`` whose ``reply_to`` is
        that id (:func:`~ros_hrc.link.protocol.is_reply_to`). Other messages stay in the
        inbox; several threads may request at once, each gets its own answer. Returns the
        answer; raises :class:`LinkTimeout`, :class:`LinkClosed`, or :class:`LinkDropped` at
        once when the connection breaks before the answer comes, :class:`ReplyRejected` at
        once when the answer came but is rejected (malformed or too large with this
        ``reply_to``; of another epoch than the request's, when the request has one; or
        answering it without a ``reply_to``). A late answer to a request that failed is
        dropped when it arrives."""
        if not isinstance(msg, Message):
            encode(msg)  # raises MessageError, as send() would
        deadline = deadline_after(self.send_timeout if timeout is None else timeout)
        with self._cond:
            msg = self._inbox.open_request(msg)
        answered = False
        try:
            number = self.send(msg, time_left(deadline))
            reply = self._receive(time_left(deadline), lambda r: is_reply_to(r, msg), number,
                                  msg.id)
            answered = True
            return reply
        finally:
            with self._cond:
                self._inbox.close_request(msg.id, answered)

    def next_id(self) -> int:
        """A fresh correlation id of this client (the counter :meth:`request` uses)."""
        with self._cond:
            return self._inbox.next_id()

    def drain(self) -> List[Message]:
        """Take every message waiting in the inbox (e.g. stale ones after a reset)."""
        with self._cond:
            return self._inbox.drain()

    # -- waiting -----------------------------------------------------------------------------

    def _receive(self, timeout: Optional[float], match: Optional[Callable[[Message], bool]],
                 connection: Optional[int], own_id: Optional[int]) -> Message:
        deadline = deadline_after(timeout)
        with self._cond:
            while True:
                why = self._inbox.rejection(own_id)
                if why is not None:
                    raise ReplyRejected(f"{self.name}: {why}")
                msg = self._inbox.take(match, own_id)
                if msg is not None:
                    return msg
                if self._closed.is_set():
                    raise LinkClosed(f"{self.name}: client closed while receiving")
                if connection is not None and (self._ws is None or
                                               self._connections != connection):
                    raise LinkDropped(f"{self.name}: the connection to {self.url} broke "
                                      "before the reply came")
                left = time_left(deadline)
                if left == 0.0:
                    raise LinkTimeout(f"{self.name}: no message from {self.url} in {timeout} s")
                self._cond.wait(left)

    def _wait_connected(self, deadline: Optional[float]) -> ClientConnection:
        with self._cond:
            while self._ws is None:
                if self._closed.is_set():
                    raise LinkClosed(f"{self.name}: client is closed")
                left = time_left(deadline)
                if left == 0.0:
                    raise LinkTimeout(f"{self.name}: no connection to {self.url}")
                self._cond.wait(left)
            return self._ws

    def _forget(self, ws: ClientConnection) -> None:
        with self._cond:
            if self._ws is ws:
                self._ws = None
                self._cond.notify_all()

    # -- the reader thread -------------------------------------------------------------------

    def _run(self) -> None:
        """Connect, say hello, read until the connection ends, and again, until closed.
        websockets' ``reconnect`` opens each connection and retries a failed attempt; the
        pauses between attempts are ours (:meth:`_pauses`)."""
        attempts = reconnect(self.url, open_timeout=max(1.0, self._backoff[1]),
                             process_exception=self._retry, reconnect_delays=self._pauses,
                             proxy=None,   # the links are local: no proxy of the environment
                             **websocket_settings(self._log))
        try:
            for connection in attempts:
                if self._closed.is_set():
                    break
                if not self._open(connection):
                    # Refused or unproven (said once per outage): try again, slower each time.
                    connection.close()
                    self._wait_pause()
                    continue
                close_code = self._read(connection)
                self._forget(connection)
                if self._closed.is_set():
                    break
                self._lost(close_code)
        except LinkClosed:
            pass
        finally:
            with self._cond:
                self._opening = self._ws = None
                self._cond.notify_all()

    def _lost(self, close_code: Optional[int]) -> None:
        """A connection in use ended: say why, tell the owner, pause if it was refused."""
        quiet, self._quiet = self._quiet, True
        if close_code == CLOSE_REFUSED:
            # Refused (e.g. the seat is taken): the refusal's error frame tells the owner why;
            # saying it here too would be noise.
            self._log.log(logging.DEBUG if quiet else logging.INFO,
                          "%s: %s refused the connection (%s); retrying", self.name, self.url,
                          self.last_close[1] if self.last_close else "")
        elif close_code == CLOSE_GOING_AWAY:
            # The server is stopping (shutdown, or a respawn): one plain line, and the
            # attempts to reconnect while it is gone say nothing more.
            self._log.info("%s: %s is going away (it stops); reconnecting when it is back",
                           self.name, self.url)
            self._pause = self._backoff[0]
        else:
            self._log.warning("%s: lost the connection to %s; reconnecting", self.name,
                              self.url)
            self._pause = self._backoff[0]
        self._call(self._on_disconnect, "on_disconnect")
        if close_code == CLOSE_REFUSED:
            self._wait_pause()

    def _retry(self, exc: Exception) -> Optional[Exception]:
        """websockets' ``process_exception``: an attempt to connect failed. Network and
        handshake failures are retried (said once per outage, in one plain line); anything
        else is a fault and ends the reader."""
        if self._closed.is_set():
            return LinkClosed(f"{self.name}: client is closed")
        if not isinstance(exc, (OSError, WebSocketException)):
            return exc
        self._log.log(logging.DEBUG if self._quiet else logging.INFO,
                      "%s: cannot connect to %s yet (%s); retrying", self.name, self.url,
                      connect_failure(exc))
        self._quiet = True
        return None

    def _pauses(self) -> Iterator[float]:
        """websockets' ``reconnect_delays``. The library sleeps its delays in a way
        :meth:`close` cannot cut short, so each pause is waited here instead (on the closed
        event, growing from the first to the longest of ``backoff``, shared with the pauses
        after a refusal) and the library is given nothing left to sleep."""
        while True:
            self._wait_pause()
            yield 0.0

    def _wait_pause(self) -> None:
        """Wait the next pause between attempts (it doubles up to the longest); raises
        :class:`LinkClosed` as soon as the client is closed."""
        pause, self._pause = self._pause, min(self._pause * 2, self._backoff[1])
        if self._closed.wait(pause):
            raise LinkClosed(f"{self.name}: client is closed")

    def _open(self, connection: ClientConnection) -> bool:
        """Say hello on a new connection, and with a token take the server only once its
        answer proves the token; then sends go out on it. False: refused, or closed."""
        with self._cond:
            if self._closed.is_set():
                return False
            self._opening = connection
        session = Session("client", self.name, self._port, self._token)
        try:
            connection.send(encode(session.opening_hello()))
            if self._token is not None and not self._proven(session, connection):
                self._quiet = True
                return False
        except (WebSocketException, OSError) as exc:   # e.g. no answer to our hello in time
            self._retry(exc)
            return False
        with self._cond:
            if self._closed.is_set():
                return False
            self._ws = connection
            self._connections += 1
            self._cond.notify_all()
        self._log.info("%s: connected to %s", self.name, self.url)
        self._call(self._on_connect, "on_connect")
        return True

    def _proven(self, session: Session, connection: ClientConnection) -> bool:
        """Whether the server's answer to our hello proves it knows the link token (said once
        per outage when it does not)."""
        answer: Optional[Message] = None
        try:
            answer = decode(connection.recv(timeout=HELLO_TIMEOUT))
        except (MessageError, ConnectionClosed):   # an unreadable answer, or none at all
            pass
        why = session.check_answer(answer)
        if why is None:
            self._take_server_hello(answer)
            self._token_refused = False
            return True
        if not self._token_refused:
            self._log.error("%s: %s: %s; trying again", self.name, self.url, why)
            self._token_refused = True
        return False

    def _take_server_hello(self, hello: Hello) -> None:
        self.server_hello = hello
        mismatch = version_mismatch(hello)
        if mismatch is not None:
            self._log.error("%s: server %s %s", self.name, hello.who, mismatch)

    def _call(self, callback: Optional[Callable[[], None]], what: str) -> None:
        if callback is None:
            return
        try:
            callback()
        except Exception:  # a failing callback must not stop the reader
            self._log.exception("%s: %s failed", self.name, what)

    def _read(self, connection: ClientConnection) -> Optional[int]:
        """Read frames until the connection ends; the close code the server gave, if any."""
        while True:
            try:
                frame = connection.recv()
            except ConnectionClosed as exc:
                received = exc.rcvd
                if received is None:
                    self.last_close = (None, "")
                    return None
                code = None if received.code == CloseCode.NO_STATUS_RCVD else received.code
                self.last_close = (code, received.reason)
                return code
            try:
                msg = decode(frame)
            except MessageError as exc:
                self._log.warning("%s: rejected a frame from %s: %s", self.name, self.url, exc)
                if exc.reply_to is not None:
                    with self._cond:
                        if self._inbox.reject(exc.reply_to, f"the answer to request "
                                              f"{exc.reply_to} was rejected: {exc.reason}"):
                            self._cond.notify_all()
                if exc.msg_type == Error.TYPE:
                    continue  # an error is never answered, even a malformed one
                try:
                    connection.send(error_reply(exc))
                except ConnectionClosed:
                    continue   # the next recv says how it ended
                continue
            if isinstance(msg, Hello):
                self._take_server_hello(msg)
                continue
            with self._cond:
                if self._inbox.deliver(msg):
                    self._cond.notify_all()
