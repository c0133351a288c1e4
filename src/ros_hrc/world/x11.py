"""PyBullet's window named through Xlib: the example browser that draws it has a fixed title.

PyBullet 3.2.x takes the window's size and sky colour as connect options, but no title
("Bullet Physics ExampleBrowser using OpenGL3+ [btgl] Release build" is fixed in the library).
:func:`name_window` renames it (``XStoreName`` and ``_NET_WM_NAME``) from an Xlib connection
of its own, once, right after the window opened: X11 only, best effort (no X11, no rename).
"""
from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
import sys
import time
from typing import Optional, Set

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
    """An Xlib connection of our own, X errors ignored while it is open (a window may vanish
    between two calls; Xlib's default handler would end the process)."""

    def __init__(self) -> None:
        self.x = _xlib()
        self.display = self.x.XOpenDisplay(None) if self.x is not None else None
        self._previous = None

    def __enter__(self) -> "_Display":
        if self.display:
            self._previous = self.x.XSetErrorHandler(ctypes.cast(_ignore_errors, ctypes.c_void_p))
        return self

    def __exit__(self, *exc: object) -> None:
        if self.display:
            self.x.XSync(self.display, 0)
            self.x.XSetErrorHandler(self._previous)
            self.x.XCloseDisplay(self.display)


def bullet_windows() -> Set[int]:
    """X ids of the windows PyBullet's example browser has named (empty without X11)."""
    try:
        with _Display() as d:
            return _windows(d.x, d.display, BULLET_TITLE) if d.display else set()
    except Exception:  # best effort: never stop a world for its title
        LOG.debug("could not list the X windows", exc_info=True)
        return set()


def name_window(title: str, before: Optional[Set[int]] = None, wait: float = 2.0) -> bool:
    """Give PyBullet's window ``title``: the example-browser windows not in ``before`` (those
    that were there before this process opened its own), waiting up to ``wait`` s for one to
    appear. True if a window was renamed."""
    before = before or set()
    deadline = time.monotonic() + wait
    try:
        with _Display() as d:
            if not d.display:
                return False
            while True:
                mine = _windows(d.x, d.display, BULLET_TITLE) - before
                if mine or time.monotonic() > deadline:
                    break
                time.sleep(0.05)
            encoded = title.encode("utf-8")
            utf8 = d.x.XInternAtom(d.display, b"UTF8_STRING", 0)
            net_name = d.x.XInternAtom(d.display, b"_NET_WM_NAME", 0)
            for window in mine:
                d.x.XStoreName(d.display, window, encoded)
                d.x.XChangeProperty(d.display, window, net_name, utf8, 8, 0, encoded, len(encoded))
            return bool(mine)
    except Exception:
        LOG.debug("could not name the PyBullet window", exc_info=True)
        return False
