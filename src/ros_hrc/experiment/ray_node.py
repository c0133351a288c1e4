"""A Ray node of one's own, on this machine: the head of a cluster, or a node joining one
(``ray start --block`` in a session of its own, every port it listens on named), and its stop
with every process it started. ``--cluster local``, the tests and the benchmark use it
(docs/cluster.md). No ROS here; Ray runs in its own processes, never imported here.
"""
from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Optional, Set

from ros_hrc.errors import HrcError
from ros_hrc.experiment.stack import log_tail, port_is_free
from ros_hrc.link.transport import free_port
from ros_hrc.process_tree import children_of, command_line, group_alive

#: The custom resource a cell asks for (one unit), beside one CPU: a machine offers it when
#: the package is installed there (``make setup``) and Ray was started with it.
RESOURCE = "ros_hrc"


class RayNodeError(HrcError):
    """A node of one's own cannot start: one line saying why."""


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
        raise RayNodeError("no free port for a Ray node")


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
        one, :data:`LOOPBACK_NODE_IP`. RayNodeError with the last lines of its output
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
               "--object-store-memory", str(100 * 1024 * 1024), "--disable-usage-stats",
               # No log monitor: it tails every worker's log to forward it to drivers, and
               # ours take none (cluster.py: log_to_driver=False; a cell's lines go to its
               # own log files). Several nodes on one machine would each run one.
               "--include-log-monitor=false"]
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
                raise RayNodeError(f"ray start did not come up ({tail or 'no output'})")
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
