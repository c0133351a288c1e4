"""One PyBullet physics server per world, with every call bound to it.

PyBullet's module-level functions act on "the last connected" server unless each call names
``physicsClientId``. Several worlds live in one process (tests build many), so every body
module talks to the server through a :class:`PhysicsClient`, never through ``pybullet``
directly.
"""
from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import re
import sys
import tempfile
import types
from typing import Any, Iterator

from ..errors import SimulationError

#: What PyBullet's C code prints on its own as it is imported, opens or closes its window, and
#: now and then while the window draws: build dates, its argv, GL driver strings, its threads
#: and semaphores. It says nothing a user can act on; a line of its that is none of these (a
#: failure's reason) still comes through.
PYBULLET_CHATTER = re.compile(
    r"^\s*(pybullet build time:|argv\[\d+\]\s*=|argc=|startThreads creating|"
    r"start(ing|ed) thread|X11 functions dynamically loaded|Creating context|"
    r"Created GL|Direct GLX rendering|Making context current|GL_[A-Z_]+=|"
    r"pthread_getconcurrency|Version = |Vendor = |Renderer = |ven = |b3Printf: Selected demo|"
    r"MotionThreadFunc thread started|ExampleBrowserThreadFunc started|numActiveThreads = |"
    r"(btShutDownExampleBrowser )?stopping threads|Thread with taskId \d+ exiting|"
    r"Thread TERMINATED|destroy (main )?semaphore|(main )?semaphore destroyed|finished$)")


def without_chatter(text: str) -> str:
    """``text`` without its lines of :data:`PYBULLET_CHATTER`."""
    return "".join(line for line in text.splitlines(keepends=True)
                   if not PYBULLET_CHATTER.match(line))


def _flush_c_streams() -> None:
    """Flush the C library's stdio buffers (PyBullet prints with printf: into a file or a
    pipe its text waits in a buffer, and must be out before the descriptors move back)."""
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass


@contextlib.contextmanager
def pybullet_chatter_dropped() -> Iterator[None]:
    """Around a PyBullet call that prints from C (its import, a window's opening or closing):
    what it writes to the process's stdout and stderr (file descriptors 1 and 2) is caught,
    and every line of it but :data:`PYBULLET_CHATTER` goes on to where it was going, after
    the call. Only for short calls: another thread's line meanwhile comes out after it."""
    sys.stdout.flush()
    sys.stderr.flush()
    _flush_c_streams()
    caught = []
    for fd in (1, 2):
        try:
            saved = os.dup(fd)
        except OSError:         # no such descriptor (closed): nothing to catch there
            continue
        sink = tempfile.TemporaryFile()
        os.dup2(sink.fileno(), fd)
        caught.append((fd, saved, sink))
    try:
        yield
    finally:
        _flush_c_streams()
        for fd, saved, sink in caught:
            os.dup2(saved, fd)
            os.close(saved)
            sink.seek(0)
            kept = without_chatter(sink.read().decode(errors="replace"))
            sink.close()
            if kept:
                stream = sys.stdout if fd == 1 else sys.stderr
                stream.write(kept if kept.endswith("\n") else kept + "\n")
                stream.flush()


class ChatterFilter:
    """While PyBullet's window is open, its drawing thread prints too (``ven = ...`` each
    time it makes a render target): the process's stdout (descriptor 1) then goes through a
    pipe, and a thread passes on every line but :data:`PYBULLET_CHATTER`, a whole line at a
    time, to where stdout went before. :meth:`stop` puts stdout back and passes on what is
    left; it runs at the process's exit too."""

    def __init__(self) -> None:
        import atexit
        import threading
        sys.stdout.flush()
        _flush_c_streams()
        self._saved = os.dup(1)
        read_end, self._write_end = os.pipe()
        os.dup2(self._write_end, 1)
        self._thread = threading.Thread(target=self._pass_on, args=(read_end,),
                                        name="pybullet-chatter", daemon=True)
        self._thread.start()
        atexit.register(self.stop)

    def _pass_on(self, read_end: int) -> None:
        pending = b""
        with os.fdopen(read_end, "rb", buffering=0) as pipe:
            while True:
                chunk = pipe.read(65536)
                if not chunk:
                    break
                pending += chunk
                lines, _, pending = pending.rpartition(b"\n")
                if lines:
                    self._write(lines + b"\n")
        if pending:
            self._write(pending + b"\n")

    def _write(self, text: bytes) -> None:
        kept = without_chatter(text.decode(errors="replace")).encode()
        while kept:
            try:
                kept = kept[os.write(self._saved, kept):]
            except OSError:      # stdout's reader is gone: nothing to say it to
                return

    def stop(self) -> None:
        """Stdout back where it was; what the pipe still holds is passed on first."""
        if self._write_end < 0:
            return
        sys.stdout.flush()
        _flush_c_streams()
        os.dup2(self._saved, 1)
        os.close(self._write_end)
        self._write_end = -1
        # The pipe ends when no descriptor of it is left: a child process started meanwhile
        # may hold one, so the wait is bounded; the thread is a daemon.
        self._thread.join(timeout=2.0)


with pybullet_chatter_dropped():
    import pybullet


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
        self._chatter = ChatterFilter() if gui else None
        with pybullet_chatter_dropped():
            if gui:
                client_id = pybullet.connect(pybullet.GUI, options=options)
            else:
                client_id = pybullet.connect(pybullet.DIRECT)
        if client_id < 0:
            if self._chatter is not None:
                self._chatter.stop()
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
                with pybullet_chatter_dropped():
                    pybullet.disconnect(physicsClientId=self.client_id)
            self.client_id = -1
            if self._chatter is not None:
                self._chatter.stop()
            for name in self._bound:   # later calls go to no server (and fail)
                delattr(self, name)
            self._bound.clear()

