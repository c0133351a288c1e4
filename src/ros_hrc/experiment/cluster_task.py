"""A cell's Ray task, on the node it lands on (``--cluster``): one attempt at the cell.

The task (:func:`run_cell_on_node`) writes the cell's files (its models, and a sequence's
selector model, schedule and library: :mod:`ros_hrc.experiment.shipped_files`) and spec into
the node's own directory, runs the same worker command as the local pool
(:func:`ros_hrc.experiment.stack.worker_command`: the cell's whole stack, with a roscore and
free ports of its own on that machine) and streams each episode's line back to the driver
(:mod:`ros_hrc.experiment.cluster`) as the worker prints it (a Ray generator task). A cancelled
task, or one whose process dies, stops its worker, which stops its stack as Ctrl-C would.
Ray is imported in the task only; no ROS here.
"""
from __future__ import annotations

import contextlib
import dataclasses
import queue
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import Any, Iterator, List, Optional, Tuple

from ros_hrc.experiment.shipped_files import ShippedFiles, place_cell_files
from ros_hrc.experiment.stack import (RESULT_LINES, CellSpec, cell_name, log_tail, stack_log,
                                      worker_command, write_spec)

#: Lines of a failed cell's logs brought back from its node.
TAIL_LINES = 8
#: How often a task looks whether the driver cancelled it (s).
CANCEL_POLL = 0.25
#: Seconds a cancelled task gives its worker to stop its stack (the worker's own grace is 20 s).
STOP_WAIT = 60.0


def node_directory() -> Path:
    """Where cells keep their files on this node: beside Ray's own logs, in the node's
    session directory (a temporary directory when that cannot be found)."""
    try:
        import ray._private.worker as ray_worker   # the node's own session, not the driver's
        return Path(ray_worker.global_worker.node.get_session_dir_path()) / "ros_hrc"
    except Exception:   # noqa: BLE001 - any failure: the plain temporary directory
        return Path(tempfile.gettempdir()) / "ros_hrc_cluster"


#: The worker's keeper: the one process of a cell that is the Ray worker's child. Ray kills a
#: worker's children (SIGKILL) when the worker exits (the job over, the node lost), which would
#: leave the cell's stack running with nobody to stop it; the keeper's death instead sends the
#: cell's worker SIGTERM (``setpriv --pdeathsig``), and the worker stops its stack as Ctrl-C
#: would. A SIGTERM to the keeper (a cancelled task) goes on to the worker, and the keeper waits
#: for it.
KEEPER = """
import signal, subprocess, sys
child = subprocess.Popen(sys.argv[1:])
signal.signal(signal.SIGTERM, lambda signum, frame: child.send_signal(signum))
code = child.wait()
sys.exit(code if code >= 0 else 128 - code)
"""


def _guarded(command: List[str]) -> List[str]:
    """``command`` under a keeper (:data:`KEEPER`) that dies with the task's process and whose
    death sends SIGTERM to the command (without ``setpriv``, the command alone)."""
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        return command
    return [setpriv, "--pdeathsig", "KILL", "--", sys.executable, "-c", KEEPER,
            setpriv, "--pdeathsig", "TERM", "--"] + command


def run_cell_on_node(spec_json: str, files: ShippedFiles, run_id: str,
                     attempt: int, here: Optional[str] = None) -> Iterator[Tuple[str, Any]]:
    """The body of a cell's Ray task (a generator; it runs on the node). Writes the cell's
    files and spec into the node's own directory (``here``, a directory of the node's,
    instead: ``--cluster local``), runs the worker command there and
    yields ``("start", where)``, then ``("episode", line)`` per episode as the worker prints it,
    and, unless every episode was delivered (the task then ends while the stack shuts down,
    so that the next cell starts meanwhile), ``("end", how)``: the worker's exit status and the
    last lines of its messages and of its stack's log. A cancelled task stops its worker (which
    stops its stack) before it ends."""
    import ray

    spec = CellSpec.from_json(spec_json)
    name = cell_name(spec)
    directory = Path(here or node_directory()) / run_id / f"{name}.attempt{attempt}"
    directory.mkdir(parents=True, exist_ok=True)
    spec = dataclasses.replace(place_cell_files(spec, files, directory / "models"),
                               log_dir=str(directory))
    context = ray.get_runtime_context()
    where = {"node_id": context.get_node_id(), "ip": ray.util.get_node_ip_address(),
             "host": socket.gethostname(), "directory": str(directory), "pid": None}
    if shutil.which("roslaunch") is None:
        yield "start", where
        yield "end", {"returncode": None, "lines": [
            "roslaunch is not on this node's PATH: start Ray there from a shell where "
            "`source env.sh` ran (docs/cluster.md)"], "stack_lines": []}
        return
    worker_log = directory / f"{name}.worker.log"
    proc = _start_worker(_guarded(worker_command(write_spec(spec, directory))))
    where["pid"] = proc.pid
    lines: "queue.Queue[Optional[str]]" = queue.Queue()
    messages: List[str] = []

    def read_stdout() -> None:
        for line in proc.stdout:
            lines.put(line)
        lines.put(None)

    def read_stderr() -> None:
        with open(worker_log, "a") as log:
            for line in proc.stderr:
                messages.append(line)
                log.write(line)
                log.flush()

    readers = [threading.Thread(target=read_stdout, daemon=True),
               threading.Thread(target=read_stderr, daemon=True)]
    for reader in readers:
        reader.start()
    delivered = 0
    try:
        yield "start", where
        while True:
            try:
                line = lines.get(timeout=CANCEL_POLL)
            except queue.Empty:
                if context.is_canceled():
                    _stop_worker(proc)
                    return
                continue
            if line is None:
                break
            # An episode's line, or a sequence cell's line (one per whole sequence).
            if line.startswith(RESULT_LINES):
                yield "episode", line
                delivered += 1
                if delivered == len(spec.episodes):
                    # Every episode is in: the worker stops its stack while the next cell of
                    # this node starts; it is waited for here, in the background.
                    threading.Thread(target=proc.wait, daemon=True).start()
                    return
        proc.wait()
        readers[1].join(5.0)
        yield "end", {"returncode": proc.returncode,
                      "lines": [m.rstrip("\n") for m in messages[-TAIL_LINES:]],
                      "stack_log": str(stack_log(spec, directory)),
                      "stack_lines": log_tail(stack_log(spec, directory), TAIL_LINES)}
    except BaseException:
        # Cancelled at a yield, or the task is going down: the stack must not run on.
        _stop_worker(proc)
        raise


def _start_worker(command: List[str]) -> subprocess.Popen:
    """Start a cell's worker in a session of its own, with no signal blocked. A Ray worker
    blocks SIGINT in the thread that runs the task, and a child inherits that mask through
    fork and exec: the worker stops its stack with SIGINT, as Ctrl-C would, and a stack
    started with SIGINT blocked would never stop."""
    blocked = signal.pthread_sigmask(signal.SIG_SETMASK, set())
    try:
        return subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, start_new_session=True)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


def _stop_worker(proc: subprocess.Popen) -> None:
    """SIGTERM to a cell's worker (it stops its stack as Ctrl-C would) and wait for it."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(STOP_WAIT)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
