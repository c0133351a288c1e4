"""PyBullet's window named through Xlib: the example browser that draws it has a fixed title.

PyBullet 3.2.x takes the window's size and sky colour as connect options, but no title
("Bullet Physics ExampleBrowser using OpenGL3+ [btgl] Release build" is fixed in the library).
:class:`WindowNamer` renames it (``WM_NAME`` and ``_NET_WM_NAME``) from an X connection of its
own, once, right after the window opened: X11 only, best effort (no X11, no rename).

The connection is python-xlib's (the X protocol in Python): its errors are exceptions of that
connection alone (a window that vanished between two requests), where libX11's error handler is
the process's, PyBullet's connection's too.

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

import logging
import os
import sys
import time
from typing import Set

LOG = logging.getLogger(__name__)

#: How PyBullet's example browser names its window (the start of it).
BULLET_TITLE = "Bullet Physics ExampleBrowser"


def open_display():
    """A python-xlib connection to ``$DISPLAY``, or None (not Linux, no display, no server
    answering, python-xlib missing)."""
    if not sys.platform.startswith("linux") or not os.environ.get("DISPLAY"):
        return None
    try:
        from Xlib import display
        return display.Display()
    except Exception:     # DisplayError, ConnectionClosedError, OSError: no X server to name in
        LOG.debug("no X connection", exc_info=True)
        return None


def _windows(display, prefix: str) -> Set[int]:
    """Ids of the windows whose name starts with ``prefix`` (the whole tree, depth first). A
    window that goes away while it is read is skipped."""
    from Xlib import error

    found: Set[int] = set()
    stack = [display.screen().root]
    while stack:
        window = stack.pop()
        try:
            name = window.get_wm_name()
            children = window.query_tree().children
        except error.XError:
            continue
        if isinstance(name, bytes):
            name = name.decode("utf-8", "replace")
        if name and name.startswith(prefix):
            found.add(window.id)
        stack.extend(children)
    return found


class WindowNamer:
    """Names the PyBullet window this process is about to open. Make it before PyBullet
    connects (it notes the example browser's windows already open, not ours, and holds the X
    server from resetting under PyBullet's window: the module docstring says why), call
    :meth:`name` once the window opened, then :meth:`close`. Best effort: without X11 it does
    nothing, and it never stops a world for its title."""

    def __init__(self, hold_for: float = 2.0) -> None:
        self._display = None
        self._before: Set[int] = set()
        # A connection that arrives while the server resets (its last client just left) is
        # accepted and then cut: it holds nothing. Listing the windows is a round trip, so a
        # connection that answered it is one the server kept; one cut is made again, for up
        # to ``hold_for`` s (a reset takes milliseconds).
        deadline = time.monotonic() + hold_for
        while True:
            display = open_display()
            if display is None:
                if os.environ.get("DISPLAY") and time.monotonic() < deadline:
                    time.sleep(0.05)     # refused while the server resets: try again
                    continue
                return
            try:
                self._before = _windows(display, BULLET_TITLE)
                self._display = display
                return
            except Exception:
                LOG.debug("the X connection was cut; connecting again", exc_info=True)
                try:
                    display.close()
                except Exception:
                    pass
                if time.monotonic() >= deadline:
                    return
                time.sleep(0.05)

    def name(self, title: str, wait: float = 2.0) -> bool:
        """Give the window that opened since ``title``, waiting up to ``wait`` s for it to
        appear. True if a window was renamed."""
        d = self._display
        if d is None:
            return False
        from Xlib import Xatom, error

        deadline = time.monotonic() + wait
        try:
            while True:
                mine = _windows(d, BULLET_TITLE) - self._before
                if mine or time.monotonic() > deadline:
                    break
                time.sleep(0.05)
            encoded = title.encode("utf-8")
            utf8 = d.intern_atom("UTF8_STRING")
            net_name = d.intern_atom("_NET_WM_NAME")
            # A window that closes meanwhile answers with an error: caught, not printed.
            ignored = error.CatchError()
            for window_id in mine:
                window = d.create_resource_object("window", window_id)
                window.change_property(Xatom.WM_NAME, Xatom.STRING, 8, encoded,
                                       onerror=ignored)
                window.change_property(net_name, utf8, 8, encoded, onerror=ignored)
            d.sync()
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
