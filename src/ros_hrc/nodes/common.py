"""What every ros_hrc node shares: starting as a node whose connections one bad client cannot
stall, reading its parameters once, calling Trigger services, waiting (however long it takes,
saying so) for the services a node needs before it starts, and routing the ROS-free rooms'
Python logging to the node's terminal."""
from __future__ import annotations

import logging
import os
import socket
import struct
import sys
import threading
import time
from dataclasses import MISSING, field, fields
from typing import Any, Callable, Dict, Iterable, List, Optional, Sequence, Tuple, Type, TypeVar

import rosgraph
import rospy
from std_srvs.srv import Trigger

from ros_hrc.errors import HrcError
from ros_hrc import settings

C = TypeVar("C")
#: How a node reads a parameter: ``get_param(name, default)`` (rospy's; the tests give a fake).
ParamReader = Callable[[str, Any], Any]
#: A config field's metadata key naming the parameter it is read from, when that is not the
#: node's private parameter of the field's name (:func:`parameter`).
_PARAM = "ros_param"


def parameter(default: Any, name: str) -> Any:
    """A config dataclass field read from the parameter ``name`` (e.g. ``/use_sim_time``)
    rather than the node's private ``~<field name>``."""
    return field(default=default, metadata={_PARAM: name})


def read_config(config_type: Type[C], get_param: Optional[ParamReader] = None,
                settings_from: Optional[Dict[str, Any]] = None) -> C:
    """The node's configuration: the config dataclass ``config_type`` built from the node's
    parameters, read once (``get_param``: rospy's by default). The one way a node reads its
    parameters.

    Each field is read from the node's private parameter of its name (``~name``), or from the
    one its :func:`parameter` names. A field named after a launch setting
    (:mod:`ros_hrc.settings`) is parsed and checked there, and takes the table's default when
    unset or empty (the one source of defaults; a bad value raises the table's one-line
    :class:`~ros_hrc.settings.SettingError`); with ``settings_from`` (a launch's resolved
    configuration, setting name -> value), such a field that names no parameter of its own
    is read there instead. Any other field takes the dataclass default when unset, coerced
    to the default's type: a bool from a word (true/1/yes/on), a number, a tuple from a list
    or a text of items apart by spaces or commas."""
    read = rospy.get_param if get_param is None else get_param
    values = {}
    for f in fields(config_type):
        name = f.metadata.get(_PARAM, f"~{f.name}")
        if f.name in settings.SETTINGS:
            given = settings_from.get(f.name, "") \
                if settings_from is not None and _PARAM not in f.metadata else read(name, "")
            values[f.name] = settings.parse(f.name, given)
            continue
        default = f.default if f.default is not MISSING else f.default_factory()  # type: ignore[misc]
        values[f.name] = _coerced(read(name, default), default)
    return config_type(**values)


def _coerced(value: Any, default: Any) -> Any:
    """A parameter's ``value`` as the type of the field's ``default``."""
    if isinstance(default, bool):
        return value.strip().lower() in settings.TRUE_WORDS if isinstance(value, str) else value
    if isinstance(default, (int, float)):
        return type(default)(value)
    if isinstance(default, tuple):
        items = value.replace(",", " ").split() if isinstance(value, str) else value
        kind = type(default[0]) if default else str
        return tuple(kind(item) for item in items)
    return value


def route_python_logging(level: int = logging.INFO) -> None:
    """Show the link and toolkit loggers (plain Python logging) on the node's stderr."""
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("[%(levelname)s] [%(name)s] %(message)s"))
    logger = logging.getLogger("ros_hrc")
    logger.addHandler(handler)
    logger.setLevel(level)


#: Seconds a client that connects to a node's TCPROS port gets to send its whole handshake
#: header before the node closes the connection.
HANDSHAKE_WAIT = 10.0
#: The largest handshake header rospy itself reads (bytes).
MAX_HEADER = 1_000_000


def init_node(name: str, **kwargs: Any) -> None:
    """``rospy.init_node`` for every ros_hrc node, its TCPROS server guarded first
    (:func:`guard_inbound_connections`)."""
    guard_inbound_connections()
    leave_latest_log_link_to_roslaunch()
    rospy.init_node(name, **kwargs)


def leave_latest_log_link_to_roslaunch(argv: Optional[List[str]] = None) -> None:
    """Keep rospy from renewing ``$ROS_HOME/log/latest`` in a node roslaunch started.

    Why: roslaunch points ``latest`` at its run's log directory before it starts the nodes;
    then each rospy node renews the link again (remove it, then link anew: not atomic), and
    nodes starting together raced, printing ``cannot create a symlink to latest log
    directory`` (one removed the link another had just made, or linked where one already
    was). rospy renews it only when the node's log file (``__log:=``) is not directly in
    ``ROS_LOG_DIR``: this makes the log file's directory the node's ``ROS_LOG_DIR``, and the
    log file stays where roslaunch put it. A node run by hand (no ``__log:=``) keeps
    rospy's way."""
    words = sys.argv if argv is None else argv
    logs = [word[len("__log:="):] for word in words if word.startswith("__log:=")]
    if logs and os.path.isabs(logs[-1]):
        os.environ["ROS_LOG_DIR"] = os.path.dirname(logs[-1])


def guard_inbound_connections() -> None:
    """Make this process's rospy TCPROS server take each inbound connection on a thread of its
    own, and close one whose handshake header has not come whole in :data:`HANDSHAKE_WAIT` s.

    Why: rospy's server accepts connections one at a time and reads each header with no time
    limit on the accepting thread, so a single client that connects and sends no header stalls
    every later connection to the node (its services, its topics) for good. It happened in a
    test that restarts the stack on one master: a new hrc_obs's TCPROS server (then the
    planner's relay node) got the port the previous hrc_obs's XML-RPC server had; a client
    that still held the old address sent its HTTP request there, which rospy read as a header
    of 1.4 GB and waited for, and the new hrc_human's first reset (/hrc/obs/reset_planner)
    hung until the test gave up. The same can follow any node's respawn. Call before
    rospy.init_node; once per process."""
    from rospy.impl import tcpros_base
    server = tcpros_base.TCPROSServer
    if getattr(server, "_hrc_guarded", False):
        return
    handle = server._tcp_server_callback

    def inbound(self, sock, client_addr) -> None:
        def run() -> None:
            if handshake_arrives(sock, HANDSHAKE_WAIT):
                handle(self, sock, client_addr)
            else:
                rospy.logdebug("closing a connection from %s that sent no ROS handshake in "
                               "%.0f s", client_addr, HANDSHAKE_WAIT)
                sock.close()
        threading.Thread(target=run, name="tcpros-inbound", daemon=True).start()

    server._tcp_server_callback = inbound
    server._hrc_guarded = True


def handshake_arrives(sock: socket.socket, wait: float) -> bool:
    """Whether a whole TCPROS handshake header (a 4-byte little-endian length, then that many
    bytes, at most :data:`MAX_HEADER`) is waiting on ``sock`` within ``wait`` s. It is only
    peeked at (MSG_PEEK), left for rospy to read; the socket is blocking again after. A
    connection closed before any byte counts as arrived: rospy then says what it got."""
    deadline = time.monotonic() + wait
    need = 4
    try:
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            sock.settimeout(left)
            data = sock.recv(need, socket.MSG_PEEK)
            if not data:
                return True
            if len(data) >= 4:
                size = struct.unpack("<I", data[:4])[0]
                if size > MAX_HEADER:
                    return False
                need = 4 + size
            if len(data) >= need:
                return True
            time.sleep(0.005)   # part of it is in: a blocking peek would return at once
    except OSError:            # timed out, or reset
        return False
    finally:
        try:
            sock.settimeout(None)
        except OSError:
            pass


def init_node_when_master_is_up(name: str, wait: float = 60.0) -> None:
    """:func:`init_node` (anonymous, without rospy's signal handlers), retried while the
    roscore that the caller has just launched is starting."""
    deadline = time.monotonic() + wait
    while True:
        try:
            init_node(name, anonymous=True, disable_signals=True)
            return
        except Exception:  # the master is not up yet
            if time.monotonic() > deadline:
                raise
            time.sleep(0.5)


class ServiceUnavailable(HrcError):
    """A ROS service the node needs could not be reached or failed in transport."""


def registered_services() -> set:
    """The names of the services the ROS master knows now (empty when it cannot be asked)."""
    try:
        _pubs, _subs, services = rosgraph.Master(rospy.get_name()).getSystemState()
    except (rosgraph.MasterException, OSError):
        return set()
    return {name for name, _providers in services}


class ServiceWait:
    """Waits, with no timeout, until every named service is registered, saying every
    ``every`` seconds which are still awaited (``say``, one line), and once, when they are
    all up after such a line, how long it took.

    ``groups``: (what, names) pairs, e.g. ``("the world", ["/hrc/world/reset", ...])``; the
    line reads ``waiting for the world: /hrc/world/reset, ...; for the robot planner
    (despot_pomdp): ws://127.0.0.1:7070 (30 s)``. ``registered()`` gives the names up now
    (:func:`registered_services`, and whatever else the caller counts, such as a link that is
    connected; the tests give a fake). :meth:`run` does the waiting (on a
    thread of its own); :meth:`wait` blocks a caller until it is done, and raises
    :class:`ServiceUnavailable` if the wait was stopped (shutdown) first."""

    def __init__(self, groups: Sequence[Tuple[str, Iterable[str]]],
                 say: Callable[[str], None], every: float = 10.0, poll: float = 0.5,
                 registered: Callable[[], set] = registered_services,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.groups: List[Tuple[str, Tuple[str, ...]]] = [(what, tuple(names))
                                                          for what, names in groups]
        self.say = say
        self.every = every
        self.poll = poll
        self.registered = registered
        self.clock = clock
        self._lock = threading.Lock()
        self._missing: List[str] = [n for _what, names in self.groups for n in names]
        self._done = threading.Event()
        self._stopped = threading.Event()
        self.waited = 0.0   # seconds it took

    @property
    def ready(self) -> bool:
        return self._done.is_set() and not self._stopped.is_set()

    def missing(self) -> List[str]:
        with self._lock:
            return list(self._missing)

    def describe(self) -> str:
        """``waiting for <what>: names; for <what>: names`` of the services still awaited."""
        missing = set(self.missing())
        parts = []
        for what, names in self.groups:
            awaited = [n for n in names if n in missing]
            if awaited:
                parts.append(f"{'waiting ' if not parts else ''}for {what}: {', '.join(awaited)}")
        return "; ".join(parts)

    def check(self) -> bool:
        """Ask once; True when every service is registered."""
        up = self.registered()
        with self._lock:
            self._missing = [n for n in self._missing if n not in up]
            return not self._missing

    def run(self) -> None:
        """Wait until every service is registered (or :meth:`stop`)."""
        started = self.clock()
        next_line = started + self.every
        said = False
        while not self._stopped.is_set():
            if self.check():
                self.waited = self.clock() - started
                if said:
                    self.say(f"{self._what_all()} up after {self.waited:.0f} s: the loop "
                             "starts (its first reset, then step 0)")
                self._done.set()
                return
            now = self.clock()
            if now >= next_line:
                self.say(f"{self.describe()} ({now - started:.0f} s; no step is taken "
                         "before they are up)")
                said = True
                while next_line <= now:
                    next_line += self.every
            self._stopped.wait(self.poll)

    def _what_all(self) -> str:
        whats = [what for what, _names in self.groups]
        joined = " and ".join(whats) if len(whats) < 3 else \
            ", ".join(whats[:-1]) + " and " + whats[-1]
        return joined[0].upper() + joined[1:] + (" are" if len(whats) > 1 else " is")

    def wait(self, timeout: Optional[float] = None) -> bool:
        """Block until the services are up (True), ``timeout`` ran out (False); raises
        :class:`ServiceUnavailable` when the wait was stopped before."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self._done.is_set():
            if self._stopped.is_set():
                raise ServiceUnavailable(f"stopped while {self.describe()}")
            left = 0.5 if deadline is None else min(0.5, deadline - time.monotonic())
            if left <= 0:
                return False
            self._done.wait(left)
        return True

    def stop(self) -> None:
        self._stopped.set()


class TriggerCaller:
    """Calls std_srvs/Trigger services by name over persistent connections (one per service,
    made on first use), one lock per service so calls never interleave.

    A call is never repeated: an action may have run before its answer was lost. When a call
    fails its connection is dropped (the next call makes a new one, e.g. to a respawned
    node) and :class:`ServiceUnavailable` says which service and why."""

    def __init__(self, wait_timeout: float = 30.0) -> None:
        self.wait_timeout = wait_timeout
        self._proxies: Dict[str, rospy.ServiceProxy] = {}
        self._locks: Dict[str, threading.Lock] = {}
        self._guard = threading.Lock()

    def __call__(self, name: str) -> Tuple[bool, str]:
        """(success, message) of the service; raises ServiceUnavailable when it cannot be
        reached, or when its handler failed (a service error: a fault, not a ``false``)."""
        response = self.call(name, Trigger)
        return bool(response.success), response.message

    def call(self, name: str, service_type: type, *args: Any) -> Any:
        """The response of any service type, with the same connection handling."""
        with self._guard:
            lock = self._locks.setdefault(name, threading.Lock())
        with lock:
            try:
                proxy = self._proxies.get(name)
                if proxy is None:
                    rospy.wait_for_service(name, timeout=self.wait_timeout)
                    proxy = self._proxies[name] = rospy.ServiceProxy(name, service_type,
                                                                     persistent=True)
                return proxy(*args)
            except rospy.ROSException as exc:   # wait_for_service timed out, or shutdown
                self._drop(name)
                raise ServiceUnavailable(f"service {name} is not available: {exc}") from exc
            except (rospy.ServiceException, OSError) as exc:
                self._drop(name)
                raise ServiceUnavailable(f"service {name} failed: {exc}") from exc

    def _drop(self, name: str) -> None:
        stale = self._proxies.pop(name, None)
        if stale is not None:
            stale.close()

    def close(self) -> None:
        with self._guard:
            proxies, self._proxies = list(self._proxies.values()), {}
        for proxy in proxies:
            proxy.close()
