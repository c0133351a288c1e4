"""Output files written whole or not at all.

A converted model or a policy is written to a temporary file beside the target and renamed over
it only once complete, so a full disk, an interrupt or an error mid-way never leaves a
half-written file behind (nor damages the file being replaced). Only a regular file (or
nothing) is ever replaced: a path that names a device, a FIFO, a socket or a directory is
refused (a rename would put a regular file in the place of ``/dev/full`` for everyone).
"""
from __future__ import annotations

import errno
import os
import stat
import tempfile
from pathlib import Path
from typing import BinaryIO, Callable


class NotARegularFile(OSError):
    """The output path exists and is a device, a FIFO or a socket: it is never replaced."""


def refuse_special(path) -> None:
    """Raise OSError when ``path`` exists and is not a regular file (a directory, a device,
    a FIFO, a socket; a symbolic link counts as what it points to)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        if exc.errno in (errno.ENOENT, errno.ENOTDIR):
            return
        raise _about(exc, path) from None
    if stat.S_ISDIR(mode):
        raise IsADirectoryError(errno.EISDIR, "is a directory", str(path))
    if not stat.S_ISREG(mode):
        kind = ("a character device" if stat.S_ISCHR(mode) else
                "a block device" if stat.S_ISBLK(mode) else
                "a FIFO" if stat.S_ISFIFO(mode) else
                "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
        raise NotARegularFile(errno.EEXIST, f"is {kind}, not a regular file; it is never "
                                            "replaced (write to a file)", str(path))


def check_writable(path) -> None:
    """Raise OSError now, before any long work, when ``path`` cannot be written: its directory
    is missing or not writable, or it exists and is not a regular file."""
    target = Path(path)
    folder = target.parent if str(target.parent) else Path(".")
    refuse_special(target)
    if not folder.is_dir():
        raise FileNotFoundError(2, "no such directory", str(folder))
    if not os.access(folder, os.W_OK | os.X_OK):
        raise PermissionError(13, "directory not writable", str(folder))


def write_atomically(path, write: Callable[[BinaryIO], None]) -> None:
    """Call ``write(file)`` on a temporary file in ``path``'s directory, then rename it to
    ``path``; on any failure the temporary file is removed and ``path`` is left as it was.
    A ``path`` that exists and is not a regular file is refused (OSError) before anything is
    written, and checked again just before the rename."""
    target = Path(path)
    refuse_special(target)
    try:
        handle, temporary = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part",
                                             dir=str(target.parent))
    except OSError as exc:
        raise _about(exc, path) from None
    try:
        with os.fdopen(handle, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        # mkstemp makes the file private (0600); give it the mode a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)
        refuse_special(target)      # it may have become one while we wrote
        os.replace(temporary, target)
    except BaseException as exc:
        try:
            os.unlink(temporary)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise _about(exc, path) from None
        raise


def _about(exc: OSError, path) -> OSError:
    """The same error about ``path``, not about the temporary file the user never named."""
    return type(exc)(exc.errno, exc.strerror or str(exc), str(path))


def write_text_atomically(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` whole or not at all."""
    data = text.encode("utf-8")
    write_atomically(path, lambda fh: fh.write(data))
