"""The reference solvers, run live beside the package's (issue #39): SARSOP's ``pomdpsol`` and
``pomdpsim``, C++ DESPOT's ``despot_pomdpx``. They are measuring instruments found through
``SARSOP_BIN`` and ``DESPOT_BIN`` (``../shared/peers/build.sh`` builds them outside the
repository and prints both); nothing of theirs is part of the package. Without a variable,
each figure that needs that peer is "no figure".

Every process is timed whole, from outside (``os.wait4``: wall seconds, CPU seconds and the
peak resident set of that process alone), so a ratio compares what a user waits for.
SARSOP's own table counts CPU seconds after loading the model; its ``--timeout`` does too.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import List, Optional, Sequence, Tuple

ROOT = Path(__file__).resolve().parents[1]
#: The command a user runs (the catkin relay execs this same file).
HRC_POMDP = [sys.executable, str(ROOT / "scripts" / "hrc_pomdp")]
NO_FIGURE = "no figure"


def sarsop(program: str) -> Optional[Path]:
    """``$SARSOP_BIN/<program>`` (pomdpsol, pomdpsim) when the variable names a folder holding
    it, else None."""
    folder = os.environ.get("SARSOP_BIN")
    path = Path(folder) / program if folder else None
    return path if path is not None and os.access(path, os.X_OK) else None


def despot_pomdpx() -> Optional[Path]:
    """C++ DESPOT's POMDPX player under ``$DESPOT_BIN``, else None."""
    folder = os.environ.get("DESPOT_BIN")
    path = Path(folder) / "pomdpx_models" / "despot_pomdpx" if folder else None
    return path if path is not None and os.access(path, os.X_OK) else None


@dataclass
class Run:
    """One finished process: what it printed and what it cost."""
    returncode: int
    stdout: str
    stderr: str
    wall_s: float
    cpu_s: float
    peak_mb: float


def run(argv: Sequence[str], cwd: Optional[Path] = None, timeout: float = 3600.0) -> Run:
    """Run ``argv`` to its end (killed after ``timeout`` s) and measure that process alone:
    ``os.wait4`` gives its own CPU time and peak resident set."""
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        start = time.perf_counter()
        proc = subprocess.Popen([str(a) for a in argv], stdout=out, stderr=err, cwd=cwd)
        killer = threading.Timer(timeout, proc.kill)
        killer.start()
        try:
            _, status, usage = os.wait4(proc.pid, 0)
        finally:
            killer.cancel()
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        return Run(proc.returncode, out.read(), err.read(), wall,
                   usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0)


# -- SARSOP's output ----------------------------------------------------------------------------
_ROW = re.compile(r"^\s*([0-9.]+)\s+(\d+)\s+(\d+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\d+)\s+(\d+)\s*$")


def sarsop_table(stdout: str) -> List[Tuple[float, float, float]]:
    """(seconds, lower, upper) of every row of pomdpsol's progress table, in order."""
    rows = []
    for line in stdout.splitlines():
        m = _ROW.match(line)
        if m:
            try:
                rows.append((float(m.group(1)), float(m.group(4)), float(m.group(5))))
            except ValueError:
                continue
    return rows


def pomdpsim_value(stdout: str) -> Optional[Tuple[float, float, float]]:
    """(mean, CI low, CI high) from pomdpsim's last table row."""
    m = re.findall(r"^\s*\d+\s+(\S+)\s+\((\S+),\s*(\S+)\)", stdout, re.M)
    return tuple(float(x) for x in m[-1]) if m else None


def despot_value(stdout: str) -> Optional[Tuple[float, float]]:
    """(mean, standard error) of despot_pomdpx's average total discounted reward."""
    m = re.search(r"Average total discounted reward \(stderr\) = (\S+) \((\S+)\)", stdout)
    return (float(m.group(1)), float(m.group(2))) if m else None


def first_time_at_gap(rows: Sequence[Tuple[float, float, float]], gap: float) -> Optional[float]:
    """The first time in (seconds, lower, upper) rows when upper - lower <= gap."""
    return next((t for t, lo, up in rows if up - lo <= gap), None)


def bounds_at(rows: Sequence[Tuple[float, float, float]], seconds: float
              ) -> Optional[Tuple[float, float]]:
    """The bounds of the last row at or before ``seconds``."""
    before = [(lo, up) for t, lo, up in rows if t <= seconds]
    return before[-1] if before else None
