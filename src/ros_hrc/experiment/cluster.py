"""Studies beyond one machine: an experiment grid's cells on a Ray cluster (``--cluster``).

``hrc_experiment --cluster ADDRESS`` (and ``hrc_fit --cluster``) runs the same cells as the
local pool, in as many lanes as the cluster has slots: each lane owns a Ray actor
(:class:`NodeLane`; on the node, :class:`ros_hrc.experiment.cluster_task.NodeStack`) that asks
for one CPU and one unit of the custom resource ``ros_hrc`` (which ``ray start --resources
'{"ros_hrc": N}'`` sets on the machines where ``make setup`` ran) and lives on one node. There
it keeps the local pool's worker (:func:`ros_hrc.experiment.stack.worker_command`, ``--serve``:
one stack, with a roscore and free ports of its own on that machine) across the lane's cells,
each handed to the running stack (a warm stack), and streams each episode's line back to the
driver as the worker prints it (a Ray generator method). The driver alone writes the results
directory: resume, the lock and the summary are the local run's.

- ``ADDRESS``: ``host:port`` of the cluster's head (its GCS, ``ray start --head --port``);
  ``auto``: the cluster ``ray start`` started on this machine (or ``RAY_ADDRESS``); ``local``:
  a private one-node cluster started for the run on this machine and stopped at its end.
- **Faults.** A node that dies (or an actor, or its worker) fails the attempt under way: the
  lane makes a new actor, maybe on another node, and hands it the cell again with only the
  episodes the driver does not have (those delivered are kept; an episode that comes twice is
  dropped, by its (human model, policy, seed, episode)). Ray's own restarts and retries would
  replay a cell from its first episode, so the actors ask for none. A cell that fails
  :data:`~ros_hrc.experiment.attempts.MAX_ATTEMPTS` times is reported with the last lines of
  its logs, read on the node where it last ran. A cell whose settings are refused fails at
  once, with the reason.
- **Stopping.** SIGINT or SIGTERM to the driver cancels the calls in flight; each actor then
  sends SIGTERM to its worker, which stops its stack as it does locally, and the driver ends
  every actor's worker and kills the actor before it lets go of the cluster. A worker whose
  actor's process dies (the driver gone, a node lost) gets SIGTERM from the kernel
  (``setpriv --pdeathsig``) and stops its stack too; with ``local`` the driver waits for its
  cells' processes to end before it stops the private cluster.
- A cell's logs stay on its node, under the node's Ray session directory
  (``<ray temp dir>/session_*/ros_hrc/<run>/``; with ``local``, beside the driver's logs:
  ``logs/<run>/``); the driver's ``logs/<cell>.worker.log`` says which node ran each attempt
  and where its logs are there.

The pieces: this module is the option and the driver (:class:`ClusterRun`, and its lanes,
:class:`NodeLane`, which retry a cell as the local pool does,
:class:`ros_hrc.experiment.attempts.CellAttempts`); :mod:`ros_hrc.experiment.cluster_task` is
the actor on the node;
:mod:`ros_hrc.experiment.ray_node` starts and stops a node of one's own (``ray start
--block``): ``--cluster local``, the tests and the benchmark use it. Ray is imported here and
in the actor only, and only when ``--cluster`` is given (DESIGN §15); no ROS here.
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import ipaddress
import math
import os
import shutil
import signal
import socket
import tempfile
import threading
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

from ros_hrc.errors import HrcError
from ros_hrc.experiment.attempts import CellAttempts
from ros_hrc.experiment.cluster_task import STOP_WAIT, NodeStack
from ros_hrc.experiment.ray_node import RESOURCE, RayNode, RayNodeError
from ros_hrc.experiment.shipped_files import ShippedFiles, cell_files
from ros_hrc.experiment.stack import CellSpec, StackKeeper, decode_episode
from ros_hrc.process_tree import processes_naming

#: Seconds the driver waits for a cancelled call to end (its worker stopped).
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
                        help="run the cells on a Ray cluster, a warm stack per slot "
                             "(docs/cluster.md): the head's host:port, auto (the one started "
                             "on this machine) or local (a private one for this run); "
                             "default: the local pool")
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
    """A cell's call in flight as :class:`ros_hrc.experiment.pool.Stopper` sees a worker
    process: ``poll()`` and ``send_signal()``, which cancels the call (the actor then stops
    its worker's stack)."""

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
    ``--cluster local``), gives each of :func:`ros_hrc.experiment.pool.run_grid`'s lanes an
    actor on a node (:meth:`lane`), says what runs where (:meth:`status`, :meth:`report`) and
    lets go of the cluster (:meth:`close`: every lane's actor first)."""

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
        self._files: Dict[Tuple[str, str], ShippedFiles] = {}   # what cells' files were read
        self._private: Optional[RayNode] = None
        self._ray = None
        self._actor_class = None
        self._lanes: List["NodeLane"] = []
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
            except RayNodeError as exc:
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
        # A lane's actor holds its CPU and ros_hrc unit for its life; Ray neither restarts it
        # nor retries its calls (a cell would replay from its first episode).
        self._actor_class = ray.remote(num_cpus=1, resources={RESOURCE: 1}, max_restarts=0,
                                       max_task_retries=0)(NodeStack)
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

    def lane(self, stopper, fresh: bool = False) -> "NodeLane":
        """A new lane of the run (its actor made with its first cell)."""
        lane = NodeLane(self, stopper, fresh)
        with self._lock:
            self._lanes.append(lane)
        return lane

    def close(self) -> None:
        """Let go of the cluster, every lane's actor ended first (its worker stopped, the actor
        killed); for ``local``, once the cells' workers on this machine have stopped their
        stacks, stop the private cluster."""
        with self._lock:
            lanes, self._lanes = self._lanes, []
        for lane in lanes:
            lane.close()
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

    def _started(self, where: Dict[str, Any]) -> NodeFigures:
        with self._lock:
            node = self.nodes.get(where["node_id"])
            if node is None:
                node = self.nodes[where["node_id"]] = NodeFigures(where["node_id"], where["ip"],
                                                                  where["host"])
            node.cells += 1
            node.in_flight += 1
        return node

    def _count_retry(self) -> None:
        with self._lock:
            self.retried_cells += 1

    def _started_or_stopped(self, generator, stopper) -> bool:
        """Wait until the cell's call has something to say (its actor lives on a node: its
        first item), the run is stopping, or no living node has offered the resource for
        ``no_node_wait`` seconds (False: Ray would keep the actor waiting for a node
        forever)."""
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

    def _take(self, line: str, attempts: CellAttempts, node: Optional[NodeFigures]) -> None:
        """Deliver one episode's line (:meth:`CellAttempts.take`: each episode once), counted
        for its node, or as dropped when it came again."""
        try:
            episode = decode_episode(line)
        except (ValueError, KeyError) as exc:   # a line cut short: the episode reruns
            attempts.log.write(f"unreadable episode line ({exc}): {line[:80]!r}\n")
            return
        if episode is None:
            return
        delivered = attempts.take(*episode)
        with self._lock:
            if not delivered:
                self.dropped_duplicates += 1
            elif node is not None:
                node.episodes += 1

    @staticmethod
    def _failure(node: Optional[NodeFigures], end: Optional[Dict[str, Any]],
                 lost: Optional[str], missing: int) -> str:
        """One line: why an attempt ended short (``missing`` episodes still missing), with
        its logs' last lines from the node."""
        where = node.label() if node is not None else "a node"
        if lost is not None:
            return f"on {where}: {lost[:400]}"
        if end is None:
            return f"on {where}: the call ended with {missing} episodes missing"
        code = end.get("returncode")
        lines = [line for line in end.get("lines", []) if line.strip()]
        text = f"on {where}: " + (lines[-1].strip() if lines else f"exit code {code}")
        stack_lines = end.get("stack_lines") or []
        if stack_lines and "last lines of" not in text:
            text += f"; last lines of {end.get('stack_log')} there: " + " | ".join(stack_lines)
        return text


class NodeLane(StackKeeper):
    """One lane of a run on the cluster: a Ray actor (:class:`NodeStack`, one CPU and one
    ``ros_hrc`` unit) that lives on a node and keeps one warm worker there across the cells
    the lane hands it (:meth:`run_cell`, what :func:`ros_hrc.experiment.pool.run_grid`'s
    cluster lane calls for each cell). A cell that needs another stack
    (:func:`~ros_hrc.experiment.stack.stack_key`) gets the actor's worker replaced; with
    ``fresh`` (``--fresh-stacks``) the actor ends its worker after each cell. An attempt that
    ends short (its node lost, the actor or its worker dead) ends the actor: the next attempt
    makes a new one, maybe on another node. :meth:`close` ends the actor's worker (it stops
    its stack) and kills the actor, which frees its slot."""

    def __init__(self, run: ClusterRun, stopper, fresh: bool = False) -> None:
        super().__init__(fresh)
        self.run = run
        self.stopper = stopper
        self.actor = None
        self._placed = False    # the actor lives on a node (a call of its started)
        self._worker = False    # its worker runs

    def stack_running(self) -> bool:
        return self._worker

    def run_cell(self, cell: CellSpec, deliver, log) -> None:
        """Run one cell on the lane's actor, as :func:`ros_hrc.experiment.pool.play_cell`
        plays it locally: ``deliver(row, steps)`` per episode as it arrives. A failed attempt
        (its node lost, its stack failed) is followed by another with the episodes still
        missing, on a new actor, up to :data:`~ros_hrc.experiment.attempts.MAX_ATTEMPTS`
        attempts (:class:`~ros_hrc.experiment.attempts.CellAttempts`); then RuntimeError with
        the last lines of its logs. A cell whose settings were refused fails at once."""
        attempts = CellAttempts(cell, deliver, log, self.run.program)
        # The files the cell names here travel with it: a node needs none of this machine's
        # paths (ros_hrc.experiment.shipped_files).
        files = cell_files(cell, self.run._files)

        def attempt(number: int, spec: CellSpec) -> Tuple[str, Sequence[str]]:
            return self._attempt(number, spec, files, attempts)

        attempts.run(attempt, self.stopper, again="go back to the queue",
                     where=" on the cluster", on_retry=self.run._count_retry)

    def _attempt(self, number: int, spec: CellSpec, files: ShippedFiles,
                 attempts: CellAttempts) -> Tuple[str, Sequence[str]]:
        """One attempt at ``spec``'s episodes on the lane's actor (made now if there is none):
        (why it ended short, its worker's last lines). RuntimeError when the cell's settings
        were refused, or when no living node offers the resource for ``no_node_wait``
        seconds."""
        run, ray = self.run, self.run._ray
        if self.actor is None:
            self.actor = run._actor_class.remote(run.run_id)
            self._placed = False
        new_stack = not self.takes(spec)
        if new_stack:
            self.key = None
        # The private cluster's node is this machine: its cells keep their files beside
        # the driver's logs, which outlive the cluster.
        here = spec.log_dir if run._private is not None else None
        generator = self.actor.play.remote(spec.to_json(), files, number, here, new_stack,
                                           not self.fresh)
        handle = _RemoteCell(ray, generator)
        self.stopper.add(handle)
        node: Optional[NodeFigures] = None
        end: Optional[Dict[str, Any]] = None
        lost: Optional[str] = None
        refused: Optional[str] = None
        if not run._started_or_stopped(generator, self.stopper):
            handle.send_signal(signal.SIGTERM)    # it never started: out of the queue
            self.stopper.discard(handle)
            self.close()                          # nor may its actor take a slot later
            raise RuntimeError(
                f"no living node of the cluster has offered the {RESOURCE} resource for "
                f"{run.no_node_wait:g} s (every such node lost); start Ray on a machine "
                f"where make setup ran with --resources '{{\"{RESOURCE}\": N}}' and run "
                "again to resume (docs/cluster.md)")
        try:
            for ref in generator:
                kind, payload = ray.get(ref)
                if kind == "start":
                    self._placed = self._worker = True
                    node = run._started(payload)
                    attempts.began(number, len(spec.episodes), f" on {node.label()}; its logs "
                                                               f"there: {payload['directory']}")
                elif kind == "episode":
                    run._take(payload, attempts, node)
                elif kind == "refused":
                    refused = payload
                elif kind == "end":
                    end = payload
        except ray.exceptions.RayError as exc:
            lost = " ".join(str(exc).split())
        except BaseException:
            # An episode could not be recorded (a full disk): the cell must not run on.
            handle.send_signal(signal.SIGTERM)
            _drain(ray, generator)
            self.close()
            raise
        finally:
            handle.returncode = 0
            self.stopper.discard(handle)
            if node is not None:
                with run._lock:
                    node.in_flight -= 1
        if refused is not None:     # the stack is as it was: the lane keeps it
            raise RuntimeError(f"refused: {refused}")
        if attempts.complete:
            self.played(spec)
            if self.fresh:
                self._worker, self.key = False, None
            return "", ()
        # Its node, its actor or its worker is gone (or the run is stopping): the next
        # attempt, if any, goes to a new actor. One lost with its node is not asked to end
        # its worker (it would not answer): its keeper died with it.
        if lost is not None:
            self._placed = False
        self.close()
        missing = len(attempts.wanted) - len(attempts.delivered)
        return run._failure(node, end, lost, missing), (end or {}).get("lines", [])

    def close(self) -> None:
        """End the actor's worker (its input closed, or SIGTERM when the run is stopping: it
        stops its stack), then kill the actor. An actor never placed is killed at once; one
        lost with its node is gone (its worker's keeper died with it)."""
        actor, placed = self.actor, self._placed
        self.actor, self._placed, self._worker, self.key = None, False, False, None
        if actor is None:
            return
        ray = self.run._ray
        if placed:
            with contextlib.suppress(Exception):    # lost with its node, or the cluster gone
                ray.get(actor.close.remote(terminate=self.stopper.stopping),
                        timeout=STOP_WAIT + 10.0)
        with contextlib.suppress(Exception):
            ray.kill(actor)


def _drain(ray, generator, wait: float = CANCEL_WAIT) -> None:
    """Wait (a bounded time) for a cancelled call to end: its worker's stack is down then."""
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
