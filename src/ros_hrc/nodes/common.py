"""What every ros_hrc node shares: reading its parameters once, calling Trigger services,
and routing the ROS-free rooms' Python logging to the node's terminal."""
from __future__ import annotations

import logging
import threading
import time
from dataclasses import fields
from typing import Any, Dict, Tuple, Type, TypeVar

import rospy
from std_srvs.srv import Trigger

from ros_hrc.errors import HrcError
from ros_hrc.loop import settings

C = TypeVar("C")


def read_config(config_type: Type[C]) -> C:
    """Build a config dataclass from the node's private parameters (``~name``). A field that
    is one of the launch settings (:mod:`ros_hrc.loop.settings`) is parsed and checked there,
    and an empty value takes the setting's default: the one source of defaults. Other fields
    take the dataclass default when unset; types are coerced."""
    values = {}
    for f in fields(config_type):
        default = f.default
        value = rospy.get_param(f"~{f.name}", default)
        if f.name in settings.SETTINGS:
            value = settings.parse(f.name, value)
        elif isinstance(default, bool) and isinstance(value, str):
            value = value.strip().lower() in ("1", "true", "yes", "on")
        elif isinstance(default, (int, float)) and not isinstance(default, bool):
            value = type(default)(value)
        values[f.name] = value
    return config_type(**values)


def route_python_logging(level: int = logging.INFO) -> None:
    """Show the link and toolkit loggers (plain Python logging) on the node's stderr."""
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("[%(levelname)s] [%(name)s] %(message)s"))
    logger = logging.getLogger("ros_hrc")
    logger.addHandler(handler)
    logger.setLevel(level)


def init_node_when_master_is_up(name: str, wait: float = 60.0) -> None:
    """rospy.init_node (anonymous, without rospy's signal handlers), retried while the roscore
    that the caller has just launched is starting."""
    deadline = time.monotonic() + wait
    while True:
        try:
            rospy.init_node(name, anonymous=True, disable_signals=True)
            return
        except Exception:  # the master is not up yet
            if time.monotonic() > deadline:
                raise
            time.sleep(0.5)


class ServiceUnavailable(HrcError):
    """A ROS service the node needs could not be reached or failed in transport."""


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
