"""What both ends of a link share: where a link is, the websocket settings both ends use, and
the hello handshake of one connection with its link-token proofs (:class:`Session`), written
once for the server (:mod:`ros_hrc.link.server`) and the client (:mod:`ros_hrc.link.client`).

The handshake (docs/protocol.md, "The link token"): the client's first frame is a hello with a
fresh nonce and its proof of the launch's token; the server checks the proof (and refuses a
nonce it accepted before), then answers with a hello carrying its own proof over the client's
nonce, which the client checks in turn. Each proof covers the sender's side, the server's port,
the sender's name and the client's nonce (:func:`~ros_hrc.link.token.proof`). A
:class:`Session` builds this end's hello and judges the other end's: it is Sans-I/O, and each
end moves the frames its own way.
"""
from __future__ import annotations

import collections
import logging
import random
import socket
import time
from typing import Any, Dict, Optional

from ros_hrc import settings
from ros_hrc.link.codec import MAX_MESSAGE_BYTES
from ros_hrc.link.messages import PROTOCOL_VERSION, Error, Hello, Message
from ros_hrc.link.token import new_nonce, proof, proof_matches

#: Where a server binds and a client connects unless told otherwise: the host setting's.
DEFAULT_HOST: str = settings.default("host")
#: Frames above this size are not read at all (close code 1009). Between the protocol's limit
#: and this one, an oversized message is still answered with an error and the link stays up.
FRAME_LIMIT_BYTES = 4 * MAX_MESSAGE_BYTES
#: Seconds a closing connection may take to finish its handshake. A local peer answers in
#: microseconds; one that does not should not hold up a stop (websockets' default is 10 s).
CLOSE_TIMEOUT = 2.0
#: websockets' keepalive, on both ends: a ping every this many seconds, and a peer whose pong
#: does not come within :data:`KEEPALIVE_TIMEOUT` is dropped (its connection fails, 1011).
KEEPALIVE_INTERVAL = 20.0
KEEPALIVE_TIMEOUT = 20.0
#: Close code of a refusal (e.g. "this seat is taken", "link token required"): policy violation.
CLOSE_REFUSED = 1008
#: Close code of a server that stops: the client reconnects quietly.
CLOSE_GOING_AWAY = 1001
#: Seconds each end waits for the other's hello: a server for the first frame of a client
#: (with a token, an unproven connection holds no thread for long), a client for the answer.
HELLO_TIMEOUT = 10.0
# Accepted hello nonces a server remembers, to refuse a replayed hello.
_REMEMBERED_NONCES = 65536


#: Where :func:`free_port` looks first: below the kernel's ephemeral range (Linux's default
#: 32768-60999), from which every client socket and every server bound to port 0 (a
#: roslaunch's own XML-RPC server, for one) takes its port, so that another stack's
#: roslaunch cannot take a port picked here before it is bound.
PICKED_PORTS = range(20000, 32768)
#: Random tries there before falling back to a port the kernel picks.
PICK_TRIES = 64


def _ephemeral_low() -> int:
    """The first port of the kernel's ephemeral range (32768 when it cannot be read)."""
    try:
        with open("/proc/sys/net/ipv4/ip_local_port_range") as f:
            return int(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def free_port(host: str = DEFAULT_HOST) -> int:
    """A TCP port free on ``host`` now: for a stack of one's own (its roscore and links)
    beside others on the same machine. It is drawn outside the kernel's ephemeral range
    when that leaves room (:data:`PICKED_PORTS`), so only another explicit pick can take it
    before it is bound, never an ephemeral one; else the kernel's choice."""
    low = _ephemeral_low()
    ports = [p for p in (random.choice(PICKED_PORTS) for _ in range(PICK_TRIES)) if p < low]
    for port in ports:
        with socket.socket() as s:
            try:
                s.bind((host, port))
            except OSError:
                continue
            return port
    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def link_url(port: int, host: str = DEFAULT_HOST) -> str:
    """The websocket URL of a server of this package."""
    return f"ws://{host}:{port}"


def deadline_after(timeout: Optional[float]) -> Optional[float]:
    """The monotonic time ``timeout`` seconds from now (``None``: no deadline)."""
    return None if timeout is None else time.monotonic() + max(0.0, timeout)


def time_left(deadline: Optional[float]) -> Optional[float]:
    """Seconds until ``deadline``, never below 0 (``None``: no deadline, wait on)."""
    return None if deadline is None else max(0.0, deadline - time.monotonic())


def websocket_settings(log: logging.Logger) -> Dict[str, Any]:
    """The keyword arguments both ends give websockets (``serve`` / ``reconnect``): no
    compression (frames are small and local, and ``max_size`` then bounds the bytes actually
    read), the frame limit, the close timeout, the keepalive, and a logger of its own below
    ``log`` whose INFO lines, which repeat ours, are left out (its warnings and errors show)."""
    library_log = log.getChild("websockets")
    if library_log.level == logging.NOTSET:
        library_log.setLevel(logging.WARNING)
    return dict(compression=None, max_size=FRAME_LIMIT_BYTES, close_timeout=CLOSE_TIMEOUT,
                ping_interval=KEEPALIVE_INTERVAL, ping_timeout=KEEPALIVE_TIMEOUT,
                logger=library_log)


def version_mismatch(hello: Hello) -> Optional[str]:
    """What to say when a hello names another protocol version than ours (``None``: same)."""
    if hello.version == PROTOCOL_VERSION:
        return None
    return f"speaks protocol {hello.version}, this is {PROTOCOL_VERSION}"


class UsedNonces:
    """The nonces of the hellos a server accepted (the latest :data:`_REMEMBERED_NONCES`), so
    that a replayed hello is refused."""

    def __init__(self) -> None:
        self._seen: "collections.OrderedDict[str, None]" = collections.OrderedDict()

    def __contains__(self, nonce: str) -> bool:
        return nonce in self._seen

    def add(self, nonce: str) -> None:
        self._seen[nonce] = None
        while len(self._seen) > _REMEMBERED_NONCES:
            self._seen.popitem(last=False)


class Session:
    """The hello handshake of one connection, and what it established, at either end.

    ``side`` is this end (``"client"`` or ``"server"``), ``name`` the name it says in its
    hello, ``port`` the server's port and ``token`` the launch's link token (``None``: no proof
    is asked or given, as for a server made without one in a test). After the handshake,
    ``who`` is the name the other end said, ``said_hello`` whether it said one, and ``proven``
    whether it proved the token (always true without a token)."""

    def __init__(self, side: str, name: str, port: int, token: Optional[str]) -> None:
        if side not in ("client", "server"):
            raise ValueError(f"a session's side is 'client' or 'server', not {side!r}")
        self.side = side
        self.name = name
        self.port = port
        self.token = token
        #: The client's nonce, which both proofs of this connection cover.
        self.nonce: Optional[str] = None
        self.who = "?"
        self.said_hello = False
        self.proven = token is None

    # -- the client's part --------------------------------------------------------------------

    def opening_hello(self) -> Hello:
        """The client's first frame: its name and, with a token, a fresh nonce and its proof."""
        if self.token is None:
            return Hello(who=self.name)
        self.nonce = new_nonce()
        return Hello(who=self.name, nonce=self.nonce, auth=self._own_proof())

    def check_answer(self, answer: Optional[Message]) -> Optional[str]:
        """Why the server's answer to our hello (``None``: no message came, or an unreadable
        one) does not show it is a server of this launch; ``None`` when its hello proves the
        token, and then it is taken."""
        if isinstance(answer, Hello) and self._proves(answer):
            self._take(answer)
            self.proven = True
            return None
        if isinstance(answer, Error):
            return f"it refused our link token: {answer.message}"
        if isinstance(answer, Hello):
            return ("it did not prove it knows the link token: it is not a server of this "
                    "launch, so nothing is sent to it")
        return "it did not answer our hello with its own"

    # -- the server's part --------------------------------------------------------------------

    def check_hello(self, first: Message, used: UsedNonces) -> Optional[str]:
        """Why a client's first message does not prove the link token (``None``: it does).
        ``used`` holds the nonces accepted before: a replayed hello is refused."""
        if not isinstance(first, Hello):
            return f"a {first.type} message before its hello"
        if first.auth is None or first.nonce is None:
            return "a hello without a proof of the link token (no auth and nonce)"
        if first.nonce in used:
            return "a hello whose nonce was used before (a replay)"
        self.nonce = first.nonce
        if not self._proves(first):
            return "a hello with a wrong proof of the link token (another launch's token?)"
        used.add(first.nonce)
        self.proven = True
        return None

    def answer(self, hello: Hello) -> Hello:
        """Take a client's hello (the name it says) and give the server's answer: with a
        token, the server's proof over the client's nonce."""
        self._take(hello)
        self.nonce = hello.nonce
        auth = self._own_proof() if self.token is not None and self.nonce is not None else None
        return Hello(who=self.name, reply_to=hello.id, auth=auth)

    # -- both ---------------------------------------------------------------------------------

    def _take(self, hello: Hello) -> None:
        self.who = hello.who
        self.said_hello = True

    def _own_proof(self) -> str:
        assert self.token is not None and self.nonce is not None
        return proof(self.token, self.side, self.port, self.name, self.nonce)

    def _proves(self, hello: Hello) -> bool:
        """Whether the other end's hello proves the token for this connection's nonce."""
        other = "server" if self.side == "client" else "client"
        return (self.token is not None and self.nonce is not None
                and proof_matches(self.token, hello.auth, other, self.port, hello.who,
                                  self.nonce))
