"""The websocket I/O of the protocol: a server that runs in a background thread and a client
that reconnects by itself. :mod:`ros_hrc.link.protocol` does all encoding, validation, reply
matching and dispatch.

* :class:`MessageServer` (websockets' threaded server): the robot node on 8080, the human node
  on 9090 and the POMDP process on 7070. It calls ``handler(message, peer)`` (a function, or a
  :class:`~ros_hrc.link.protocol.DispatchTable`) for each well-formed message; a malformed or
  unknown frame is answered with an ``error`` and the handler never sees it; an exception in
  the handler is caught at the dispatch point, logged and answered with an ``error``
  (``code: "failed"``, ``reply_to`` the message's ``id``). An ``error`` is never answered
  with an ``error``. The connection and the process stay up either way.
* Sends never block the server: each :class:`Peer` has a bounded outbox drained by a writer
  thread of its own. A peer that does not read (its outbox fills up, or one frame stays stuck
  in its socket longer than ``send_timeout``) is disconnected, with one warning, and everybody
  else is served as before.
* :class:`MessageClient` (websocket-client): the MDP process, the observer node and the POMDP
  process's link to the robot node. It retries with backoff until the server is up (servers
  may start later), says ``hello``, and reconnects whenever the connection drops (roslaunch
  respawns a process that dies: the links reconnect). :meth:`MessageClient.request` stamps a
  fresh correlation ``id`` and waits for the reply with that ``reply_to``.

Size limits: a message larger than :data:`~ros_hrc.link.protocol.MAX_MESSAGE_BYTES` is refused
by ``encode`` before it is sent, and answered with an ``error`` when received (the connection
stays up). A frame larger than :data:`FRAME_LIMIT_BYTES` is not even read: the server closes
that connection with code 1009 (message too big), which bounds memory; the client reconnects.

Exception tree (the first two live in :mod:`ros_hrc.errors`)::

    LinkError                  the link failed: cannot bind, connection lost while sending
    ├── ProtocolError          a message is malformed, unknown or too large
    │   └── MessageError       (protocol) a message was rejected; .reason, .code, .msg_type
    ├── LinkTimeout            nothing came before the deadline (also a TimeoutError)
    ├── LinkDropped            the connection a reply was awaited on broke: it cannot come
    ├── ReplyRejected          the request's answer came but was rejected (malformed, too
    │                          large, of another epoch, without reply_to): it fails at once
    └── LinkClosed             the client was closed (or the server stopped) meanwhile

Threads: every public method of both classes is thread-safe. The server's handler and its
``on_connect`` / ``on_disconnect`` callbacks run on the server's connection threads, one call
at a time (a lock serialises them, so a handler need not guard its own state against
itself); they may call ``peer.send`` / ``server.send``, which only queue. The client's
``on_connect`` and ``on_disconnect`` run on its reader thread: they may ``send`` but must not
``receive`` or ``request``.
"""
from __future__ import annotations

import collections
import errno
import itertools
import logging
import socket
import threading
import time
import urllib.parse
from dataclasses import replace
from typing import Any, Callable, Deque, Dict, List, Optional, Set, Tuple

import websocket  # websocket-client
from websockets.exceptions import ConnectionClosed
from websockets.sync.server import Server, ServerConnection, serve

from ros_hrc import settings
from ros_hrc.errors import LinkError
from ros_hrc.link.protocol import (ERR_FAILED, ERR_REFUSED, ERR_UNAUTHORIZED, ERR_VERSION,
                                   MAX_MESSAGE_BYTES,
                                   PROTOCOL_VERSION, REPLY_TYPES, Error, Hello, Message,
                                   MessageError, as_reply, decode, encode, error_reply)
from ros_hrc.link.protocol import is_reply_to  # noqa: F401  (its home is the protocol module)
from ros_hrc.link.token import new_nonce, proof, proof_matches

#: Where a server binds and a client connects unless told otherwise: the host setting's.
DEFAULT_HOST: str = settings.default("host")
#: Frames above this size are not read at all (close code 1009). Between the protocol's limit
#: and this one, an oversized message is still answered with an error and the link stays up.
FRAME_LIMIT_BYTES = 4 * MAX_MESSAGE_BYTES
#: Seconds a closing connection may take to finish its handshake. A local peer answers in
#: microseconds; one that does not should not hold up stop() (websockets' default is 10 s).
CLOSE_TIMEOUT = 2.0
#: Frames a peer's outbox holds; one more and the peer is disconnected as not reading.
OUTBOX_FRAMES = 1024
#: Seconds one frame may stay blocked in a peer's socket before the peer is disconnected.
SEND_TIMEOUT = 5.0
#: Close code of :meth:`Peer.close` by default: policy violation (e.g. "this seat is taken").
CLOSE_REFUSED = 1008
#: Close code of a server that stops (websockets sends it): the client reconnects quietly.
CLOSE_GOING_AWAY = 1001
#: Seconds a client of a server with a token has to say its hello (with its proof) before it
#: is refused: a connection that never speaks holds no thread for long.
HELLO_TIMEOUT = 10.0
#: Pause between attempts when accepting a connection fails for want of a resource (file
#: descriptors, memory): the connection waits in the listen queue meanwhile.
ACCEPT_RETRY_PAUSE = 0.1
# accept() failures that pass: the listening socket is fine, the process or the peer was not.
_TRANSIENT_ACCEPT_ERRORS = frozenset({errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM,
                                      errno.ECONNABORTED, errno.EPROTO, errno.EPERM,
                                      errno.EINTR, errno.EAGAIN})
# Accepted hello nonces a server remembers, to refuse a replayed hello.
_REMEMBERED_NONCES = 65536
# A websocket close reason is at most 123 bytes of UTF-8.
_MAX_CLOSE_REASON = 123
# How many request ids that timed out are remembered, so their late replies are dropped.
_ABANDONED_IDS = 1024

_log = logging.getLogger("ros_hrc.link")


class LinkTimeout(LinkError, TimeoutError):
    """A deadline passed: no connection, no message, or no reply in time."""


class LinkClosed(LinkError):
    """The client was closed, or the server stopped, while waiting."""


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
    HTTP status only (websocket-client's own text carries every header), 503 says the server
    is stopping."""
    status = getattr(exc, "status_code", None)
    if isinstance(exc, websocket.WebSocketBadStatusException) and status is not None:
        return "the server is stopping (HTTP 503)" if status == 503 else \
            f"the server refused the handshake (HTTP {status})"
    text = " ".join(str(exc).split())
    return text[:200] or type(exc).__name__


def free_port(host: str = DEFAULT_HOST) -> int:
    """A TCP port free on ``host`` now: for a stack of one's own (its roscore and links)
    beside others on the same machine. Another process may take it before it is bound."""
    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def link_url(port: int, host: str = DEFAULT_HOST) -> str:
    """The websocket URL of a server of this package."""
    return f"ws://{host}:{port}"


def _deadline(timeout: Optional[float]) -> Optional[float]:
    return None if timeout is None else time.monotonic() + max(0.0, timeout)


def _remaining(deadline: Optional[float]) -> Optional[float]:
    return None if deadline is None else max(0.0, deadline - time.monotonic())


class _Listener(socket.socket):
    """The listening socket of a :class:`MessageServer`. Its ``accept`` waits out a failure
    that says nothing about the socket itself (EMFILE: the process has no file descriptor
    left, ENFILE, ENOBUFS, ENOMEM, a connection aborted while queued) and tries again, so the
    server goes on serving once the resource is back; websockets' accept loop would end at the
    first such error and leave a socket that listens but is never served. Closing the socket
    (the server's shutdown) still ends the loop."""

    def setup(self, name: str, log: logging.Logger) -> "_Listener":
        self.server_name = name
        self.log = log
        self.failures = 0
        return self

    def accept(self) -> Tuple[socket.socket, Any]:
        while True:
            try:
                accepted = super().accept()
            except OSError as exc:
                if exc.errno not in _TRANSIENT_ACCEPT_ERRORS or self.fileno() < 0:
                    raise
                if self.failures == 0:
                    self.log.error("%s: cannot accept a connection: %s; trying again every "
                                   "%g s (the connection waits)", self.server_name, exc,
                                   ACCEPT_RETRY_PAUSE)
                self.failures += 1
                time.sleep(ACCEPT_RETRY_PAUSE)
                continue
            if self.failures:
                self.log.warning("%s: accepting connections again, after %d failed attempts",
                                 self.server_name, self.failures)
                self.failures = 0
            return accepted


def _listen(host: str, port: int, name: str, log: logging.Logger) -> _Listener:
    # socket.create_server sets SO_REUSEADDR, so a respawned server can bind again while old
    # connections linger in TIME_WAIT.
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    plain = socket.create_server((host, port), family=family)
    return _Listener(fileno=plain.detach()).setup(name, log)


def _close_reason(reason: str) -> str:
    data = reason.encode("utf-8", "replace")[:_MAX_CLOSE_REASON]
    return data.decode("utf-8", "ignore")


class Peer:
    """One client connected to a :class:`MessageServer`, as its handler sees it.

    ``who`` is the name the client gave in its hello (``"?"`` before that), ``address`` its
    (host, port). Calling the peer, or :meth:`send`, queues a frame for that client only and
    returns at once: a writer thread of the peer's own sends the queue in order. A peer that
    does not read is disconnected (its outbox is full, or a send stayed blocked longer than
    the server's ``send_timeout``)."""

    _ids = itertools.count(1)

    def __init__(self, connection: ServerConnection, *, server_name: str = "server",
                 outbox_frames: int = OUTBOX_FRAMES, log: logging.Logger = _log,
                 on_writer_exit: Optional[Callable[["Peer"], None]] = None) -> None:
        self.id = next(Peer._ids)
        self.who = "?"
        #: The client proved it knows the server's link token (always true without one).
        self.authenticated = False
        #: The client said hello (a second hello on the same connection is refused).
        self.said_hello = False
        self.opened_at = time.monotonic()
        try:
            self.address: Tuple[Any, ...] = tuple(connection.remote_address or ())
        except OSError:  # the socket already failed (e.g. a first frame over the limit)
            self.address = ()
        self._connection = connection
        self._server_name = server_name
        self._limit = max(1, int(outbox_frames))
        self._log = log
        self._on_writer_exit = on_writer_exit
        self._cond = threading.Condition()     # guards the five below
        self._outbox: Deque[str] = collections.deque()
        self._open = True                      # takes new frames
        self._close_args: Optional[Tuple[int, str]] = None  # close() was called
        self._gone = False                     # connection lost or aborted: send nothing more
        self._aborted = False
        self._sending_since: Optional[float] = None  # monotonic start of the send under way
        self._writer = threading.Thread(target=self._write_loop, daemon=True,
                                        name=f"link-{server_name}-peer{self.id}")

    @property
    def connected(self) -> bool:
        """Whether frames can still be queued for this client (not closed, not gone)."""
        with self._cond:
            return self._open and not self._gone

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
        """Queue an already encoded frame; ``False`` if the client is gone or closing. A full
        outbox disconnects the client (it does not read) and also gives ``False``."""
        with self._cond:
            if not self._open:
                return False
            if len(self._outbox) < self._limit:
                self._outbox.append(text)
                self._cond.notify()
                return True
        self.abort(f"its outbox is full ({self._limit} frames unsent): it does not read")
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
            self._outbox.clear()
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

    def _start(self) -> None:
        self._writer.start()

    def _lost(self) -> None:
        """The connection ended: drop what is queued and let the writer go."""
        with self._cond:
            self._open, self._gone = False, True
            self._outbox.clear()
            self._cond.notify()

    def _stuck_for(self, now: float) -> float:
        """Seconds the send under way has been blocked (0 if none)."""
        since = self._sending_since
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
                    text = self._outbox.popleft()
                    self._sending_since = time.monotonic()
                try:
                    self._connection.send(text)
                except ConnectionClosed:
                    return
                except Exception as exc:  # e.g. OSError after abort(): the socket is shut
                    if not self._aborted:
                        self._log.warning("%s: sending to %r failed: %s", self._server_name,
                                          self, exc)
                    return
                finally:
                    self._sending_since = None
            # The close handshake is bounded by the connection's close_timeout.
            try:
                self._connection.close(code, reason)
            except Exception as exc:
                self._log.debug("%s: closing %r: %s", self._server_name, self, exc)
        finally:
            with self._cond:
                self._open, self._gone = False, True
                self._outbox.clear()
            if self._on_writer_exit is not None:
                self._on_writer_exit(self)


Handler = Callable[[Message, Peer], Optional[Message]]
PeerCallback = Callable[[Peer], None]


class MessageServer:
    """A protocol server on ``host:port`` (``port=0``: any free port, see :attr:`port`).

    ``handler(message, peer)`` (a function or a
    :class:`~ros_hrc.link.protocol.DispatchTable`) is called for each well-formed message
    other than ``hello``; it replies by calling ``peer(reply)`` or by returning the reply
    (``None``: no reply). A returned ``ack`` / ``error`` / ``decision`` is stamped with the
    message's ``id`` (as ``reply_to``) and ``epoch`` where it has none. ``on_connect(peer)``
    runs once a client said hello (or sent its first message without one),
    ``on_disconnect(peer)`` when it is gone. Use :meth:`start` / :meth:`stop`, or ``with``.

    Sends never block: ``send_timeout`` (seconds) and ``outbox_frames`` bound how far a peer
    may fall behind before it is disconnected."""

    def __init__(self, port: int, handler: Handler, *, host: str = DEFAULT_HOST,
                 name: str = "server", on_connect: Optional[PeerCallback] = None,
                 on_disconnect: Optional[PeerCallback] = None,
                 send_timeout: float = SEND_TIMEOUT,
                 outbox_frames: int = OUTBOX_FRAMES, token: Optional[str] = None,
                 hello_timeout: float = HELLO_TIMEOUT) -> None:
        if not send_timeout > 0:
            raise ValueError(f"{name}: send_timeout must be > 0, got {send_timeout}")
        if outbox_frames < 1:
            raise ValueError(f"{name}: outbox_frames must be >= 1, got {outbox_frames}")
        self.host = host
        self.name = name
        self.send_timeout = float(send_timeout)
        self.outbox_frames = int(outbox_frames)
        self.hello_timeout = float(hello_timeout)
        self._token = token
        self._nonces: "collections.OrderedDict[str, None]" = collections.OrderedDict()
        self._refused = 0                   # refusals not yet logged (one line per second)
        self._refusal_logged_at = -1.0
        self._refusal_lock = threading.Lock()
        self._port = port
        self._handler = handler
        self._on_connect = on_connect
        self._on_disconnect = on_disconnect
        self._server: Optional[Server] = None
        self._thread: Optional[threading.Thread] = None
        self._watchdog: Optional[threading.Thread] = None
        self._stopping = threading.Event()
        self._accepting = False
        self._peers: Dict[int, Peer] = {}
        self._live: Set[Peer] = set()  # peers whose writer thread runs
        self._greeted: set = set()
        self._peers_changed = threading.Condition()
        self._dispatch_lock = threading.Lock()
        self._log = _log.getChild(name)

    @property
    def port(self) -> int:
        """The bound port (the real one when constructed with ``port=0``)."""
        return self._port

    @property
    def url(self) -> str:
        """The URL clients connect to."""
        return link_url(self._port, self.host)

    def start(self) -> "MessageServer":
        """Bind and serve in a background thread; raises :class:`LinkError` if binding fails."""
        if self._server is not None:
            raise LinkError(f"{self.name}: already started on {self.url}")
        # websockets' own INFO lines repeat ours; its warnings and errors still show.
        ws_log = self._log.getChild("websockets")
        if ws_log.level == logging.NOTSET:
            ws_log.setLevel(logging.WARNING)
        try:
            # No compression: frames are small and local, and max_size then bounds the bytes
            # actually read.
            self._server = serve(self._serve_connection,
                                 sock=_listen(self.host, self._port, self.name, self._log),
                                 compression=None, max_size=FRAME_LIMIT_BYTES, logger=ws_log,
                                 close_timeout=CLOSE_TIMEOUT,
                                 process_request=self._admit)
        except OSError as exc:
            raise LinkError(f"{self.name}: cannot listen on {self.host}:{self._port}: {exc}") \
                from exc
        self._port = self._server.socket.getsockname()[1]
        self._stopping.clear()
        self._accepting = True
        self._thread = threading.Thread(target=self._server.serve_forever,
                                        name=f"link-{self.name}", daemon=True)
        self._thread.start()
        self._watchdog = threading.Thread(target=self._watch, name=f"link-{self.name}-watchdog",
                                          daemon=True)
        self._watchdog.start()
        self._log.info("%s listening on %s%s", self.name, self.url,
                       " (link token required)" if self._token is not None else "")
        return self

    def stop(self) -> None:
        """Send what is queued, close every connection (code 1001, going away) and stop
        listening; a peer that does not take its frames within :data:`CLOSE_TIMEOUT` is cut.
        Waits for a running handler call to finish, so never call it from the handler.
        Idempotent."""
        server, self._server = self._server, None
        if server is None:
            return
        # From now on an opening handshake gets HTTP 503, so a client that reconnects at once
        # does not land on this server again while its connections are closed one by one.
        self._accepting = False
        with self._peers_changed:
            live = list(self._live)
        for peer in live:
            peer.close(1001, "server stopping")
        deadline = _deadline(CLOSE_TIMEOUT)
        for peer in live:
            peer._writer.join(_remaining(deadline))
        for peer in live:
            if peer._writer.is_alive():
                peer.abort("it was still sending when the server stopped")
        server.shutdown()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        self._stopping.set()
        if self._watchdog is not None:
            self._watchdog.join()
            self._watchdog = None
        with self._peers_changed:
            writers = [peer._writer for peer in self._live]
            self._peers.clear()
            self._greeted.clear()
            self._peers_changed.notify_all()
        for writer in writers:  # all are ending: their connections are closed
            writer.join(CLOSE_TIMEOUT)
        self._log.info("%s stopped", self.name)

    def __enter__(self) -> "MessageServer":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    def clients(self) -> List[Peer]:
        """The clients connected now."""
        with self._peers_changed:
            return list(self._peers.values())

    def wait_for_client(self, timeout: Optional[float] = None, who: Optional[str] = None) -> bool:
        """Wait until a client is connected (one that said hello as ``who``, if given);
        ``False`` if none came within ``timeout`` seconds or the server was stopped."""
        deadline = _deadline(timeout)

        def ready() -> bool:
            if who is None:
                return bool(self._peers)
            return any(p.who == who for p in self._peers.values())

        with self._peers_changed:
            while not ready():
                if self._server is None:
                    return False
                left = _remaining(deadline)
                if left == 0.0:
                    return False
                self._peers_changed.wait(left)
            return True

    def send(self, msg: Message, who: Optional[str] = None) -> int:
        """Queue a message for every connected client (or only those that said hello as
        ``who``); returns for how many it was queued. Never blocks."""
        text = encode(msg)
        return sum(peer.send_text(text) for peer in self.clients()
                   if who is None or peer.who == who)

    # -- on the server's threads -------------------------------------------------------------

    def _watch(self) -> None:
        """Disconnect a peer whose socket took no data for longer than ``send_timeout``."""
        interval = min(0.5, max(0.01, self.send_timeout / 4))
        while not self._stopping.wait(interval):
            now = time.monotonic()
            with self._peers_changed:
                live = list(self._live)
            for peer in live:
                stuck = peer._stuck_for(now)
                if stuck > self.send_timeout:
                    peer.abort(f"a send has been blocked for {stuck:.1f} s (send_timeout "
                               f"{self.send_timeout:g} s): it does not read")
                elif (self._token is not None and not peer.authenticated
                      and peer._close_args is None and now - peer.opened_at > self.hello_timeout):
                    self._refuse(peer, f"no hello within {self.hello_timeout:g} s")

    def _admit(self, connection: ServerConnection, request: Any) -> Any:
        """websockets' ``process_request``: refuse the handshake while stopping."""
        if not self._accepting:
            return connection.respond(503, f"{self.name} is stopping\n")
        return None

    def _writer_done(self, peer: Peer) -> None:
        with self._peers_changed:
            self._live.discard(peer)

    def _serve_connection(self, connection: ServerConnection) -> None:
        peer = Peer(connection, server_name=self.name, outbox_frames=self.outbox_frames,
                    log=self._log, on_writer_exit=self._writer_done)
        peer.authenticated = self._token is None
        with self._peers_changed:
            self._peers[peer.id] = peer
            self._live.add(peer)
            peer._start()  # under the lock: stop() never sees a writer not yet started
            self._peers_changed.notify_all()
        self._log.info("%s: client connected from %s", self.name, peer.address)
        try:
            for frame in connection:
                self._dispatch(peer, frame)
        except ConnectionClosed as exc:
            # Abnormal closes only (normal ones end the loop); 1009 is a frame over the limit.
            # A peer this server cut off or closed on purpose was already reported.
            on_purpose = peer._aborted or peer._close_args is not None
            self._log.log(logging.INFO if on_purpose else logging.WARNING,
                          "%s: connection of %r closed: %s", self.name, peer, exc)
        finally:
            peer._lost()
            with self._peers_changed:
                self._peers.pop(peer.id, None)
                greeted = peer.id in self._greeted
                self._greeted.discard(peer.id)
                self._peers_changed.notify_all()
            self._log.info("%s: %r disconnected", self.name, peer)
            if greeted and self._on_disconnect is not None:
                with self._dispatch_lock:
                    self._call_back(self._on_disconnect, peer)

    def _dispatch(self, peer: Peer, frame: Any) -> None:
        if peer._close_args is not None or peer._gone:
            return  # refused or closing: nothing it sends acts any more
        if self._token is not None and not peer.authenticated:
            self._authenticate(peer, frame)
            return
        try:
            msg = decode(frame)
        except MessageError as exc:
            if exc.msg_type == Error.TYPE:  # an error is never answered, even a malformed one
                self._log.warning("%s: dropped a malformed error from %r: %s", self.name, peer,
                                  exc)
                return
            self._log.warning("%s: rejected a frame from %r: %s", self.name, peer, exc)
            peer.send_text(error_reply(exc))
            return
        if isinstance(msg, Hello):
            if peer.said_hello:
                peer.send(Error(message=f"{self.name}: this connection said hello already, as "
                                        f"{peer.who!r}; a hello is the first frame only",
                                in_reply_to=Hello.TYPE, code=ERR_REFUSED, reply_to=msg.id))
                return
            self._greet(peer, msg)
            return
        step = getattr(msg, "step", None)
        with self._dispatch_lock:
            if peer.id not in self._greeted:
                self._mark_greeted(peer)
            try:
                reply = self._handler(msg, peer)
            except Exception as exc:  # the dispatch point: one bad message never kills us
                self._log.exception("%s: handler failed on %s from %r", self.name, msg.type,
                                    peer)
                if not isinstance(msg, Error):
                    peer.send_text(error_reply(exc, msg.type, step, reply_to=msg.id,
                                               epoch=msg.epoch, code=ERR_FAILED))
                return
            if reply is None:
                return
            if isinstance(msg, Error) and isinstance(reply, Error):
                self._log.warning("%s: the handler answered an error from %r with an error; "
                                  "not sent (an error is never answered with an error): %s",
                                  self.name, peer, reply.message)
                return
            if isinstance(reply, REPLY_TYPES):
                reply = as_reply(reply, msg)
            try:
                peer.send(reply)
            except MessageError as exc:
                self._log.error("%s: handler returned an unsendable reply: %s", self.name, exc)
                if not isinstance(msg, Error):
                    peer.send_text(error_reply(exc, msg.type, step, reply_to=msg.id,
                                               epoch=msg.epoch, code=ERR_FAILED))

    def _authenticate(self, peer: Peer, frame: Any) -> None:
        """The first frame of a client of a server with a token: a hello proving the token,
        or the client is refused and closed."""
        reply_to: Optional[int] = None
        try:
            msg = decode(frame)
        except MessageError as exc:
            if exc.msg_type == Error.TYPE:   # never answered: just closed
                self._refuse(peer, "an error instead of its hello", answer=False)
            else:
                self._refuse(peer, f"a malformed first frame ({exc.reason})", exc.msg_id)
            return
        if isinstance(msg, Hello):
            reply_to = msg.id
            if msg.auth is None or msg.nonce is None:
                why = "a hello without a proof of the link token (no auth and nonce)"
            elif msg.nonce in self._nonces:
                why = "a hello whose nonce was used before (a replay)"
            elif not proof_matches(self._token, msg.auth, "client", self.port, msg.who,
                                   msg.nonce):
                why = "a hello with a wrong proof of the link token (another launch's token?)"
            else:
                self._nonces[msg.nonce] = None
                while len(self._nonces) > _REMEMBERED_NONCES:
                    self._nonces.popitem(last=False)
                peer.authenticated = True
                self._greet(peer, msg)
                return
        else:
            why = f"a {msg.type} message before its hello"
            reply_to = msg.id
        self._refuse(peer, why, reply_to, answer=not isinstance(msg, Error))

    def _refuse(self, peer: Peer, why: str, reply_to: Optional[int] = None,
                answer: bool = True) -> None:
        """Refuse a client that did not prove the link token: one ``error``
        (:data:`~ros_hrc.link.protocol.ERR_UNAUTHORIZED`), then close (1008); one log line
        per second at most, however many are refused."""
        if answer:
            peer.send(Error(message=f"{self.name}: refused: {why}; this link takes only the "
                                    "processes of its own launch (docs/protocol.md, 'The "
                                    "link token')",
                            in_reply_to=Hello.TYPE, code=ERR_UNAUTHORIZED, reply_to=reply_to))
        peer.close(CLOSE_REFUSED, "link token required")
        with self._refusal_lock:
            now = time.monotonic()
            self._refused += 1
            if now - self._refusal_logged_at < 1.0:
                return
            more = f" ({self._refused - 1} more refused since the last line)" \
                if self._refused > 1 else ""
            self._refused, self._refusal_logged_at = 0, now
        self._log.warning("%s: refused a client from %s: %s%s", self.name, peer.address, why,
                          more)

    def _greet(self, peer: Peer, hello: Hello) -> None:
        peer.who = hello.who
        peer.said_hello = True
        if hello.version != PROTOCOL_VERSION:
            self._log.error("%s: %r speaks protocol %d, this is %d", self.name, peer,
                            hello.version, PROTOCOL_VERSION)
            peer.send(Error(message=f"protocol version {hello.version} is not supported; "
                                    f"{self.name} speaks {PROTOCOL_VERSION}",
                            in_reply_to=Hello.TYPE, code=ERR_VERSION, reply_to=hello.id))
        auth = None
        if self._token is not None and hello.nonce is not None:
            auth = proof(self._token, "server", self.port, self.name, hello.nonce)
        peer.send(Hello(who=self.name, reply_to=hello.id, auth=auth))
        with self._dispatch_lock:
            if peer.id not in self._greeted:
                self._mark_greeted(peer)
        with self._peers_changed:
            self._peers_changed.notify_all()  # wait_for_client(who=...) may be waiting

    def _mark_greeted(self, peer: Peer) -> None:
        """Record the client as known and tell the owner; under the dispatch lock."""
        with self._peers_changed:
            self._greeted.add(peer.id)
        self._log.info("%s: %r says hello", self.name, peer)
        if self._on_connect is not None:
            self._call_back(self._on_connect, peer)

    def _call_back(self, callback: PeerCallback, peer: Peer) -> None:
        try:
            callback(peer)
        except Exception:  # a failing callback must not take the connection down
            self._log.exception("%s: callback %s failed for %r", self.name,
                                getattr(callback, "__name__", callback), peer)


class MessageClient:
    """A protocol client of the server at ``url``, saying hello as ``name``.

    It connects in a background thread, retrying with exponential backoff (``backoff`` =
    first and longest pause, in seconds) until :meth:`close`; after a drop it reconnects the
    same way and says hello again, then calls ``on_connect()``. ``on_disconnect()`` is called
    when a connection is lost (not when :meth:`close` ends it); :attr:`last_close` tells the
    close code and reason the server gave, if any. A server that refuses the client (close
    code 1008) is retried with growing pauses.

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
        self._token_refused = False   # said once per outage that the server refused us
        self.connect_timeout = connect_timeout
        self.send_timeout = send_timeout
        self._backoff = backoff
        self._on_connect = on_connect
        self._on_disconnect = on_disconnect
        self._cond = threading.Condition()  # guards everything below
        self._ws: Optional[websocket.WebSocket] = None
        self._connections = 0
        self._inbox: List[Message] = []
        self._next_id = itertools.count(1)
        self._pending: Dict[int, int] = {}  # id of a request in flight -> how many wait on it
        self._requests: Dict[int, Message] = {}   # id of a request in flight -> the request
        self._rejected: Dict[int, str] = {}   # id of a request in flight -> why its answer failed
        self._abandoned: "collections.OrderedDict[int, None]" = collections.OrderedDict()
        self._closed = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._send_lock = threading.Lock()
        self.server_hello: Optional[Hello] = None
        #: (code, reason) of the last connection the server closed (code None: no close frame).
        self.last_close: Optional[Tuple[Optional[int], str]] = None
        self._log = _log.getChild(name)

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
        self._wait_connected(_deadline(self.connect_timeout if timeout is None else timeout))
        return self

    def close(self) -> None:
        """Close the connection (code 1000) and stop reconnecting; wakes every waiter with
        :class:`LinkClosed`. Idempotent."""
        with self._cond:
            self._closed.set()
            ws = self._ws
            self._cond.notify_all()
        if ws is not None:
            try:
                with self._send_lock:
                    ws.send_close()
            except (websocket.WebSocketException, OSError):
                pass
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            # The server answers the close frame at once; if it does not, cut the socket.
            thread.join(1.0)
            if thread.is_alive() and ws is not None:
                self._shutdown_socket(ws)
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
        deadline = _deadline(self.send_timeout if timeout is None else timeout)
        for attempt in (1, 2):
            ws = self._wait_connected(deadline)
            with self._cond:
                number = self._connections
            try:
                with self._send_lock:
                    ws.send(text)
                return number
            except (websocket.WebSocketException, OSError) as exc:
                self._log.warning("%s: send failed (%s), reconnecting", self.name, exc)
                # Make sure the reader notices too, then wait for a new connection.
                self._shutdown_socket(ws)
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
        deadline = _deadline(self.send_timeout if timeout is None else timeout)
        with self._cond:
            if msg.id is None:
                msg = replace(msg, id=next(self._next_id))
            self._pending[msg.id] = self._pending.get(msg.id, 0) + 1
            self._requests[msg.id] = msg
        answered = False
        try:
            number = self.send(msg, _remaining(deadline))
            reply = self._receive(_remaining(deadline), lambda r: is_reply_to(r, msg), number,
                                  msg.id)
            answered = True
            return reply
        finally:
            with self._cond:
                left = self._pending.pop(msg.id) - 1
                if left:
                    self._pending[msg.id] = left
                else:
                    self._requests.pop(msg.id, None)
                    self._rejected.pop(msg.id, None)
                if not left and not answered:
                    self._abandoned[msg.id] = None
                    while len(self._abandoned) > _ABANDONED_IDS:
                        self._abandoned.popitem(last=False)

    def next_id(self) -> int:
        """A fresh correlation id of this client (the counter :meth:`request` uses)."""
        with self._cond:
            return next(self._next_id)

    def drain(self) -> List[Message]:
        """Take every message waiting in the inbox (e.g. stale ones after a reset)."""
        with self._cond:
            taken, self._inbox = self._inbox, []
            return taken

    # -- the reader thread -------------------------------------------------------------------

    def _receive(self, timeout: Optional[float], match: Optional[Callable[[Message], bool]],
                 connection: Optional[int], own_id: Optional[int]) -> Message:
        deadline = _deadline(timeout)
        with self._cond:
            while True:
                if own_id is not None and own_id in self._rejected:
                    raise ReplyRejected(f"{self.name}: {self._rejected[own_id]}")
                for i, msg in enumerate(self._inbox):
                    if (msg.reply_to is not None and msg.reply_to in self._pending
                            and msg.reply_to != own_id):
                        continue  # kept for the request that waits for it
                    if match is None or match(msg):
                        return self._inbox.pop(i)
                if self._closed.is_set():
                    raise LinkClosed(f"{self.name}: client closed while receiving")
                if connection is not None and (self._ws is None or
                                               self._connections != connection):
                    raise LinkDropped(f"{self.name}: the connection to {self.url} broke "
                                      "before the reply came")
                left = _remaining(deadline)
                if left == 0.0:
                    raise LinkTimeout(f"{self.name}: no message from {self.url} in {timeout} s")
                self._cond.wait(left)

    def _wait_connected(self, deadline: Optional[float]) -> websocket.WebSocket:
        with self._cond:
            while self._ws is None:
                if self._closed.is_set():
                    raise LinkClosed(f"{self.name}: client is closed")
                left = _remaining(deadline)
                if left == 0.0:
                    raise LinkTimeout(f"{self.name}: no connection to {self.url}")
                self._cond.wait(left)
            return self._ws

    def _forget(self, ws: websocket.WebSocket) -> None:
        with self._cond:
            if self._ws is ws:
                self._ws = None
                self._cond.notify_all()

    @staticmethod
    def _shutdown_socket(ws: websocket.WebSocket) -> None:
        # shutdown(), unlike close(), wakes a thread blocked in recv on this socket.
        sock = ws.sock
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def _run(self) -> None:
        pause = self._backoff[0]
        failures = 0
        while not self._closed.is_set():
            ws = self._open(quiet=failures > 0)
            if ws is None:
                failures += 1
                # Servers may start later (or be respawning): retry, slower each time.
                self._closed.wait(pause)
                pause = min(pause * 2, self._backoff[1])
                continue
            close_code = self._read(ws)
            self._forget(ws)
            ws.shutdown()
            if self._closed.is_set():
                break
            if close_code == CLOSE_REFUSED:
                # Refused (e.g. the seat is taken): try again, but slower each time. The
                # refusal's error frame tells the owner why; saying it here too would be noise.
                self._log.log(logging.DEBUG if failures else logging.INFO,
                              "%s: %s refused the connection (%s); retrying", self.name,
                              self.url, self.last_close[1] if self.last_close else "")
                failures += 1
            elif close_code == CLOSE_GOING_AWAY:
                # The server is stopping (shutdown, or a respawn): one plain line, and the
                # attempts to reconnect while it is gone say nothing more.
                self._log.info("%s: %s is going away (it stops); reconnecting when it is back",
                               self.name, self.url)
                pause, failures = self._backoff[0], 1
            else:
                self._log.warning("%s: lost the connection to %s; reconnecting", self.name,
                                  self.url)
                pause, failures = self._backoff[0], 1
            self._call(self._on_disconnect, "on_disconnect")
            if close_code == CLOSE_REFUSED:
                self._closed.wait(pause)
                pause = min(pause * 2, self._backoff[1])

    def _call(self, callback: Optional[Callable[[], None]], what: str) -> None:
        if callback is None:
            return
        try:
            callback()
        except Exception:  # a failing callback must not stop the reader
            self._log.exception("%s: %s failed", self.name, what)

    def _open(self, quiet: bool) -> Optional[websocket.WebSocket]:
        try:
            ws = websocket.create_connection(self.url, timeout=max(1.0, self._backoff[1]),
                                             enable_multithread=True)
            if self._token is None:
                ws.send(encode(Hello(who=self.name)))
            elif not self._prove(ws):
                ws.shutdown()
                return None
            # Blocking from now on: the reader waits for frames; close() cuts the socket.
            ws.settimeout(None)
        except (websocket.WebSocketException, OSError) as exc:
            # Say it once per outage, not once per retry, in one plain line.
            self._log.log(logging.DEBUG if quiet else logging.INFO,
                          "%s: cannot connect to %s yet (%s); retrying", self.name, self.url,
                          connect_failure(exc))
            return None
        with self._cond:
            if self._closed.is_set():
                ws.shutdown()
                return None
            self._ws = ws
            self._connections += 1
            self._cond.notify_all()
        self._log.info("%s: connected to %s", self.name, self.url)
        self._call(self._on_connect, "on_connect")
        return ws

    def _prove(self, ws: websocket.WebSocket) -> bool:
        """The token handshake of a client: our hello with a fresh nonce and our proof, then
        the server's hello, which must carry the server's proof for that nonce. False (said
        once per outage) when the server refuses us or cannot prove it knows the token."""
        assert self._token is not None
        nonce = new_nonce()
        ws.send(encode(Hello(who=self.name, nonce=nonce,
                             auth=proof(self._token, "client", self._port, self.name, nonce))))
        ws.settimeout(HELLO_TIMEOUT)
        opcode, data = ws.recv_data()
        answer: Optional[Message] = None
        if opcode == websocket.ABNF.OPCODE_TEXT:
            try:
                answer = decode(data.decode("utf-8") if isinstance(data, bytes) else data)
            except (MessageError, UnicodeDecodeError):
                answer = None
        if isinstance(answer, Hello) and proof_matches(self._token, answer.auth, "server",
                                                       self._port, answer.who, nonce):
            self.server_hello = answer
            self._token_refused = False
            if answer.version != PROTOCOL_VERSION:
                self._log.error("%s: server %s speaks protocol %d, this is %d", self.name,
                                answer.who, answer.version, PROTOCOL_VERSION)
            return True
        if isinstance(answer, Error):
            why = f"it refused our link token: {answer.message}"
        elif isinstance(answer, Hello):
            why = ("it did not prove it knows the link token: it is not a server of this "
                   "launch, so nothing is sent to it")
        else:
            why = "it did not answer our hello with its own"
        if not self._token_refused:
            self._log.error("%s: %s: %s; trying again", self.name, self.url, why)
            self._token_refused = True
        return False

    def _read(self, ws: websocket.WebSocket) -> Optional[int]:
        """Read frames until the connection ends; the close code the server gave, if any."""
        while True:
            try:
                opcode, data = ws.recv_data()
            except (websocket.WebSocketException, OSError):
                self.last_close = (None, "")
                return None
            if opcode == websocket.ABNF.OPCODE_CLOSE:
                code = int.from_bytes(data[:2], "big") if len(data) >= 2 else None
                reason = data[2:].decode("utf-8", "replace") if len(data) > 2 else ""
                self.last_close = (code, reason)
                return code
            if opcode == websocket.ABNF.OPCODE_TEXT:
                try:
                    data = data.decode("utf-8") if isinstance(data, bytes) else data
                except UnicodeDecodeError:
                    pass  # decode() then reports a binary (non-text) frame
            try:
                msg = decode(data)
            except MessageError as exc:
                self._log.warning("%s: rejected a frame from %s: %s", self.name, self.url, exc)
                if exc.reply_to is not None:
                    self._reject_answer(exc.reply_to, f"the answer to request {exc.reply_to} "
                                        f"was rejected: {exc.reason}")
                if exc.msg_type == Error.TYPE:
                    continue  # an error is never answered, even a malformed one
                try:
                    with self._send_lock:
                        ws.send(error_reply(exc))
                except (websocket.WebSocketException, OSError):
                    self.last_close = (None, "")
                    return None
                continue
            if isinstance(msg, Hello):
                self.server_hello = msg
                if msg.version != PROTOCOL_VERSION:
                    self._log.error("%s: server %s speaks protocol %d, this is %d", self.name,
                                    msg.who, msg.version, PROTOCOL_VERSION)
                continue
            with self._cond:
                if msg.reply_to is not None and msg.reply_to in self._abandoned:
                    del self._abandoned[msg.reply_to]
                    self._log.debug("%s: dropped a late %s answering request %d", self.name,
                                    msg.type, msg.reply_to)
                    continue
                why = self._wrong_answer(msg)
                if why is not None:
                    request_id, text = why
                    self._log.warning("%s: %s", self.name, text)
                    self._rejected[request_id] = text
                    self._cond.notify_all()
                    continue
                self._inbox.append(msg)
                self._cond.notify_all()

    def _wrong_answer(self, msg: Message) -> Optional[Tuple[int, str]]:
        """(request id, why) when ``msg`` answers a request in flight but may not be taken
        as its answer: of another epoch than the request's, or (a reply without ``reply_to``)
        answering it only by the version 1 rules. Called with ``_cond`` held."""
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

    def _reject_answer(self, request_id: int, why: str) -> None:
        """Fail the request in flight ``request_id`` at once with ``why``."""
        with self._cond:
            if request_id in self._requests:
                self._rejected[request_id] = why
                self._cond.notify_all()
