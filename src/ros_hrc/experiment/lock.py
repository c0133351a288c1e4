"""One writer per results directory, for a whole run.

:func:`lock_directory` takes an exclusive, non-blocking ``flock`` on ``<directory>/.lock``
(which holds the owner's pid); a second run on the same directory gets :class:`DirectoryLocked`,
naming the directory and the pid of the run that holds it, and has touched nothing. The file is
removed when the lock is released: a finished run leaves only its results (a run killed leaves
it, unlocked, and the next run takes it).
"""
from __future__ import annotations

import errno
import fcntl
import os
from typing import Any, Optional, Union

from ros_hrc.errors import HrcError

LOCK_FILE = ".lock"


class DirectoryLocked(HrcError):
    """Another run holds the results directory."""

    def __init__(self, directory: str, pid: Optional[int]) -> None:
        self.directory = directory
        self.pid = pid
        who = f"pid {pid}" if pid else "a process whose pid it does not say"
        super().__init__(f"{directory} is in use by another run ({who}); wait for it to end "
                         "or choose another directory")


class DirectoryLock:
    """An exclusive flock on ``<directory>/.lock``, held until :meth:`release` (or the end of
    a ``with`` block, or the process). :meth:`release` removes the file, still locked, then
    unlocks it: whoever opened it meanwhile finds, once it has the lock, that the path is no
    longer its file, and starts again (:func:`lock_directory`)."""

    def __init__(self, directory: str, fd: int) -> None:
        self.directory = directory
        self.path = os.path.join(directory, LOCK_FILE)
        self._fd: Optional[int] = fd

    @property
    def held(self) -> bool:
        return self._fd is not None

    def release(self) -> None:
        if self._fd is not None:
            fd, self._fd = self._fd, None
            try:
                try:
                    os.unlink(self.path)
                except FileNotFoundError:
                    pass
                fcntl.flock(fd, fcntl.LOCK_UN)
            finally:
                os.close(fd)

    def __enter__(self) -> "DirectoryLock":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.release()


def _same_file(fd: int, path: str) -> bool:
    """Whether ``path`` is still the file open as ``fd``."""
    try:
        there = os.stat(path)
    except FileNotFoundError:
        return False
    here = os.fstat(fd)
    return (here.st_dev, here.st_ino) == (there.st_dev, there.st_ino)


def _lock_owner(fd: int) -> Optional[int]:
    try:
        text = os.pread(fd, 64, 0).decode("ascii", "replace").strip()
        return int(text) if text.isdigit() else None
    except OSError:
        return None


def lock_directory(directory: Union[str, os.PathLike]) -> DirectoryLock:
    """Lock ``directory`` (created if missing) for this process: an exclusive, non-blocking
    flock on ``<directory>/.lock``, which then holds this process's pid. Raises
    DirectoryLocked (naming the directory and the holder's pid) if another open file holds it,
    without writing anything."""
    directory = os.fspath(directory)
    os.makedirs(directory, exist_ok=True)
    path = os.path.join(directory, LOCK_FILE)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            owner = _lock_owner(fd)
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise DirectoryLocked(directory, owner) from None
            raise
        if _same_file(fd, path):
            break
        os.close(fd)    # its holder removed it as we opened it: lock the path's file now
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
        os.fsync(fd)
    except BaseException:
        os.close(fd)
        raise
    return DirectoryLock(directory, fd)
