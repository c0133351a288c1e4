"""A full disk under a run: told from any other I/O error, and watched for while the run goes.

Every stack of a grid writes into the results directory (its ``roslaunch`` output, its ROS
logs under ``logs/ros/``, its worker log) and into ``$ROS_HOME`` (rospack's cache, where
roslaunch starts its nodes); the run itself appends its episodes there. When one of those
disks fills, a stack's processes fail in ways the run cannot see (a node whose log cannot be
written dies and respawns; roslaunch's own output is lost), so :class:`DiskWatch` looks at the
disks themselves, and :func:`is_full_disk` tells an ENOSPC or EDQUOT of the run's own writes.
No ROS here.
"""
from __future__ import annotations

import errno
import os
from pathlib import Path
from typing import Dict, Iterable, Optional, Union

from ros_hrc.errors import HrcError
from ros_hrc.model_files import ros_home

#: The errors of a write that found no room: the disk is full, or the user's quota is.
FULL_DISK_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT})
#: Less room than this on a watched disk counts as full: a stack writes that much log in a
#: second or two, so a run that went on would lose its next write there.
FULL_MARGIN_BYTES = 64 * 1024
#: How often a run looks at its disks, s.
CHECK_INTERVAL = 0.5


class DiskFull(HrcError):
    """A disk the run writes to is full: ``mount`` is where that disk is mounted, ``what``
    says how it was seen (a write that failed, or the room left)."""

    def __init__(self, mount: Union[str, os.PathLike], what: str) -> None:
        super().__init__(f"the disk at {mount} is full ({what})")
        self.mount = str(mount)
        self.what = what

    @classmethod
    def of_error(cls, error: OSError) -> "DiskFull":
        """The full disk behind a failed write (``error.filename`` names the file)."""
        name = error.filename or "."
        return cls(mount_point(name), f"{error.strerror or error}: {name}")


def is_full_disk(error: BaseException) -> bool:
    """Whether ``error`` is a write that found no room (ENOSPC, EDQUOT)."""
    return isinstance(error, OSError) and error.errno in FULL_DISK_ERRNOS


def mount_point(path: Union[str, os.PathLike]) -> Path:
    """Where the disk that holds ``path`` (or its nearest existing folder) is mounted."""
    here = Path(os.path.abspath(path))
    while not here.exists() and here != here.parent:
        here = here.parent
    device = here.stat().st_dev
    while here != here.parent and here.parent.stat().st_dev == device:
        here = here.parent
    return here


def room_left(path: Union[str, os.PathLike]) -> Optional[str]:
    """Why the disk holding ``path`` has no room for the run (too few bytes or no inode
    left for a new file), or None when it has."""
    stats = os.statvfs(path)
    # root may write into the blocks a filesystem keeps back from users.
    free = (stats.f_bfree if os.geteuid() == 0 else stats.f_bavail) * stats.f_frsize
    if stats.f_blocks and free < FULL_MARGIN_BYTES:
        return f"{free // 1024} KiB left"
    if stats.f_files and stats.f_favail == 0:
        return "no inode left for a new file"
    return None


class DiskWatch:
    """The disks under ``paths`` (the results directory, ``$ROS_HOME``), each looked at once
    however many of the paths it holds. :meth:`full` says whether one has no room left."""

    def __init__(self, paths: Iterable[Union[str, os.PathLike]]) -> None:
        self.disks: Dict[int, Path] = {}
        for path in paths:
            try:
                mount = mount_point(path)
                self.disks.setdefault(mount.stat().st_dev, mount)
            except OSError:     # nothing of it there, or not ours to look at
                continue

    @classmethod
    def of_run(cls, out: Union[str, os.PathLike]) -> "DiskWatch":
        """The disks a run on results directory ``out`` writes to: ``out``'s (the results,
        every stack's logs) and ``$ROS_HOME``'s."""
        return cls([out, ros_home()])

    def full(self) -> Optional[DiskFull]:
        """The first watched disk with no room left, or None."""
        for mount in self.disks.values():
            try:
                why = room_left(mount)
            except OSError:
                continue
            if why is not None:
                return DiskFull(mount, why)
        return None


def full_disk_line(program: str, full: DiskFull, kept: int, out: Union[str, os.PathLike],
                   command: str, unit: str = "episodes") -> str:
    """The one line a run that stopped on a full disk ends with: which disk, what was kept
    (``kept`` whole ``unit``: a store's rows, episodes or sequences), and how to go on
    (``command``: the run's own, which resumes it)."""
    whole = f"1 whole {unit[:-1]}" if kept == 1 else f"{kept} whole {unit}"
    return (f"{program}: {full}: {whole} kept in {out}; resume with: {command} "
            f"once there is room on {full.mount} (or copy {out} to another disk and give "
            "--out that copy)")
