"""PyBullet's window named through Xlib: the example browser that draws it has a fixed title.

PyBullet 3.2.x takes the window's size and sky colour as connect options, but no title
("Bullet Physics ExampleBrowser using OpenGL3+ [btgl] Release build" is fixed in the library).
:class:`WindowNamer` renames it (``XStoreName`` and ``_NET_WM_NAME``) from an Xlib connection
of its own, once, right after the window opened: X11 only, best effort (no X11, no rename).

That connection is opened *before* PyBullet connects and held until the window is named. An X
server resets when its last client leaves (Xvfb and Xorg do, unless started with ``-noreset``)
and cuts a connection that arrives while it resets. On a display nobody else uses (a headless
Xvfb), a connection that listed the windows and closed just before PyBullet connected made the
server reset under PyBullet's window: PyBullet printed "cannot connect to X server" and ended
the process (3 of 40 starts under two busy cores, measured 2026-11-29, against 0 of 40 without
the listing; strace showed the server resetting the new connection after its set-up request;
0 of 60 with the connection held).
"""
from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
import sys
import time
from contextlib import contextmanager
from typing import Iterator, Optional, Set

LOG = logging.getLogger(__name__)

#: How PyBullet's example browser names its window (the start of it).
BULLET_TITLE = "Bullet Physics ExampleBrowser"


_ERROR_HANDLER = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)
_ignore_errors = _ERROR_HANDLER(lambda display, event: 0)   # kept alive: Xlib holds it


def _xlib() -> Optional[ctypes.CDLL]:
    if not sys.platform.startswith("linux") or not os.environ.get("DISPLAY"):
        return None
    name = ctypes.util.find_library("X11") or "libX11.so.6"
    try:
        x = ctypes.CDLL(name)
    except OSError:
        return None
    x.XOpenDisplay.restype = ctypes.c_void_p
    x.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x.XDefaultRootWindow.restype = ctypes.c_ulong
    x.XDefaultRootWindow.argtypes = [ctypes.c_void_p]
    x.XQueryTree.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.POINTER(ctypes.c_ulong),
                             ctypes.POINTER(ctypes.c_ulong), ctypes.POINTER(ctypes.POINTER(ctypes.c_ulong)),
                             ctypes.POINTER(ctypes.c_uint)]
    x.XFetchName.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.POINTER(ctypes.c_char_p)]
    x.XStoreName.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_char_p]
    x.XInternAtom.restype = ctypes.c_ulong
    x.XInternAtom.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int]
    x.XChangeProperty.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong,
                                  ctypes.c_int, ctypes.c_int, ctypes.c_char_p, ctypes.c_int]
    x.XFree.argtypes = [ctypes.c_void_p]
    x.XSync.argtypes = [ctypes.c_void_p, ctypes.c_int]
    x.XCloseDisplay.argtypes = [ctypes.c_void_p]
    x.XSetErrorHandler.restype = ctypes.c_void_p
    x.XSetErrorHandler.argtypes = [ctypes.c_void_p]
    return x


def _windows(x: ctypes.CDLL, display: int, prefix: str) -> Set[int]:
    """Ids of the windows whose name starts with ``prefix`` (the whole tree, depth first)."""
    found: Set[int] = set()
    stack = [x.XDefaultRootWindow(display)]
    while stack:
        window = stack.pop()
        name = ctypes.c_char_p()
        if x.XFetchName(display, window, ctypes.byref(name)) and name.value is not None:
            if name.value.decode("utf-8", "replace").startswith(prefix):
                found.add(window)
            x.XFree(name)
        root, parent = ctypes.c_ulong(), ctypes.c_ulong()
        children, count = ctypes.POINTER(ctypes.c_ulong)(), ctypes.c_uint()
        if x.XQueryTree(display, window, ctypes.byref(root), ctypes.byref(parent),
                        ctypes.byref(children), ctypes.byref(count)):
            stack.extend(children[i] for i in range(count.value))
            if children:
                x.XFree(children)
    return found


class _Display:
    """An Xlib connection of our own. X errors are ignored only inside :meth:`ignoring_errors`
    (a window may vanish between two calls, and Xlib's default handler would end the
    process); the handler is process-wide, so PyBullet's own connection keeps Xlib's outside."""

    def __init__(self) -> None:
        self.x = _xlib()
        self.display = self.x.XOpenDisplay(None) if self.x is not None else None

    @contextmanager
    def ignoring_errors(self) -> Iterator[None]:
        previous = self.x.XSetErrorHandler(ctypes.cast(_ignore_errors, ctypes.c_void_p))
        try:
            yield
        finally:
            self.x.XSync(self.display, 0)   # errors of our calls arrive before the handler goes
            self.x.XSetErrorHandler(previous)

    def close(self) -> None:
        if self.display:
            self.x.XCloseDisplay(self.display)
            self.display = None


class WindowNamer:
    """Names the PyBullet window this process is about to open. Make it before PyBullet
    connects (it notes the example browser's windows already open, not ours, and holds the X
    server from resetting under PyBullet's window: the module docstring says why), call
    :meth:`name` once the window opened, then :meth:`close`. Best effort: without X11 it does
    nothing, and it never stops a world for its title."""

    def __init__(self) -> None:
        self._display: Optional[_Display] = None
        self._before: Set[int] = set()
        try:
            self._display = _Display()
            if self._display.display:
                with self._display.ignoring_errors():
                    self._before = _windows(self._display.x, self._display.display, BULLET_TITLE)
        except Exception:
            LOG.debug("could not list the X windows", exc_info=True)

    def name(self, title: str, wait: float = 2.0) -> bool:
        """Give the window that opened since ``title``, waiting up to ``wait`` s for it to
        appear. True if a window was renamed."""
        d = self._display
        if d is None or not d.display:
            return False
        deadline = time.monotonic() + wait
        try:
            with d.ignoring_errors():
                while True:
                    mine = _windows(d.x, d.display, BULLET_TITLE) - self._before
                    if mine or time.monotonic() > deadline:
                        break
                    time.sleep(0.05)
                encoded = title.encode("utf-8")
                utf8 = d.x.XInternAtom(d.display, b"UTF8_STRING", 0)
                net_name = d.x.XInternAtom(d.display, b"_NET_WM_NAME", 0)
                for window in mine:
                    d.x.XStoreName(d.display, window, encoded)
                    d.x.XChangeProperty(d.display, window, net_name, utf8, 8, 0, encoded,
                                        len(encoded))
                return bool(mine)
        except Exception:
            LOG.debug("could not name the PyBullet window", exc_info=True)
            return False

    def close(self) -> None:
        """Close the connection (safe to call twice)."""
        if self._display is not None:
            try:
                self._display.close()
            except Exception:
                LOG.debug("could not close the X connection", exc_info=True)
            self._display = None
