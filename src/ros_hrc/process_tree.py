"""The machine's process tree, read through psutil (no ROS): who is whose parent, what a process
runs, whether it is still alive. Shared by the world's guard (hrc_guard), the world node and the
solvers, which each need to find the roslaunch that started them, by the Ray nodes of
``--cluster``, and by a study's cells, which find what is left of a stack whose roslaunch died.

A zombie (a process that ended and is not reaped yet) is never alive here, and a process that
is gone, or one this user may not look at, answers as nothing (None, [], False).

psutil is imported by each function, not with this module: every process of a stack imports
this module (through ``ros_hrc.link.token``), few ever look at the tree, and the import costs
tens of milliseconds of each one's start-up.
"""
from __future__ import annotations

import os
from typing import List, Optional


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs or is stopped (a zombie is not alive)."""
    import psutil
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False


def is_stopped(pid: int) -> bool:
    """Whether process ``pid`` is stopped (SIGSTOP, or a tracer's stop)."""
    import psutil
    try:
        return psutil.Process(pid).status() in (psutil.STATUS_STOPPED,
                                                psutil.STATUS_TRACING_STOP)
    except psutil.Error:
        return False


def parent_of(pid: int) -> Optional[int]:
    """The parent of process ``pid``, or None when it is gone."""
    import psutil
    try:
        return psutil.Process(pid).ppid()
    except psutil.Error:
        return None


def children_of(pid: int) -> List[int]:
    """The living processes whose parent is ``pid``, in the order of their pids."""
    import psutil
    return sorted(process.pid for process in psutil.process_iter(["ppid", "status"])
                  if process.info["ppid"] == pid
                  and process.info["status"] not in (None, psutil.STATUS_ZOMBIE))


def group_of(pid: int) -> Optional[int]:
    """The process group of process ``pid``, or None when it is gone."""
    try:
        return os.getpgid(pid)
    except OSError:
        return None


def group_alive(leader: int) -> bool:
    """Whether process group ``leader`` still has a live member."""
    import psutil
    return any(group_of(pid) == leader and alive(pid) for pid in psutil.pids())


def command_line(pid: int) -> List[str]:
    """The arguments of process ``pid``, empty ones left out ([] when it is gone)."""
    import psutil
    try:
        return [word for word in psutil.Process(pid).cmdline() if word]
    except psutil.Error:
        return []


def is_roslaunch(pid: int) -> bool:
    """Whether process ``pid`` runs roslaunch (``roslaunch ...``, ``python3 .../roslaunch``
    or ``python3 -m roslaunch``)."""
    return any(os.path.basename(word) == "roslaunch" for word in command_line(pid)[:3])


def processes_naming(marker: str) -> List[int]:
    """This machine's processes (but this one) whose command line has a word containing
    ``marker``."""
    import psutil
    own = os.getpid()
    return [process.pid for process in psutil.process_iter(["cmdline"])
            if process.pid != own
            and any(marker in word for word in process.info["cmdline"] or ())]
