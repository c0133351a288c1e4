"""The websocket I/O of the protocol: a server that runs in a background thread and a client
that reconnects by itself. :mod:`ros_hrc.link.protocol` does all encoding and validation.

* :class:`MessageServer` (websockets' threaded server): the robot node on 8080, the human node
  on 9090 and the POMDP process on 7070. It calls ``handler(message, peer)`` for each
  well-formed message; a malformed or unknown frame is answered with an ``error`` and the
  handler never sees it; an exception in the handler is caught at the dispatch point, logged
  and answered with an ``error``. The connection and the process stay up either way.
* :class:`MessageClient` (websocket-client): the MDP process, the observer node and the POMDP
  process's link to the robot node. It retries with backoff until the server is up (servers
  may start later), says ``hello``, and reconnects whenever the connection drops (roslaunch
  respawns a process that dies: the links reconnect).

Size limits: a message larger than :data:`~ros_hrc.link.protocol.MAX_MESSAGE_BYTES` is refused
by ``encode`` before it is sent, and answered with an ``error`` when received (the connection
stays up). A frame larger than :data:`FRAME_LIMIT_BYTES` is not even read: the server closes
that connection with code 1009 (message too big), which bounds memory; the client reconnects.

Exception tree (the first two live in :mod:`ros_hrc.errors`)::

    LinkError                  the link failed: cannot bind, connection lost while sending
    ├── ProtocolError          a message is malformed, unknown or too large
    │   └── MessageError       (protocol) a message was rejected; .reason, .msg_type, .step
    ├── LinkTimeout            nothing came before the deadline (also a TimeoutError)
    ├── LinkDropped            the connection a reply was awaited on broke: it cannot come
    └── LinkClosed             the client was closed (or the server stopped) meanwhile

Threads: every public method of both classes is thread-safe. The server's handler and its
``on_connect`` / ``on_disconnect`` callbacks run on the server's connection threads, one call
at a time (a lock serialises them, so a handler need not guard its own state against
itself). The client's ``on_connect`` runs on its reader thread: it may ``send`` but must not
``receive``.
"""
from __future__ import annotations

import itertools
import logging
import socket
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Tuple

import websocket  # websocket-client
from websockets.exceptions import ConnectionClosed
from websockets.sync.server import Server, ServerConnection, serve

from ros_hrc.errors import LinkError
from ros_hrc.link.protocol import (MAX_MESSAGE_BYTES, PROTOCOL_VERSION, Ack, Error, Hello,
                                   Message, MessageError, decode, encode, error_reply)

DEFAULT_HOST = "127.0.0.1"
#: Frames above this size are not read at all (close code 1009). Between the protocol's limit
#: and this one, an oversized message is still answered with an error and the link stays up.
FRAME_LIMIT_BYTES = 4 * MAX_MESSAGE_BYTES
#: Seconds a closing connection may take to finish its handshake. A local peer answers in
#: microseconds; one that does not should not hold up stop() (websockets' default is 10 s).
CLOSE_TIMEOUT = 2.0

_log = logging.getLogger("ros_hrc.link")


class LinkTimeout(LinkError, TimeoutError):
    """A deadline passed: no connection, no message, or no reply in time."""


class LinkClosed(LinkError):
    """The client was closed, or the server stopped, while waiting."""


class LinkDropped(LinkError):
    """The connection a reply was awaited on broke. The server that would have answered has
    lost its state (it died, or restarted), so the reply will never come."""


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


class Peer:
    """One client connected to a :class:`MessageServer`, as its handler sees it.

    ``who`` is the name the client gave in its hello (``"?"`` before that), ``address`` its
    (host, port). Calling the peer, or :meth:`send`, replies to that client only."""

    _ids = itertools.count(1)

    def __init__(self, connection: ServerConnection) -> None:
        self.id = next(Peer._ids)
        self.who = "?"
        self.address: Tuple[Any, ...] = tuple(connection.remote_address or ())
        self._connection = connection
        self._lock = threading.Lock()

    def send(self, msg: Message) -> bool:
        """Send a message to this client; ``False`` if its connection is already closed."""
        return self.send_text(encode(msg))

    __call__ = send

    def send_text(self, text: str) -> bool:
        """Send an already encoded frame; ``False`` if the connection is closed."""
        try:
            with self._lock:
                self._connection.send(text)
            return True
        except ConnectionClosed:
            return False

    def __repr__(self) -> str:
        return f"Peer({self.who!r} #{self.id} at {self.address})"


Handler = Callable[[Message, Peer], Optional[Message]]
PeerCallback = Callable[[Peer], None]


class MessageServer:
    """A protocol server on ``host:port`` (``port=0``: any free port, see :attr:`port`).

    ``handler(message, peer)`` is called for each well-formed message other than ``hello``;
    it replies by calling ``peer(reply)`` or by returning the reply (``None``: no reply).
    ``on_connect(peer)`` runs once a client said hello (or sent its first message without
    one), ``on_disconnect(peer)`` when it is gone. Use :meth:`start` / :meth:`stop`, or
    ``with``."""

    def __init__(self, port: int, handler: Handler, *, host: str = DEFAULT_HOST,
                 name: str = "server", on_connect: Optional[PeerCallback] = None,
                 on_disconnect: Optional[PeerCallback] = None) -> None:
        self.host = host
        self.name = name
        self._port = port
        self._handler = handler
        self._on_connect = on_connect
        self._on_disconnect = on_disconnect
        self._server: Optional[Server] = None
        self._thread: Optional[threading.Thread] = None
        self._peers: Dict[int, Peer] = {}
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
            # actually read. socket.create_server sets SO_REUSEADDR, so a respawned server
            # can bind again while old connections linger in TIME_WAIT.
            self._server = serve(self._serve_connection, self.host, self._port,
                                 compression=None, max_size=FRAME_LIMIT_BYTES, logger=ws_log,
                                 close_timeout=CLOSE_TIMEOUT)
        except OSError as exc:
            raise LinkError(f"{self.name}: cannot listen on {self.host}:{self._port}: {exc}") \
                from exc
        self._port = self._server.socket.getsockname()[1]
        self._thread = threading.Thread(target=self._server.serve_forever,
                                        name=f"link-{self.name}", daemon=True)
        self._thread.start()
        self._log.info("%s listening on %s", self.name, self.url)
        return self

    def stop(self) -> None:
        """Close every connection (code 1001, going away) and stop listening. Waits for a
        running handler call to finish, so never call it from the handler. Idempotent."""
        server, self._server = self._server, None
        if server is None:
            return
        server.shutdown()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        with self._peers_changed:
            self._peers.clear()
            self._greeted.clear()
            self._peers_changed.notify_all()
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
        """Send a message to every connected client (or only those that said hello as
        ``who``); returns how many got it."""
        text = encode(msg)
        return sum(peer.send_text(text) for peer in self.clients()
                   if who is None or peer.who == who)

    # -- on the connection threads ----------------------------------------------------------

    def _serve_connection(self, connection: ServerConnection) -> None:
        peer = Peer(connection)
        with self._peers_changed:
            self._peers[peer.id] = peer
            self._peers_changed.notify_all()
        self._log.info("%s: client connected from %s", self.name, peer.address)
        try:
            for frame in connection:
                self._dispatch(peer, frame)
        except ConnectionClosed as exc:
            # Abnormal closes only (normal ones end the loop); 1009 is a frame over the limit.
            self._log.warning("%s: connection of %r closed: %s", self.name, peer, exc)
        finally:
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
        try:
            msg = decode(frame)
        except MessageError as exc:
            self._log.warning("%s: rejected a frame from %r: %s", self.name, peer, exc)
            peer.send_text(error_reply(exc))
            return
        if isinstance(msg, Hello):
            self._greet(peer, msg)
            return
        with self._dispatch_lock:
            if peer.id not in self._greeted:
                self._mark_greeted(peer)
            try:
                reply = self._handler(msg, peer)
            except Exception as exc:  # the dispatch point: one bad message never kills us
                self._log.exception("%s: handler failed on %s from %r", self.name, msg.type,
                                    peer)
                peer.send_text(error_reply(exc, msg.type, getattr(msg, "step", None)))
                return
            if reply is not None:
                try:
                    peer.send(reply)
                except MessageError as exc:
                    self._log.error("%s: handler returned an unsendable reply: %s",
                                    self.name, exc)
                    peer.send_text(error_reply(exc, msg.type, getattr(msg, "step", None)))

    def _greet(self, peer: Peer, hello: Hello) -> None:
        peer.who = hello.who
        if hello.version != PROTOCOL_VERSION:
            self._log.error("%s: %r speaks protocol %d, this is %d", self.name, peer,
                            hello.version, PROTOCOL_VERSION)
            peer.send(Error(message=f"protocol version {hello.version} is not supported; "
                                    f"{self.name} speaks {PROTOCOL_VERSION}",
                            in_reply_to=Hello.TYPE))
        peer.send(Hello(who=self.name))
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
    same way and says hello again, then calls ``on_connect()``. Received messages wait in an
    inbox until :meth:`receive` takes them; the server's hello is kept in
    :attr:`server_hello` instead. A malformed frame from the server is answered with an
    ``error`` and dropped. Use :meth:`connect` / :meth:`close`, or ``with`` (which connects)."""

    def __init__(self, url: str, name: str, *, connect_timeout: float = 30.0,
                 send_timeout: float = 10.0, backoff: Tuple[float, float] = (0.05, 1.0),
                 on_connect: Optional[Callable[[], None]] = None) -> None:
        self.url = url
        self.name = name
        self.connect_timeout = connect_timeout
        self.send_timeout = send_timeout
        self._backoff = backoff
        self._on_connect = on_connect
        self._cond = threading.Condition()  # guards everything below
        self._ws: Optional[websocket.WebSocket] = None
        self._connections = 0
        self._inbox: List[Message] = []
        self._closed = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._send_lock = threading.Lock()
        self.server_hello: Optional[Hello] = None
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

    def receive(self, timeout: Optional[float] = None,
                match: Optional[Callable[[Message], bool]] = None,
                connection: Optional[int] = None) -> Message:
        """The oldest received message (the oldest one for which ``match`` is true, leaving
        the others in order). Waits up to ``timeout`` seconds (``None``: until one comes or
        the client is closed). With ``connection`` (a number :meth:`send` returned), stop
        waiting as soon as that connection is gone: raises :class:`LinkDropped`. Raises
        :class:`LinkTimeout` or :class:`LinkClosed`."""
        deadline = _deadline(timeout)
        with self._cond:
            while True:
                for i, msg in enumerate(self._inbox):
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

    def request(self, msg: Message, timeout: Optional[float] = None) -> Message:
        """Send ``msg`` and wait for its answer: the ``ack`` with the same step (and, if the ack
        names ``of``, of the same type) or an ``error`` about it. Other messages stay in the
        inbox. Returns the ack or the :class:`~ros_hrc.link.protocol.Error` message; raises
        :class:`LinkDropped` if the connection breaks before the answer comes."""
        deadline = _deadline(self.send_timeout if timeout is None else timeout)
        number = self.send(msg, _remaining(deadline))
        return self.receive(_remaining(deadline), match=lambda reply: is_reply_to(reply, msg),
                            connection=number)

    def drain(self) -> List[Message]:
        """Take every message waiting in the inbox (e.g. stale ones after a reset)."""
        with self._cond:
            taken, self._inbox = self._inbox, []
            return taken

    # -- the reader thread -------------------------------------------------------------------

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
            pause, failures = self._backoff[0], 0
            self._read(ws)
            self._forget(ws)
            ws.shutdown()
            if not self._closed.is_set():
                self._log.warning("%s: lost the connection to %s; reconnecting", self.name,
                                  self.url)

    def _open(self, quiet: bool) -> Optional[websocket.WebSocket]:
        try:
            ws = websocket.create_connection(self.url, timeout=max(1.0, self._backoff[1]),
                                             enable_multithread=True)
            # Blocking from now on: the reader waits for frames; close() cuts the socket.
            ws.settimeout(None)
            ws.send(encode(Hello(who=self.name)))
        except (websocket.WebSocketException, OSError) as exc:
            # Say it once per outage, not once per retry.
            self._log.log(logging.DEBUG if quiet else logging.INFO,
                          "%s: cannot connect to %s yet (%s); retrying", self.name, self.url, exc)
            return None
        with self._cond:
            if self._closed.is_set():
                ws.shutdown()
                return None
            self._ws = ws
            self._connections += 1
            self._cond.notify_all()
        self._log.info("%s: connected to %s", self.name, self.url)
        if self._on_connect is not None:
            try:
                self._on_connect()
            except Exception:  # a failing callback must not stop the reader
                self._log.exception("%s: on_connect failed", self.name)
        return ws

    def _read(self, ws: websocket.WebSocket) -> None:
        while True:
            try:
                opcode, data = ws.recv_data()
            except (websocket.WebSocketException, OSError):
                return
            if opcode == websocket.ABNF.OPCODE_CLOSE:
                return
            if opcode == websocket.ABNF.OPCODE_TEXT:
                try:
                    data = data.decode("utf-8") if isinstance(data, bytes) else data
                except UnicodeDecodeError:
                    pass  # decode() then reports a binary (non-text) frame
            try:
                msg = decode(data)
            except MessageError as exc:
                self._log.warning("%s: rejected a frame from %s: %s", self.name, self.url, exc)
                try:
                    with self._send_lock:
                        ws.send(error_reply(exc))
                except (websocket.WebSocketException, OSError):
                    return
                continue
            if isinstance(msg, Hello):
                self.server_hello = msg
                if msg.version != PROTOCOL_VERSION:
                    self._log.error("%s: server %s speaks protocol %d, this is %d", self.name,
                                    msg.who, msg.version, PROTOCOL_VERSION)
                continue
            with self._cond:
                self._inbox.append(msg)
                self._cond.notify_all()


def is_reply_to(reply: Message, request: Message) -> bool:
    """Whether ``reply`` answers ``request``: an ``ack`` of its step (and type, when the ack
    names one; a request without a step, such as ``reset``, needs an ack naming its type),
    or an ``error`` naming its step or, lacking a step, its type."""
    step = getattr(request, "step", None)
    if isinstance(reply, Ack):
        if step is None:  # e.g. a reset: only an ack that names it answers it
            return reply.of == request.type
        return reply.step == step and reply.of in (None, request.type)
    if isinstance(reply, Error):
        if reply.in_reply_to is not None and reply.in_reply_to != request.type:
            return False
        if reply.step is not None:
            return reply.step == step
        return reply.in_reply_to == request.type
    return False
