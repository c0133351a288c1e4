"""One PyBullet physics server per world, with every call bound to it.

PyBullet's module-level functions act on "the last connected" server unless each call names
``physicsClientId``. Several worlds live in one process (tests build many), so every body
module talks to the server through a :class:`PhysicsClient`, never through ``pybullet``
directly.
"""
from __future__ import annotations

import functools
import os
import sys
import types
from typing import Any

import pybullet

from ..errors import SimulationError


class PhysicsClient:
    """A connection to one physics server; ``client.X(...)`` is ``pybullet.X(..., physicsClientId=id)``.

    Constants (``client.GEOM_BOX``, ``client.POSITION_CONTROL``) and ``client.error`` (the
    exception PyBullet raises) are passed through unchanged.
    """

    def __init__(self, gui: bool = False, options: str = "") -> None:
        """``options``: command-line options of PyBullet's window (``--width=1024
        --height=768``, ``--background_color_red=0.8`` ...); ignored without ``gui``."""
        if gui and sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
            # PyBullet's GUI exits the whole process when it cannot reach an X server.
            raise SimulationError("a PyBullet window needs a display, and DISPLAY is not set "
                                  "(run headless with gui:=false)")
        if gui:
            client_id = pybullet.connect(pybullet.GUI, options=options)
        else:
            client_id = pybullet.connect(pybullet.DIRECT)
        if client_id < 0:
            what = "a GUI window (is a display available? only one GUI per process)" if gui \
                else "a DIRECT server"
            raise SimulationError(f"PyBullet could not open {what}")
        self.client_id = client_id
        self.gui = gui
        self._bound: list = []   # names of the bound functions set on this instance

    def __getattr__(self, name: str) -> Any:
        # Only called for names not found normally: forward to pybullet. A bound function is
        # then set on the instance, so the next lookup (on the per-step path) is a plain one.
        if name.startswith("_"):
            raise AttributeError(name)
        target = getattr(pybullet, name)
        if not isinstance(target, types.BuiltinFunctionType):
            return target  # constants, and the exception class `error`
        bound = functools.partial(target, physicsClientId=self.client_id)
        setattr(self, name, bound)
        self._bound.append(name)
        return bound

    @property
    def connected(self) -> bool:
        """True while the server is up."""
        return self.client_id >= 0 and bool(pybullet.isConnected(physicsClientId=self.client_id))

    def disconnect(self) -> None:
        """Close the server; later calls fail. Safe to call twice."""
        if self.client_id >= 0:
            if pybullet.isConnected(physicsClientId=self.client_id):
                pybullet.disconnect(physicsClientId=self.client_id)
            self.client_id = -1
            for name in self._bound:   # later calls go to no server (and fail)
                delattr(self, name)
            self._bound.clear()

