"""The protocol's server: websockets' threaded server, running in a background thread. The
human node serves 9090 (for the MDP process) and the POMDP process 7070 (for the coordinator).

It calls ``handler(message, peer)`` (a function, or a
:class:`~ros_hrc.link.protocol.DispatchTable`) for each well-formed message; a malformed or
unknown frame is answered with an ``error`` and the handler never sees it; an exception in the
handler is caught at the dispatch point, logged and answered with an ``error`` (``code:
"failed"``, ``reply_to`` the message's ``id``). An ``error`` is never answered with an
``error``. The connection and the process stay up either way. A server with a link token takes
a client only once its hello proves the token (:class:`~ros_hrc.link.session.Session`); any
other first frame, or none within the hello timeout, is refused with one ``error`` and closed.

Sends never block the server: each client is a :class:`~ros_hrc.link.peer.Peer` with an outbox
of its own. A peer that does not read (its outbox has not moved for ``read_timeout`` seconds,
the launch's ``link_read_timeout``; or, the last resort, it holds ``outbox_bytes``) is
disconnected, with one warning, and everybody else is served as before; a peer that reads
slowly is served however far behind it is. A frame larger than :data:`~ros_hrc.link.session.FRAME_LIMIT_BYTES` is not even
read: websockets closes that connection with code 1009 (message too big).

Threads: every public method is thread-safe. The handler and the ``on_connect`` /
``on_disconnect`` callbacks run on the server's connection threads, one call at a time (a lock
serialises them, so a handler need not guard its own state against itself); they may call
``peer.send`` / ``server.send``, which only queue.
"""
from __future__ import annotations

import errno
import logging
import socket
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Set, Tuple

from websockets.exceptions import ConnectionClosed, ConnectionClosedOK
from websockets.sync.server import Server, ServerConnection, serve

from ros_hrc.errors import LinkError
from ros_hrc.link.codec import decode, encode
from ros_hrc.link.messages import PROTOCOL_VERSION, REPLY_TYPES, Error, Hello, Message
from ros_hrc.link.peer import OUTBOX_BYTES, READ_TIMEOUT, Peer
from ros_hrc.link.refusals import (ERR_FAILED, ERR_REFUSED, ERR_UNAUTHORIZED, ERR_VERSION,
                                   MessageError)
from ros_hrc.link.replies import as_reply, error_reply
from ros_hrc.link.session import (CLOSE_GOING_AWAY, CLOSE_REFUSED, CLOSE_TIMEOUT, DEFAULT_HOST,
                                  HELLO_TIMEOUT, Session, UsedNonces, deadline_after,
                                  link_url, time_left, version_mismatch, websocket_settings)

#: Pause between attempts when accepting a connection fails for want of a resource (file
#: descriptors, memory): the connection waits in the listen queue meanwhile.
ACCEPT_RETRY_PAUSE = 0.1
# accept() failures that pass: the listening socket is fine, the process or the peer was not.
_TRANSIENT_ACCEPT_ERRORS = frozenset({errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM,
                                      errno.ECONNABORTED, errno.EPROTO, errno.EPERM,
                                      errno.EINTR, errno.EAGAIN})

_log = logging.getLogger("ros_hrc.link")


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

    ``token`` is the launch's link token: a client must prove it in its hello, within
    ``hello_timeout`` seconds (``None``: no proof asked, as in tests). Sends never block:
    ``read_timeout`` (seconds a peer's outbox may go without a frame sent) and
    ``outbox_bytes`` (the memory it may hold, the last resort) bound how long a peer may stop
    reading before it is disconnected."""

    def __init__(self, port: int, handler: Handler, *, host: str = DEFAULT_HOST,
                 name: str = "server", on_connect: Optional[PeerCallback] = None,
                 on_disconnect: Optional[PeerCallback] = None,
                 read_timeout: float = READ_TIMEOUT,
                 outbox_bytes: int = OUTBOX_BYTES, token: Optional[str] = None,
                 hello_timeout: float = HELLO_TIMEOUT) -> None:
        if not read_timeout > 0:
            raise ValueError(f"{name}: read_timeout must be > 0, got {read_timeout}")
        if outbox_bytes < 1:
            raise ValueError(f"{name}: outbox_bytes must be >= 1, got {outbox_bytes}")
        self.host = host
        self.name = name
        self.read_timeout = float(read_timeout)
        self.outbox_bytes = int(outbox_bytes)
        self.hello_timeout = float(hello_timeout)
        self._token = token
        self._used_nonces = UsedNonces()
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
        self._greeted: Set[int] = set()
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
        try:
            self._server = serve(self._serve_connection,
                                 sock=_listen(self.host, self._port, self.name, self._log),
                                 process_request=self._admit, **websocket_settings(self._log))
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
        listening; a peer that does not take its frames within
        :data:`~ros_hrc.link.session.CLOSE_TIMEOUT` is cut. Waits for a running handler call
        to finish, so never call it from the handler. Idempotent."""
        server, self._server = self._server, None
        if server is None:
            return
        # From now on an opening handshake gets HTTP 503, so a client that reconnects at once
        # does not land on this server again while its connections are closed one by one.
        self._accepting = False
        with self._peers_changed:
            live = list(self._live)
        # Each peer's outbox is sent before its close (websockets' own shutdown would close
        # the connections with what is queued still unsent).
        for peer in live:
            peer.close(CLOSE_GOING_AWAY, "server stopping")
        deadline = deadline_after(CLOSE_TIMEOUT)
        for peer in live:
            peer._writer.join(time_left(deadline))
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
        deadline = deadline_after(timeout)

        def ready() -> bool:
            if who is None:
                return bool(self._peers)
            return any(p.who == who for p in self._peers.values())

        with self._peers_changed:
            while not ready():
                if self._server is None:
                    return False
                left = time_left(deadline)
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
        """Disconnect a peer whose outbox has not moved for longer than ``read_timeout``: it
        reads nothing (its writer thread is blocked in a send, and websockets has no send
        timeout)."""
        interval = min(0.5, max(0.01, self.read_timeout / 4))
        while not self._stopping.wait(interval):
            now = time.monotonic()
            with self._peers_changed:
                live = list(self._live)
            for peer in live:
                stalled = peer._stalled_for(now)
                if stalled > self.read_timeout:
                    peer.abort(f"it has read nothing for {stalled:.1f} s with "
                               f"{peer.queued} frames waiting (link_read_timeout "
                               f"{self.read_timeout:g} s): it does not read")

    def _admit(self, connection: ServerConnection, request: Any) -> Any:
        """websockets' ``process_request``: refuse the handshake while stopping."""
        if not self._accepting:
            return connection.respond(503, f"{self.name} is stopping\n")
        return None

    def _writer_done(self, peer: Peer) -> None:
        with self._peers_changed:
            self._live.discard(peer)

    def _serve_connection(self, connection: ServerConnection) -> None:
        peer = Peer(connection, Session("server", self.name, self.port, self._token),
                    server_name=self.name, outbox_bytes=self.outbox_bytes, log=self._log,
                    on_writer_exit=self._writer_done)
        with self._peers_changed:
            self._peers[peer.id] = peer
            self._live.add(peer)
            peer._start()  # under the lock: stop() never sees a writer not yet started
            self._peers_changed.notify_all()
        self._log.info("%s: client connected from %s", self.name, peer.address)
        try:
            if not peer.session.proven:   # its hello comes first, and soon
                try:
                    first = connection.recv(timeout=self.hello_timeout)
                except TimeoutError:
                    self._refuse(peer, f"no hello within {self.hello_timeout:g} s")
                else:
                    self._dispatch(peer, first)
            for frame in connection:
                self._dispatch(peer, frame)
        except ConnectionClosedOK:
            pass   # closed normally before its first frame
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
        if peer._closing:
            return  # refused or closing: nothing it sends acts any more
        if not peer.session.proven:
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
            if peer.session.said_hello:
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
        """The first frame of a client of a server with a token: a hello proving the token
        (then the client is greeted), or the client is refused and closed."""
        try:
            msg = decode(frame)
        except MessageError as exc:
            if exc.msg_type == Error.TYPE:   # never answered: just closed
                self._refuse(peer, "an error instead of its hello", answer=False)
            else:
                self._refuse(peer, f"a malformed first frame ({exc.reason})", exc.msg_id)
            return
        why = peer.session.check_hello(msg, self._used_nonces)
        if why is None:
            self._greet(peer, msg)
        else:
            self._refuse(peer, why, msg.id, answer=not isinstance(msg, Error))

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
        """Answer a client's hello with ours, and tell the owner a client came."""
        answer = peer.session.answer(hello)
        mismatch = version_mismatch(hello)
        if mismatch is not None:
            self._log.error("%s: %r %s", self.name, peer, mismatch)
            peer.send(Error(message=f"protocol version {hello.version} is not supported; "
                                    f"{self.name} speaks {PROTOCOL_VERSION}",
                            in_reply_to=Hello.TYPE, code=ERR_VERSION, reply_to=hello.id))
        peer.send(answer)
        with self._dispatch_lock:
            if peer.id not in self._greeted:
                self._mark_greeted(peer)
        with self._peers_changed:
            self._peers_changed.notify_all()  # wait_for_client(who=...) may be waiting

    def _mark_greeted(self, peer: Peer) -> None:
        """Record the client as known and tell the owner; under the dispatch lock."""
        with self._peers_changed:
            self._greeted.add(peer.id)
        self._log.debug("%s: %r says hello", self.name, peer)
        if self._on_connect is not None:
            self._call_back(self._on_connect, peer)

    def _call_back(self, callback: PeerCallback, peer: Peer) -> None:
        try:
            callback(peer)
        except Exception:  # a failing callback must not take the connection down
            self._log.exception("%s: callback %s failed for %r", self.name,
                                getattr(callback, "__name__", callback), peer)
