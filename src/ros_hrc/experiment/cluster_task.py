"""A cluster lane's Ray actor, on the node it lives on (``--cluster``): one warm stack across
the lane's cells.

The actor (:class:`NodeStack`, one CPU and one ``ros_hrc`` unit for its life) keeps one worker
process, the local pool's (:func:`ros_hrc.experiment.stack.worker_command`, ``--serve``: it owns
one stack, with a roscore and free ports of its own on that machine, and plays the cells whose
spec files it reads on its standard input, each handed to the running stack). For each cell its
lane hands it (:meth:`NodeStack.play`, a generator method) it writes the cell's files (its
models, and a sequence's selector model, schedule and library:
:mod:`ros_hrc.experiment.shipped_files`) and spec into the node's own directory, hands the spec
to its worker and streams each episode's line back to the driver
(:mod:`ros_hrc.experiment.cluster`) as the worker prints it. A cancelled call, or an actor
whose process dies, stops its worker, which stops its stack as Ctrl-C would. Ray is imported
in the actor only; no ROS here.
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
from collections import deque
from pathlib import Path
from typing import Any, Deque, Iterator, List, Optional, TextIO, Tuple

from ros_hrc.experiment.shipped_files import ShippedFiles, place_cell_files
from ros_hrc.experiment.stack import (RESULT_LINES, CellSpec, cell_name, decode_cell_end,
                                      log_tail, stack_log, worker_command, write_spec)

#: Lines of a failed cell's logs brought back from its node.
TAIL_LINES = 8
#: How often a call waiting for its worker's next line looks whether the driver cancelled it (s).
CANCEL_POLL = 0.25
#: Seconds a worker gets to stop its stack before its keeper is killed (the worker's own grace
#: for a stack is 60 s, 5 s when stopped by a signal).
STOP_WAIT = 60.0


def node_directory() -> Path:
    """Where cells keep their files on this node: beside Ray's own logs, in the node's
    session directory (a temporary directory when that cannot be found)."""
    try:
        import ray._private.worker as ray_worker   # the node's own session, not the driver's
        return Path(ray_worker.global_worker.node.get_session_dir_path()) / "ros_hrc"
    except Exception:   # noqa: BLE001 - any failure: the plain temporary directory
        return Path(tempfile.gettempdir()) / "ros_hrc_cluster"


#: The worker's keeper: the one process of a lane's stack that is the Ray worker's child. Ray
#: kills a worker's children (SIGKILL) when the worker exits (the actor killed, the job over,
#: the node lost), which would leave the stack running with nobody to stop it; the keeper's
#: death instead sends the worker SIGTERM (``setpriv --pdeathsig``), and the worker stops its
#: stack as Ctrl-C would. A SIGTERM to the keeper (a cancelled call) goes on to the worker, and
#: the keeper waits for it.
KEEPER = """
import signal, subprocess, sys
child = subprocess.Popen(sys.argv[1:])
signal.signal(signal.SIGTERM, lambda signum, frame: child.send_signal(signum))
code = child.wait()
sys.exit(code if code >= 0 else 128 - code)
"""


def _guarded(command: List[str]) -> List[str]:
    """``command`` under a keeper (:data:`KEEPER`) that dies with the actor's process and whose
    death sends SIGTERM to the command (without ``setpriv``, the command alone)."""
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        return command
    return [setpriv, "--pdeathsig", "KILL", "--", sys.executable, "-c", KEEPER,
            setpriv, "--pdeathsig", "TERM", "--"] + command


class NodeStack:
    """The body of a cluster lane's Ray actor, on its node: one worker process that owns one
    stack (``--serve``, under a keeper, :func:`_guarded`), kept across the cells the lane
    hands it (:meth:`play`): the first starts the stack, each next is handed to it (a warm
    stack; docs/experiments.md, "Warm stacks"). ``run_id`` names the run's directory on the
    node."""

    def __init__(self, run_id: str) -> None:
        self.run_id = run_id
        self.proc: Optional[subprocess.Popen] = None
        self._lines: "queue.Queue[Optional[str]]" = queue.Queue()   # its stdout, None at its end
        self._stack_log: Optional[Path] = None     # its stack's log (its first cell's)
        self._messages: Deque[str] = deque(maxlen=TAIL_LINES)   # its stderr since the cell began
        self._log: Optional[TextIO] = None         # where its stderr goes: the cell's worker log
        self._log_lock = threading.Lock()
        self._stderr_reader: Optional[threading.Thread] = None

    def play(self, spec_json: str, files: ShippedFiles, attempt: int, here: Optional[str] = None,
             new_stack: bool = False, keep: bool = True) -> Iterator[Tuple[str, Any]]:
        """Play one attempt at a cell (a generator; Ray streams what it yields to the driver).
        Writes the cell's files and spec into the node's own directory (``here``, a directory
        of the node's, instead: ``--cluster local``) and hands the spec to the worker (a new
        worker when there is none, or ``new_stack``: the cell needs another stack). Yields
        ``("start", where)``, then ``("episode", line)`` per episode or sequence as the worker
        prints it; the cell over (``CELL_OVER``), the call ends (``keep=False``,
        ``--fresh-stacks``: the worker stops its stack meanwhile); its settings refused,
        ``("refused", reason)``; the worker gone before the cell's end, ``("end", how)``: its
        exit status and the last lines of its messages and of its stack's log. A cancelled
        call stops the worker (which stops its stack) before it ends."""
        import ray

        spec = CellSpec.from_json(spec_json)
        name = cell_name(spec)
        directory = Path(here or node_directory()) / self.run_id / f"{name}.attempt{attempt}"
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
        if new_stack:
            self.close()
        if self.proc is None:
            self._start(stack_log(spec, directory))
        proc, lines = self.proc, self._lines
        where["pid"] = proc.pid
        self._cell_began(directory / f"{name}.worker.log")
        try:
            proc.stdin.write(f"{write_spec(spec, directory)}\n")
            proc.stdin.flush()
        except OSError:   # it died before it could read the cell: its reason is on stderr
            pass
        try:
            yield "start", where
            while True:
                # Asked at every line too: a cell whose episodes come quickly never waits.
                if context.is_canceled():
                    self.close(terminate=True)
                    return
                try:
                    line = lines.get(timeout=CANCEL_POLL)
                except queue.Empty:
                    continue
                if line is None:
                    break
                end = decode_cell_end(line)
                if end is not None:
                    over, what = end
                    if not over:
                        yield "refused", what["reason"]
                    elif not keep:
                        self.close(wait=False)   # the next cell's stack starts meanwhile
                    return
                if line.startswith(RESULT_LINES):
                    yield "episode", line
            # Its output ended before the cell did: the worker (and so its stack) is gone.
            proc.wait()
            self._stderr_reader.join(5.0)
            with self._log_lock:
                messages = [m.rstrip("\n") for m in self._messages]
            stack_log_path = self._stack_log
            self._forget()
            yield "end", {"returncode": proc.returncode, "lines": messages,
                          "stack_log": str(stack_log_path),
                          "stack_lines": log_tail(stack_log_path, TAIL_LINES)}
        except BaseException:
            # The call is going down: the stack must not run on.
            self.close(terminate=True)
            raise

    def _start(self, stack_log_path: Path) -> None:
        """Start the worker, and the threads that read its output."""
        proc = self.proc = _start_worker(_guarded(worker_command()))
        self._stack_log = stack_log_path
        lines = self._lines = queue.Queue()

        def read_stdout() -> None:
            for line in proc.stdout:
                lines.put(line)
            lines.put(None)

        def read_stderr() -> None:
            for line in proc.stderr:
                with self._log_lock:
                    self._messages.append(line)
                    if self._log is not None:
                        self._log.write(line)
                        self._log.flush()

        threading.Thread(target=read_stdout, name="worker-stdout", daemon=True).start()
        self._stderr_reader = threading.Thread(target=read_stderr, name="worker-stderr",
                                               daemon=True)
        self._stderr_reader.start()

    def _cell_began(self, worker_log: Path) -> None:
        """From now on the worker's messages go to ``worker_log`` (the cell's, on the node)."""
        with self._log_lock:
            if self._log is not None:
                self._log.close()
            self._log = open(worker_log, "a")
            self._messages.clear()

    def _forget(self) -> None:
        self.proc, self._stack_log = None, None

    def close(self, terminate: bool = False, wait: bool = True) -> None:
        """End the worker: its input closed, it stops its stack and exits (``terminate``:
        SIGTERM, it stops its stack as Ctrl-C would: the run is stopping); waited for, at most
        :data:`STOP_WAIT` s, unless ``wait`` is False (it stops in the background)."""
        proc = self.proc
        if proc is None:
            return
        self._forget()
        if not terminate:
            with contextlib.suppress(OSError):
                proc.stdin.close()
        if wait:
            _stop_worker(proc, terminate)
        else:
            threading.Thread(target=_stop_worker, args=(proc, terminate), name="worker-stop",
                             daemon=True).start()


def _start_worker(command: List[str]) -> subprocess.Popen:
    """Start a worker in a session of its own, its input a pipe (the cells' spec files), with
    no signal blocked. A Ray worker blocks SIGINT in the thread that runs the actor's calls,
    and a child inherits that mask through fork and exec: the worker stops its stack with
    SIGINT, as Ctrl-C would, and a stack started with SIGINT blocked would never stop."""
    blocked = signal.pthread_sigmask(signal.SIG_SETMASK, set())
    try:
        return subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, start_new_session=True)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


def _stop_worker(proc: subprocess.Popen, terminate: bool = True) -> None:
    """Wait for a worker to end, after SIGTERM (``terminate``: it stops its stack as Ctrl-C
    would) or its input closed; SIGKILL to its keeper after :data:`STOP_WAIT` s (whose death
    sends the worker SIGTERM)."""
    if proc.poll() is None:
        if terminate:
            with contextlib.suppress(ProcessLookupError):
                proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(STOP_WAIT)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
