"""The machine's process tree, read from /proc (no ROS): who is whose parent, what a process
runs. Shared by the world's guard (hrc_guard), the world node and the solvers, which each need
to find the roslaunch that started them, by the Ray nodes of ``--cluster``, and by a study's
cells, which find what is left of a stack whose roslaunch died."""
from __future__ import annotations

import os
from typing import List, Optional


def stat_fields(pid: int) -> Optional[List[str]]:
    """Fields of /proc/<pid>/stat after the command name (state, ppid, pgrp, ...), or None."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            text = f.read()
    except OSError:
        return None
    return text[text.rindex(b")") + 2:].decode("ascii", "replace").split()


def all_pids() -> List[int]:
    """Every process of the machine (its pid), as /proc lists them now."""
    return [int(name) for name in os.listdir("/proc") if name.isdigit()]


def group_alive(leader: int) -> bool:
    """Whether process group ``leader`` still has a live member (a zombie, ended and not yet
    reaped, is not one)."""
    for other in all_pids():
        fields = stat_fields(other)
        if fields and int(fields[2]) == leader and fields[0] != "Z":
            return True
    return False


def parent_of(pid: int) -> Optional[int]:
    """The parent of process ``pid``, or None when it is gone."""
    fields = stat_fields(pid)
    return int(fields[1]) if fields else None


def command_line(pid: int) -> List[str]:
    """The arguments of process ``pid`` ([] when it is gone)."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            raw = f.read()
    except OSError:
        return []
    return [word.decode("utf-8", "replace") for word in raw.split(b"\0") if word]


def is_roslaunch(pid: int) -> bool:
    """Whether process ``pid`` runs roslaunch (``roslaunch ...``, ``python3 .../roslaunch``
    or ``python3 -m roslaunch``)."""
    return any(os.path.basename(word) == "roslaunch" for word in command_line(pid)[:3])


def processes_naming(marker: str) -> List[int]:
    """This machine's processes (but this one) whose command line has a word containing
    ``marker``."""
    own = os.getpid()
    return [pid for pid in all_pids()
            if pid != own and any(marker in word for word in command_line(pid))]
