"""Studies beyond one machine: an experiment grid's cells as Ray tasks (``--cluster``).

``hrc_experiment --cluster ADDRESS`` (and ``hrc_fit --cluster``) runs the same cells as the
local pool, each as a Ray task that asks for one CPU and one unit of the custom resource
``ros_hrc`` (which ``ray start --resources '{"ros_hrc": N}'`` sets on the machines where
``make setup`` ran). On the node it lands on, the task runs the same worker command as the
local pool (:func:`ros_hrc.experiment.stack.worker_command`: the cell's whole stack, with a
roscore and free ports of its own on that machine) and streams each episode's line back to the
driver as the worker prints it (a Ray generator task). The driver alone writes the results
directory: resume, the lock and the summary are the local run's.

- ``ADDRESS``: ``host:port`` of the cluster's head (its GCS, ``ray start --head --port``);
  ``auto``: the cluster ``ray start`` started on this machine (or ``RAY_ADDRESS``); ``local``:
  a private one-node cluster started for the run on this machine and stopped at its end.
- **Faults.** A node that dies takes its cells back to the queue: the driver submits the cell
  again with only the episodes it does not have (a cell's episodes already delivered are kept;
  an episode that comes twice is dropped, by its (human model, policy, seed, episode)). Ray's
  own task retry would replay a cell from its first episode, so the tasks ask for none. A cell
  that fails :data:`MAX_ATTEMPTS` times is reported with the last lines of its logs, read on the
  node where it last ran.
- **Stopping.** SIGINT or SIGTERM to the driver cancels the remote tasks; each task then sends
  SIGTERM to its worker, which stops its stack as it does locally. A worker whose task's
  process dies (the driver gone before its tasks ended, a node lost) gets SIGTERM from the
  kernel (``setpriv --pdeathsig``) and stops its stack too; with ``local`` the driver waits
  for its cells' processes to end before it stops the private cluster.
- A cell's logs stay on its node, under the node's Ray session directory
  (``<ray temp dir>/session_*/ros_hrc/<run>/``; with ``local``, beside the driver's logs:
  ``logs/<run>/``); the driver's ``logs/<cell>.worker.log`` says which node ran each attempt
  and where its logs are there.

Ray is imported here only, and only when ``--cluster`` is given (DESIGN §15); no ROS here.
:class:`RayNode` starts and stops a node of one's own (``ray start --block``): ``--cluster
local``, the tests and the benchmark use it.
"""
from __future__ import annotations

import argparse
import bisect
import contextlib
import dataclasses
import ipaddress
import math
import os
import queue
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any, Callable, Dict, Iterator, List, Optional, Set, Tuple

from ros_hrc.errors import HrcError
from ros_hrc.experiment.stack import (EPISODE_LINE, MAX_ATTEMPTS, CellSpec, EpisodeRanges,
                                      cell_name, decode_episode, log_tail, port_is_free, say,
                                      stack_log, worker_command, write_spec)
from ros_hrc.link.transport import free_port
from ros_hrc.process_tree import children_of, command_line, group_alive, processes_naming

#: The custom resource a cell asks for (one unit), beside one CPU: a machine offers it when
#: the package is installed there (``make setup``) and Ray was started with it.
RESOURCE = "ros_hrc"
#: Lines of a failed cell's logs brought back from its node.
TAIL_LINES = 8
#: How often a task looks whether the driver cancelled it (s).
CANCEL_POLL = 0.25
#: Seconds a cancelled task gives its worker to stop its stack (the worker's own grace is 20 s).
STOP_WAIT = 60.0
#: Seconds the driver waits for cancelled tasks to end before it lets go of the cluster.
CANCEL_WAIT = 90.0
#: How long the node count shown on the progress bar is kept before it is asked again (s).
NODES_REFRESH = 5.0
#: Seconds a cell waits to start while no living node offers the resource (every such node
#: lost, the head alive) before it fails with the reason (``--cluster-wait``).
NO_NODE_WAIT = 120.0
#: What ``--cluster`` takes besides an address.
KEYWORDS = ("auto", "local")


class ClusterError(HrcError):
    """The cluster cannot run the grid: one line naming ``--cluster`` and what is wrong."""


# --------------------------------------------------------------------------------------------
# The option


def cluster_argument(text: str) -> str:
    """``--cluster``'s value: ``auto``, ``local`` or ``host:port`` (the head's GCS)."""
    value = text.strip()
    if value in KEYWORDS:
        return value
    host, sep, port = value.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"expected ADDRESS (host:port of the head), auto or "
                                         f"local, got {text[:80]!r}")
    return value


def add_argument(parser: argparse.ArgumentParser) -> None:
    """``--cluster ADDRESS|auto|local`` (hrc_experiment and hrc_fit)."""
    parser.add_argument("--cluster", type=cluster_argument, default=None,
                        metavar="ADDRESS|auto|local",
                        help="run the cells as Ray tasks on a cluster (docs/cluster.md): the "
                             "head's host:port, auto (the one started on this machine) or "
                             "local (a private one for this run); default: the local pool")
    parser.add_argument("--cluster-wait", type=_seconds, default=NO_NODE_WAIT, metavar="S",
                        help="with --cluster: how long a cell waits to start while no living "
                             f"node offers the {RESOURCE} resource (all of them lost) before "
                             f"it fails, seconds ({NO_NODE_WAIT:g})")


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value <= 0 or value > 86400:
        raise argparse.ArgumentTypeError(f"expected seconds, more than 0 and at most 86400, "
                                         f"got {text[:40]!r}")
    return value


# --------------------------------------------------------------------------------------------
# Episode ranges


def contains(ranges: EpisodeRanges, episode: int) -> bool:
    """Whether ``episode`` is one of ``ranges``' numbers (without listing them)."""
    i = bisect.bisect_right(ranges.spans, (episode, float("inf"))) - 1
    return i >= 0 and ranges.spans[i][0] <= episode < ranges.spans[i][1]


def without(ranges: EpisodeRanges, taken: Set[int]) -> EpisodeRanges:
    """``ranges`` but the numbers in ``taken``: memory in proportion to ``taken``."""
    spans: List[Tuple[int, int]] = []
    for start, stop in ranges.spans:
        rest = EpisodeRanges.missing(stop - start, (n - start for n in taken))
        spans.extend((start + a, start + b) for a, b in rest.spans)
    return EpisodeRanges(tuple(spans))


# --------------------------------------------------------------------------------------------
# On the node: one attempt at a cell


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


def run_cell_on_node(spec_json: str, files: Dict[str, Tuple[str, bytes]], run_id: str,
                     attempt: int, here: Optional[str] = None) -> Iterator[Tuple[str, Any]]:
    """The body of a cell's Ray task (a generator; it runs on the node). Writes the cell's
    model files and spec into the node's own directory (``here``, a directory of the node's,
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
    models = directory / "models"
    models.mkdir(parents=True, exist_ok=True)
    changes: Dict[str, str] = {}
    for field_name, (base, data) in files.items():
        path = models / base
        path.write_bytes(data)
        changes[field_name] = str(path)
    spec = dataclasses.replace(spec, log_dir=str(directory), **changes)
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
            if line.startswith(EPISODE_LINE):
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


# --------------------------------------------------------------------------------------------
# The driver


@dataclasses.dataclass
class NodeFigures:
    """What one node did for the run."""
    node_id: str
    ip: str
    host: str
    cells: int = 0          # attempts started there
    episodes: int = 0       # episodes delivered from there
    in_flight: int = 0

    def label(self) -> str:
        host = "" if self.host in (self.ip, "") else f"{self.host} "
        return f"{host}{self.ip} (node {self.node_id[:8]})"


class _RemoteCell:
    """A running task as :class:`ros_hrc.experiment.cli.Stopper` sees a worker process:
    ``poll()`` and ``send_signal()``, which cancels the task (it then stops its stack)."""

    def __init__(self, ray_module, generator) -> None:
        self._ray = ray_module
        self.generator = generator
        self.returncode: Optional[int] = None

    def poll(self) -> Optional[int]:
        return self.returncode

    def send_signal(self, signum: int) -> None:
        try:
            self._ray.cancel(self.generator)
        except Exception:   # noqa: BLE001 - already over, or the cluster is gone
            pass


def _import_ray():
    try:
        import ray
    except ImportError:
        raise ClusterError("--cluster: Ray is not installed here (make setup installs it, "
                           "pinned in requirements.txt)") from None
    return ray


def _own_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback address Ray leaves as it is: a node of this machine
    listening there (Ray turns 127.0.0.1 and localhost into the machine's network address,
    where a node started on the loopback does not listen)."""
    try:
        return ipaddress.ip_address(host).is_loopback and host not in ("127.0.0.1", "::1")
    except ValueError:
        return False


def check_reachable(address: str) -> None:
    """``--cluster``'s address checked before anything is written: ClusterError at once when
    nothing listens at ``host:port`` (Ray would retry for a minute before it says so).
    ``auto`` and ``local`` are looked at when joining."""
    if address in KEYWORDS:
        return
    host, _, port = address.rpartition(":")
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=10.0).close()
    except OSError as exc:
        raise ClusterError(f"--cluster {address}: no Ray head answers there "
                           f"({exc.strerror or exc}); start one with ray start --head "
                           "(docs/cluster.md)") from None


class ClusterRun:
    """The driver's side of a run on a Ray cluster: connects (or starts the private cluster of
    ``--cluster local``), runs cells as Ray tasks (:meth:`run_cell`, what
    :func:`ros_hrc.experiment.cli.run_grid` calls for each cell), says what runs where
    (:meth:`status`, :meth:`report`) and lets go of the cluster (:meth:`close`)."""

    def __init__(self, address: str, program: str, slots: int = 0,
                 no_node_wait: float = NO_NODE_WAIT) -> None:
        self.address = address
        self.no_node_wait = no_node_wait
        self.program = program
        self.requested = slots     # --jobs: cells in flight at most (0: the cluster's slots)
        self.slots = 0             # the cluster's ros_hrc units when joined
        self.run_id = f"{time.strftime('%Y%m%d-%H%M%S')}-{socket.gethostname()}-{os.getpid()}"
        self.nodes: Dict[str, NodeFigures] = {}
        self.retried_cells = 0
        self.dropped_duplicates = 0
        self.connect_seconds = 0.0
        self._lock = threading.Lock()
        self._files: Dict[str, Tuple[str, bytes]] = {}
        self._private: Optional[RayNode] = None
        self._ray = None
        self._remote = None
        self._alive: Tuple[float, int] = (0.0, 0)

    # -- connecting ---------------------------------------------------------------------------

    def connect(self) -> None:
        """Join the cluster (start the private one first for ``local``); ClusterError (one
        line) when it cannot be reached or offers no ``ros_hrc`` resource."""
        started = time.monotonic()
        ray = _import_ray()
        address, node_ip = self.address, None
        if self.address == "local":
            slots = self.requested or os.cpu_count() or 1
            directory = Path(tempfile.mkdtemp(prefix="ros_hrc_ray_"))
            try:
                self._private = RayNode.start(directory, cpus=slots, ros_hrc=slots)
            except ClusterError as exc:
                raise ClusterError(f"--cluster local: {exc}") from None
            address, node_ip = self._private.address, self._private.node_ip
        elif self.address != "auto":
            check_reachable(self.address)
            host = self.address.rpartition(":")[0]
            if _own_loopback(host):     # a cluster on this machine's loopback: join its node
                node_ip = host
        options: Dict[str, Any] = {"log_to_driver": False, "logging_level": "WARNING",
                                   "configure_logging": True}
        if node_ip is not None:
            options["_node_ip_address"] = node_ip
        try:
            ray.init(address=address, **options)
        except Exception as exc:   # noqa: BLE001 - ConnectionError, ValueError, RuntimeError...
            self.close()
            raise ClusterError(f"--cluster {self.address}: cannot join the Ray cluster: "
                               f"{' '.join(str(exc).split())[:300]}") from None
        self._ray = ray
        capacity = int(ray.cluster_resources().get(RESOURCE, 0))
        if capacity < 1:
            self.close()
            raise ClusterError(f"--cluster {self.address}: no node of the cluster offers the "
                               f"{RESOURCE} resource; start Ray on the machines where make "
                               f"setup ran with --resources '{{\"{RESOURCE}\": N}}' "
                               "(docs/cluster.md)")
        self.slots = capacity
        self._remote = ray.remote(num_cpus=1, resources={RESOURCE: 1},
                                  max_retries=0)(run_cell_on_node)
        self.connect_seconds = time.monotonic() - started
        offers = self._offers()
        offered = ", ".join(f"{ip} {count:g}" for ip, count in offers)
        print(f"{self.program}: Ray cluster {self._shown_address()}: "
              f"{_count(len(offers), 'node')} offer{'s' if len(offers) == 1 else ''} "
              f"{capacity} {RESOURCE} slots ({offered}); joined in "
              f"{self.connect_seconds:.1f} s", flush=True)

    @property
    def in_flight_limit(self) -> int:
        """Cells submitted at once: ``--jobs``, or every ``ros_hrc`` slot of the cluster."""
        return self.requested or self.slots

    def _shown_address(self) -> str:
        if self._private is not None:
            return f"local (private, {self._private.address})"
        return self.address

    def _offers(self) -> List[Tuple[str, float]]:
        """(ip, ros_hrc units) of each living node that offers the resource."""
        return [(n["NodeManagerAddress"], n["Resources"].get(RESOURCE, 0))
                for n in self._ray.nodes() if n.get("Alive") and n["Resources"].get(RESOURCE)]

    def close(self) -> None:
        """Let go of the cluster; for ``local``, once the cells' workers on this machine have
        stopped their stacks, stop the private cluster."""
        if self._ray is not None and self._ray.is_initialized():
            self._ray.shutdown()
        if self._private is not None:
            wait_for_cells(self.run_id, STOP_WAIT)
            self._private.stop()
            shutil.rmtree(self._private.directory, ignore_errors=True)
            self._private = None

    # -- what the run shows -------------------------------------------------------------------

    def status(self) -> str:
        """For the progress bar: the nodes that offer the resource and the cells in flight."""
        now = time.monotonic()
        if now - self._alive[0] > NODES_REFRESH:
            try:
                self._alive = (now, len(self._offers()))
            except Exception:   # noqa: BLE001 - the bar must not fail the run
                self._alive = (now, self._alive[1])
        with self._lock:
            flying = sum(n.in_flight for n in self.nodes.values())
        return f"{_count(self._alive[1], 'node')}, {_count(flying, 'cell')} in flight | "

    def report(self) -> Dict[str, Any]:
        """What ran where (for run.json), and its lines printed: cells and episodes per node."""
        try:
            alive = {n["NodeID"] for n in self._ray.nodes() if n.get("Alive")}
        except Exception:   # noqa: BLE001
            alive = set(self.nodes)
        with self._lock:
            nodes = sorted(self.nodes.values(), key=lambda n: (n.ip, n.node_id))
        parts = [f"{n.label()}: {_count(n.cells, 'cell')}, {_count(n.episodes, 'episode')}"
                 + ("" if n.node_id in alive else " (node lost)") for n in nodes]
        print(f"{self.program}: cells per node: " + "; ".join(parts) +
              f"; {_count(self.retried_cells, 'cell')} run again after a failure, "
              f"{_count(self.dropped_duplicates, 'episode')} that came twice dropped",
              flush=True)
        return {"address": self.address, "slots": self.slots,
                "connect_seconds": self.connect_seconds,
                "retried_cells": self.retried_cells,
                "dropped_duplicates": self.dropped_duplicates,
                "nodes": [{"node_id": n.node_id, "ip": n.ip, "host": n.host, "cells": n.cells,
                           "episodes": n.episodes, "alive": n.node_id in alive} for n in nodes]}

    # -- one cell -----------------------------------------------------------------------------

    def _model_files(self, cell: CellSpec) -> Dict[str, Tuple[str, bytes]]:
        """The cell's model files (name and contents), sent with it: the nodes need not have
        them at the same path, or at all (a model given as a path on this machine)."""
        files = {}
        for field_name in ("robot_model", "human_model_file"):
            path = getattr(cell, field_name)
            if path:
                if path not in self._files:
                    self._files[path] = (Path(path).name, Path(path).read_bytes())
                files[field_name] = self._files[path]
        return files

    def _started(self, where: Dict[str, Any]) -> NodeFigures:
        with self._lock:
            node = self.nodes.get(where["node_id"])
            if node is None:
                node = self.nodes[where["node_id"]] = NodeFigures(where["node_id"], where["ip"],
                                                                  where["host"])
            node.cells += 1
            node.in_flight += 1
        return node

    def run_cell(self, cell: CellSpec, deliver, log, stopper=None,
                 on_all_delivered: Optional[Callable[[], None]] = None) -> None:
        """Run one cell on the cluster, as :func:`ros_hrc.experiment.cli.run_local_cell` runs it
        locally: ``deliver(row, steps)`` per episode as it arrives, ``on_all_delivered()``
        once the last one is in. A failed attempt (its node lost, its stack failed) is
        submitted again with the episodes still missing, up to :data:`MAX_ATTEMPTS` attempts;
        then RuntimeError with the last lines of its logs."""
        ray = self._ray
        name = cell_name(cell)
        wanted = EpisodeRanges.of(cell.episodes)
        delivered: Set[int] = set()
        files = self._model_files(cell)
        failure, attempt = "", 0
        while attempt < MAX_ATTEMPTS and len(delivered) < len(wanted):
            if stopper is not None and stopper.stopping:
                return
            attempt += 1
            missing = without(wanted, delivered)
            spec = dataclasses.replace(cell, episodes=missing)
            # The private cluster's node is this machine: its cells keep their files beside
            # the driver's logs, which outlive the cluster.
            here = cell.log_dir if self._private is not None else None
            generator = self._remote.remote(spec.to_json(), files, self.run_id, attempt, here)
            handle = _RemoteCell(ray, generator)
            if stopper is not None:
                stopper.add(handle)
            node: Optional[NodeFigures] = None
            end: Optional[Dict[str, Any]] = None
            lost: Optional[str] = None
            if not self._started_or_stopped(generator, stopper):
                handle.send_signal(signal.SIGTERM)    # it never started: out of the queue
                if stopper is not None:
                    stopper.discard(handle)
                raise RuntimeError(
                    f"no living node of the cluster has offered the {RESOURCE} resource for "
                    f"{self.no_node_wait:g} s (every such node lost); start Ray on a machine "
                    f"where make setup ran with --resources '{{\"{RESOURCE}\": N}}' and run "
                    "again to resume (docs/cluster.md)")
            try:
                for ref in generator:
                    kind, payload = ray.get(ref)
                    if kind == "start":
                        node = self._started(payload)
                        log.write(f"{self.program}: {name}: attempt {attempt} of "
                                  f"{MAX_ATTEMPTS} ({len(missing)} episodes) on "
                                  f"{node.label()}; its logs there: {payload['directory']}\n")
                        log.flush()
                    elif kind == "episode":
                        if self._take(payload, wanted, delivered, deliver, node, log) and \
                                len(delivered) == len(wanted) and on_all_delivered is not None:
                            on_all_delivered()
                    elif kind == "end":
                        end = payload
            except ray.exceptions.RayError as exc:
                lost = " ".join(str(exc).split())
            except BaseException:
                # An episode could not be recorded (a full disk): the task must not run on.
                handle.send_signal(signal.SIGTERM)
                _drain(ray, generator)
                raise
            finally:
                handle.returncode = 0
                if stopper is not None:
                    stopper.discard(handle)
                if node is not None:
                    with self._lock:
                        node.in_flight -= 1
            if len(delivered) == len(wanted) or (stopper is not None and stopper.stopping):
                return
            failure = self._failure(node, end, lost, wanted, delivered)
            log.write(f"{self.program}: {name}: attempt {attempt} failed: {failure}\n")
            if end:
                log.writelines(f"  {line}\n" for line in end.get("lines", []))
            log.flush()
            if attempt < MAX_ATTEMPTS:
                with self._lock:
                    self.retried_cells += 1
                say(f"{self.program}: cell {name}: {failure}; its "
                    f"{len(wanted) - len(delivered)} episodes still missing go back to the "
                    f"queue (attempt {attempt + 1} of {MAX_ATTEMPTS})")
        if len(delivered) < len(wanted):
            raise RuntimeError(f"failed {attempt} times on the cluster, the last: {failure}")

    def _started_or_stopped(self, generator, stopper) -> bool:
        """Wait until the cell's task has something to say (it started on a node: its first
        item), the run is stopping, or no living node has offered the resource for
        ``no_node_wait`` seconds (False: Ray would keep the task queued forever)."""
        none_since: Optional[float] = None
        while True:
            ready, _ = self._ray.wait([generator], timeout=NODES_REFRESH)
            if ready or (stopper is not None and stopper.stopping):
                return True
            try:
                offered = bool(self._offers())
            except Exception:   # noqa: BLE001 - the head did not answer: Ray reports it
                offered = True
            if offered:
                none_since = None
                continue
            now = time.monotonic()
            none_since = now if none_since is None else none_since
            if now - none_since >= self.no_node_wait:
                return False

    def _take(self, line: str, wanted: EpisodeRanges, delivered: Set[int], deliver,
              node: Optional[NodeFigures], log) -> bool:
        """Deliver one episode's line unless it is not the cell's or already delivered (an
        attempt that ran it again): each episode is counted once. Whether it was delivered."""
        try:
            episode = decode_episode(line)
        except (ValueError, KeyError) as exc:   # a line cut short: the episode reruns
            log.write(f"unreadable episode line ({exc}): {line[:80]!r}\n")
            return False
        if episode is None:
            return False
        row, steps = episode
        if row.episode in delivered or not contains(wanted, row.episode):
            with self._lock:
                self.dropped_duplicates += 1
            log.write(f"{self.program}: episode {row.key} came again; dropped\n")
            return False
        deliver(row, steps)
        delivered.add(row.episode)
        if node is not None:
            with self._lock:
                node.episodes += 1
        return True

    @staticmethod
    def _failure(node: Optional[NodeFigures], end: Optional[Dict[str, Any]],
                 lost: Optional[str], wanted: EpisodeRanges, delivered: Set[int]) -> str:
        """One line: why an attempt ended short, with its logs' last lines from the node."""
        where = node.label() if node is not None else "a node"
        if lost is not None:
            return f"on {where}: {lost[:400]}"
        if end is None:
            return f"on {where}: the task ended with {len(wanted) - len(delivered)} episodes " \
                   "missing"
        code = end.get("returncode")
        lines = [line for line in end.get("lines", []) if line.strip()]
        text = f"on {where}: " + (lines[-1].strip() if lines else f"exit code {code}")
        stack_lines = end.get("stack_lines") or []
        if stack_lines and "last lines of" not in text:
            text += f"; last lines of {end.get('stack_log')} there: " + " | ".join(stack_lines)
        return text


def _drain(ray, generator, wait: float = CANCEL_WAIT) -> None:
    """Wait (a bounded time) for a cancelled task to end: its stack is down then."""
    deadline = time.monotonic() + wait
    try:
        for ref in generator:
            if time.monotonic() > deadline:
                return
            try:
                ray.get(ref, timeout=max(0.1, deadline - time.monotonic()))
            except Exception:   # noqa: BLE001
                return
    except Exception:   # noqa: BLE001 - cancelled, lost: over either way
        return


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")



def wait_for_cells(marker: str, wait: float) -> bool:
    """Wait until no process of this machine names ``marker`` (the cells of a run stopped
    their stacks), at most ``wait`` s; whether none is left."""
    deadline = time.monotonic() + wait
    while processes_naming(marker):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.2)
    return True


# --------------------------------------------------------------------------------------------
# A node of one's own


#: What a node listens on besides its workers' ports (the head also on its GCS and dashboard).
NODE_PORTS = ("node-manager-port", "object-manager-port", "dashboard-agent-listen-port",
              "dashboard-agent-grpc-port", "runtime-env-agent-port", "metrics-export-port")
HEAD_PORTS = ("port", "dashboard-port")
#: Where a node of one's own listens by default: this machine's loopback, but not 127.0.0.1,
#: which Ray turns into the machine's network address when a node or a driver joins.
LOOPBACK_NODE_IP = "127.0.0.2"
#: Seconds ``ray start`` gets to say it is up.
START_WAIT = 120.0


class PortSource:
    """Ports for a node: each free when taken, none taken twice; from ``first`` upwards
    (a range of one's own) or, without one, wherever the system finds a free one."""

    def __init__(self, first: Optional[int] = None, last: int = 65535) -> None:
        self.next = first
        self.last = last
        self.taken: Set[int] = set()

    def take(self) -> int:
        for _ in range(1000):
            if self.next is None:
                port = free_port()
            else:
                if self.next > self.last:
                    break
                port, self.next = self.next, self.next + 1
            if port not in self.taken and port_is_free(port) and port_is_free(port, "0.0.0.0"):
                self.taken.add(port)
                return port
        raise ClusterError("no free port for a Ray node")


@dataclasses.dataclass
class RayNode:
    """A Ray node started here (``ray start --block`` in a session of its own): the head of a
    cluster, or a node joining one. :meth:`stop` stops it and every process it started."""
    proc: subprocess.Popen
    directory: Path
    node_ip: str
    address: str          # the cluster's head, host:port
    log_path: Path

    @classmethod
    def start(cls, directory: Path, cpus: int, ros_hrc: int, head_address: Optional[str] = None,
              node_ip: Optional[str] = None, ports: Optional[PortSource] = None,
              worker_ports: Optional[int] = None) -> "RayNode":
        """Start a node with ``cpus`` CPUs and ``ros_hrc`` units of the resource, its files
        under ``directory`` (its own ``--temp-dir``), every port it listens on named
        (``ports``: from a range of one's own, or free ones), and return once it is up.
        ``head_address``: join that head; otherwise start a head. ``node_ip``: the node's
        address (127.0.0.x, x > 1, runs several nodes on one machine's loopback); without
        one, :data:`LOOPBACK_NODE_IP`. ClusterError with the last lines of its output
        when it does not come up."""
        ports = ports or PortSource()
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        env = dict(os.environ)
        env.update(RAY_USAGE_STATS_ENABLED="0", RAY_GRACEFUL_SHUTDOWN_DRAIN_TIMEOUT_S="0")
        node_ip = node_ip or LOOPBACK_NODE_IP
        cmd = [sys.executable, "-m", "ray.scripts.scripts", "start", "--block",
               "--node-ip-address", node_ip, "--num-cpus", str(cpus),
               "--resources", f'{{"{RESOURCE}": {ros_hrc}}}', "--temp-dir", str(directory),
               "--object-store-memory", str(100 * 1024 * 1024), "--disable-usage-stats"]
        if head_address is None:
            head_port = ports.take()
            cmd += ["--head", "--port", str(head_port), "--include-dashboard=false",
                    "--dashboard-port", str(ports.take())]
            address = f"{node_ip}:{head_port}"
        else:
            cmd += ["--address", head_address]
            address = head_address
        for option in NODE_PORTS:
            cmd += [f"--{option}", str(ports.take())]
        count = worker_ports or 2 * cpus + 8
        cmd += ["--worker-port-list", ",".join(str(ports.take()) for _ in range(count))]
        log_path = directory / "ray_start.log"
        with open(log_path, "wb") as log:
            proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=log,
                                    stderr=subprocess.STDOUT, start_new_session=True, env=env)
        node = cls(proc, directory, node_ip, address, log_path)
        node._wait_up()
        return node

    def _wait_up(self) -> None:
        deadline = time.monotonic() + START_WAIT
        while True:
            text = self.log_path.read_text(errors="replace") if self.log_path.exists() else ""
            if "Ray runtime started" in text:
                return
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.stop()
                tail = " | ".join(log_tail(self.log_path, 3))
                raise ClusterError(f"ray start did not come up ({tail or 'no output'})")
            time.sleep(0.2)

    def raylet_pid(self) -> Optional[int]:
        """The node's raylet (its scheduler), one of ``ray start``'s children."""
        for child in children_of(self.proc.pid):
            words = command_line(child)
            if words and os.path.basename(words[0]) == "raylet":
                return child
        return None

    def stop(self, grace: float = 20.0) -> None:
        """SIGTERM to the node's whole process group (``ray start`` and what it started),
        SIGKILL after ``grace`` s."""
        for sig, wait in ((signal.SIGTERM, grace), (signal.SIGKILL, 10.0)):
            try:
                os.killpg(self.proc.pid, sig)
            except ProcessLookupError:
                pass
            deadline = time.monotonic() + wait
            while time.monotonic() < deadline:
                self.proc.poll()        # reaps ray start, the group's leader
                if not group_alive(self.proc.pid):
                    return
                time.sleep(0.1)
