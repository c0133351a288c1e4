"""What every ros_hrc node shares: reading its parameters once, calling Trigger services,
and routing the ROS-free rooms' Python logging to the node's terminal."""
from __future__ import annotations

import logging
import threading
import time
from dataclasses import fields
from typing import Dict, Tuple, Type, TypeVar

import rospy
from std_srvs.srv import Trigger

from ros_hrc.errors import HrcError

C = TypeVar("C")


def read_config(config_type: Type[C]) -> C:
    """Build a config dataclass from the node's private parameters (``~name``), taking the
    dataclass defaults (the launch defaults) for the ones not set; types are coerced."""
    values = {}
    for f in fields(config_type):
        default = f.default
        value = rospy.get_param(f"~{f.name}", default)
        if isinstance(default, bool) and isinstance(value, str):
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
    """Calls std_srvs/Trigger services by name over persistent connections (the world's
    predicates are asked every step), one lock per service so calls never interleave."""

    def __init__(self, wait_timeout: float = 30.0) -> None:
        self.wait_timeout = wait_timeout
        self._proxies: Dict[str, rospy.ServiceProxy] = {}
        self._locks: Dict[str, threading.Lock] = {}
        self._guard = threading.Lock()

    def __call__(self, name: str) -> Tuple[bool, str]:
        """(success, message) of the service; raises ServiceUnavailable (saying which and
        why) when it cannot be reached."""
        with self._guard:
            lock = self._locks.setdefault(name, threading.Lock())
        with lock:
            for attempt in (1, 2):
                try:
                    proxy = self._proxies.get(name)
                    if proxy is None:
                        rospy.wait_for_service(name, timeout=self.wait_timeout)
                        proxy = self._proxies[name] = rospy.ServiceProxy(name, Trigger,
                                                                         persistent=True)
                    response = proxy()
                    return bool(response.success), response.message
                except rospy.ROSException as exc:   # wait_for_service timed out
                    raise ServiceUnavailable(f"service {name} is not available: {exc}") from exc
                except (rospy.ServiceException, OSError) as exc:
                    # A persistent link breaks when the server restarts: try once anew.
                    stale = self._proxies.pop(name, None)
                    if stale is not None:
                        stale.close()
                    if attempt == 2:
                        raise ServiceUnavailable(f"service {name} failed: {exc}") from exc
        raise ServiceUnavailable(f"service {name} failed")

    def close(self) -> None:
        for proxy in self._proxies.values():
            proxy.close()
        self._proxies.clear()
