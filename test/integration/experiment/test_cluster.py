"""hrc_experiment --cluster: the cells on Ray actors that keep their stacks (docs/cluster.md).

The one real Ray test starts a cluster of three nodes on this machine's loopback (a head on
127.0.0.2 with no ``ros_hrc`` slot, nodes on 127.0.0.3 and 127.0.0.4 with one each, one CPU
each, each with its own temp dir) and runs three studies on it through the real stacks (each
stack starts its own roscore: no master is needed beforehand): a sequence cell with the
driver's library and selector model; a small grid, one node's raylet killed once that node
has delivered an episode, its rows checked against the same grid run by the local pool and a
lane's later cells seen to play on the stack its first one started; then a cell whose only
node left is killed, which fails after --cluster-wait with the reason. The others need no
cluster of their own (one runs on --cluster local, with a roslaunch that dies at start)."""
import contextlib
import importlib.util
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from ros_hrc.experiment.cluster import cluster_argument, wait_for_cells
from ros_hrc.experiment.ray_node import PortSource, RayNode
from ros_hrc.experiment.stack import EpisodeRanges, contains, without
from result_rows import TIMED_COLUMNS, rows_of

HAS_RAY = importlib.util.find_spec("ray") is not None
HAS_STACK = importlib.util.find_spec("rospy") is not None and shutil.which("roslaunch")

#: Two human models, the human alone and the reactive robot, one seed: four cells, the human
#: alone first on each stream, then its robot (the gate of the paired counterfactual).
#: Episodes per cell: enough that a cell under way on the lost node still has most of its
#: episodes to run when its raylet dies (killed once it has delivered 1 to EPISODES // 4 of
#: them). Its Ray worker notices at once: in the runs measured (24 episodes a cell), the lost
#: node delivered nothing after the kill (3 episodes, then none), so 12 leave 9 or more
#: to run again on the survivor, at half the episodes of 24 (docs/performance.md).
EPISODES = 12
GRID = ["--human-models", "tired,distracted", "--policies", "no_robot,reactive", "--seeds", "0",
        "--episodes", str(EPISODES), "--step-limit", "8", "--no-plots"]
#: Ray's ports for the test's nodes (each taken only when free).
RAY_PORTS = (23311, 23999)
#: The tests that start a Ray cluster run one at a time, on one pytest worker: each cluster's
#: raylets, stacks and Ray workers would otherwise share the machine's two cores with
#: another's (and the three-node cluster takes its loopback addresses and port range).
ONE_RAY_CLUSTER_AT_A_TIME = pytest.mark.xdist_group("ray")


def experiment(*args: str) -> list:
    return [sys.executable, "-m", "ros_hrc.experiment.cli", *args]



def key(row: dict) -> tuple:
    return row["human_model"], row["robot_policy"], row["seed"], row["episode"]


def test_episode_ranges_without_some_numbers():
    ranges = EpisodeRanges.of([0, 1, 2, 3, 7, 8, 9])
    rest = without(ranges, {0, 2, 9, 40})
    assert list(rest) == [1, 3, 7, 8]
    assert [contains(ranges, n) for n in (0, 3, 4, 6, 7, 9, 10)] == \
        [True, True, False, False, True, True, False]


@pytest.mark.parametrize("text", ["", "nohost", "host:", "host:0", "host:70000", ":6379"])
def test_a_bad_cluster_address_is_refused(text):
    with pytest.raises(Exception, match="expected ADDRESS"):
        cluster_argument(text)


def test_without_cluster_ray_is_not_imported():
    code = ("import sys, ros_hrc.experiment.cli, ros_hrc.experiment.fit; "
            "sys.exit('ray' in sys.modules)")
    assert subprocess.run([sys.executable, "-c", code], timeout=120).returncode == 0


@pytest.mark.skipif(not HAS_RAY, reason="Ray is not installed")
# In the Ray tests' group: the head it looks for, on their address and in their port range,
# must not be one of theirs (seen: it met the three-node cluster's head on 127.0.0.2:23311).
@ONE_RAY_CLUSTER_AT_A_TIME
def test_a_cluster_that_is_not_there_is_one_line(tmp_path):
    port = PortSource(*RAY_PORTS).take()      # free: nothing listens there
    done = subprocess.run(experiment("--human-models", "expert", "--policies", "no_robot",
                                     "--episodes", "1", "--cluster", f"127.0.0.2:{port}",
                                     "--out", str(tmp_path / "out")),
                          capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        f"hrc_experiment: --cluster 127.0.0.2:{port}: no Ray head answers there"), done.stderr
    assert not (tmp_path / "out" / "episodes.csv").exists()


#: A roslaunch whose stack dies at start: every attempt at a cell fails.
DYING_ROSLAUNCH = """#!/bin/sh
echo "start $$" >> "$FAKE_ROSLAUNCH_LOG"
echo "OSError: [Errno 28] No space left on device: '/full/disk/log'"
exit 1
"""


@pytest.mark.skipif(not (HAS_RAY and importlib.util.find_spec("rospy")),
                    reason="needs Ray; the worker needs rospy")
@ONE_RAY_CLUSTER_AT_A_TIME
def test_a_cell_that_fails_three_times_is_reported_with_its_log_s_last_lines(tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "roslaunch").write_text(DYING_ROSLAUNCH)
    (bin_dir / "roslaunch").chmod(0o755)
    starts = tmp_path / "roslaunch.log"
    # The private cluster's node inherits this environment: its cells find this roslaunch.
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}",
               FAKE_ROSLAUNCH_LOG=str(starts), TMPDIR="/tmp")
    out = tmp_path / "out"
    done = subprocess.run(experiment("--human-models", "tired", "--policies", "no_robot",
                                     "--seeds", "0", "--episodes", "1", "--cluster", "local",
                                     "--jobs", "1", "--out", str(out), "--no-plots"),
                          env=env, capture_output=True, text=True, timeout=300,
                          stdin=subprocess.DEVNULL)
    assert done.returncode == 1, done.stdout[-2000:] + done.stderr[-2000:]
    assert starts.read_text().count("start ") == 3
    failed = [line for line in (done.stdout + done.stderr).splitlines() if "cell failed" in line]
    assert len(failed) == 1, done.stdout + done.stderr
    assert "tired-no_robot-seed0: failed 3 times on the cluster, the last: on " in failed[0]
    assert failed[0].endswith("No space left on device: '/full/disk/log'"), failed[0]
    # With --cluster local, the attempts' logs outlive the private cluster, beside the run's.
    logs = [line.split("its logs there: ")[1]
            for line in (out / "logs" / "tired-no_robot-seed0.worker.log").read_text().splitlines()
            if "its logs there: " in line]
    assert len(logs) == 3 and all(Path(log).is_relative_to(out / "logs") for log in logs)
    assert all((Path(log) / "tired-no_robot-seed0.log").exists() for log in logs)


def _said(output: Path) -> str:
    """What a run said, for a failed assertion: its lines about cells that failed or ran again
    (which the summary would push out of view), then its last lines."""
    text = output.read_text(errors="replace")
    marks = ("cell failed", "run again (attempt", "go back to the queue")
    cells = [line for line in text.splitlines() if any(mark in line for mark in marks)]
    return "\n".join(cells + ["...", text[-2000:]])


def _start(command: list, output: Path) -> subprocess.Popen:
    with open(output, "w") as out:
        return subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=out,
                                stderr=subprocess.STDOUT, text=True)


def _node_cells(logs: Path, node_ip: str) -> list:
    """The cells whose worker log says an attempt ran on ``node_ip`` (their names)."""
    return [log.name[:-len(".worker.log")] for log in sorted(logs.glob("*.worker.log"))
            if f" {node_ip} (node " in log.read_text(errors="replace")]


def _attempt_logs(logs: Path) -> list:
    """(cell, its attempt's directory on its node) of every attempt, from the driver's worker
    logs (``its logs there: DIR``)."""
    return [(log.name[:-len(".worker.log")], Path(line.split("its logs there: ")[1]))
            for log in sorted(logs.glob("*.worker.log"))
            for line in log.read_text(errors="replace").splitlines()
            if "its logs there: " in line]


def _node_cell(logs: Path, node_ip: str):
    """The first cell whose worker log says an attempt ran on ``node_ip``, if any."""
    cells = _node_cells(logs, node_ip)
    return cells[0] if cells else None


def _rows_of_cell(episodes: Path, cell: str) -> int:
    if not episodes.exists():
        return 0
    human, policy = cell.rsplit("-seed", 1)[0].split("-", 1)
    return sum(1 for row in rows_of(episodes)
               if (row["human_model"], row["robot_policy"]) == (human, policy))


@contextlib.contextmanager
def three_nodes():
    """A head on 127.0.0.2 with no ros_hrc slot (it runs no cell) and nodes on 127.0.0.3 and
    127.0.0.4 with one each, one CPU each, Ray's ports from :data:`RAY_PORTS`; all stopped
    and their files removed at the end."""
    # Ray's socket paths must stay short: its own temp dirs under /tmp, not pytest's.
    ray_dir = Path(tempfile.mkdtemp(prefix="hrc_ray_", dir="/tmp"))
    nodes = []
    try:
        ports = PortSource(*RAY_PORTS)
        nodes.append(RayNode.start(ray_dir / "head", cpus=1, ros_hrc=0, node_ip="127.0.0.2",
                                   ports=ports))
        for name, ip in (("first", "127.0.0.3"), ("second", "127.0.0.4")):
            nodes.append(RayNode.start(ray_dir / name, cpus=1, ros_hrc=1, node_ip=ip,
                                       head_address=nodes[0].address, ports=ports))
        yield tuple(nodes)
    finally:
        for node in reversed(nodes):
            node.stop()
        shutil.rmtree(ray_dir, ignore_errors=True)


def _kill(proc) -> None:
    """Kill a process the test started, if it still runs."""
    if proc is not None and proc.poll() is None:
        proc.kill()
        proc.wait()


@pytest.mark.skipif(not (HAS_RAY and HAS_STACK), reason="needs Ray and the built stack")
@ONE_RAY_CLUSTER_AT_A_TIME
def test_a_cluster_plays_sequences_and_grids_through_lost_nodes(tmp_path, monkeypatch):
    """One cluster, three studies in turn: a sequence cell with the driver's library; a grid
    equal to the local pool's though a node is lost mid-cell; a cell that fails with the
    reason once no living node offers ros_hrc."""
    # The head sees a lost node (its raylet killed: every health check refused at once) after
    # three checks a second apart instead of Ray's five, 3 s apart: each loss below costs
    # about 3 s of waiting, not 15. A check still waits Ray's 10 s for a slow but living
    # node's answer. (Ray's own settings, read by the nodes' processes from the environment.)
    monkeypatch.setenv("RAY_health_check_period_ms", "1000")
    monkeypatch.setenv("RAY_health_check_failure_threshold", "3")
    # The local pool's run, while the cluster starts (on one stack: its rows are the same on
    # any number, test_warm_stacks.py, and a second stack's start would take CPU from Ray's).
    local = _start(experiment(*GRID, "--jobs", "1", "--out", str(tmp_path / "local")),
                   tmp_path / "local.out")
    try:
        with three_nodes() as (head, first, second):
            for part in ("sequence", "no_node"):
                (tmp_path / part).mkdir()
            _sequence_cell_with_the_driver_s_library(tmp_path / "sequence", head.address)
            _grid_on_two_nodes(tmp_path, local, head, survivor=first, lost=second)
            _fail_without_a_node(tmp_path / "no_node", first, head.address)
    finally:
        _kill(local)


def _grid_on_two_nodes(tmp_path: Path, local, head, survivor, lost) -> None:
    """The grid on the cluster, the ``lost`` node's raylet killed mid-cell, against
    ``local``: the lost cell's missing episodes run again on the ``survivor``."""
    driver = None
    try:
        assert local.wait(timeout=600) == 0, _said(tmp_path / "local.out")

        out = tmp_path / "cluster"
        driver = _start(experiment(*GRID, "--cluster", head.address, "--out", str(out)),
                        tmp_path / "cluster.out")
        # Once the lost node has delivered some but not all of a cell's episodes (the cell is
        # under way there: a finished one would leave nothing to lose), its raylet dies.
        killed_cell = None
        deadline = time.monotonic() + 300
        while driver.poll() is None and killed_cell is None and time.monotonic() < deadline:
            for cell in _node_cells(out / "logs", lost.node_ip):
                if 1 <= _rows_of_cell(out / "episodes.csv", cell) <= EPISODES // 4:
                    os.kill(lost.raylet_pid(), signal.SIGKILL)
                    killed_cell = cell
                    break
            time.sleep(0.02)
        driver.wait(timeout=600)
        cluster_out = (tmp_path / "cluster.out").read_text()
        assert driver.returncode == 0, _said(tmp_path / "cluster.out")
        assert killed_cell is not None, _said(tmp_path / "cluster.out")

        # The rows are the local run's: every episode once, none lost, none twice.
        for name in ("episodes.csv", "steps.csv"):
            remote_rows = rows_of(out / name, TIMED_COLUMNS)
            local_rows = rows_of(tmp_path / "local" / name, TIMED_COLUMNS)
            assert sorted(map(sorted, map(dict.items, remote_rows))) == \
                sorted(map(sorted, map(dict.items, local_rows))), name
        episodes = rows_of(out / "episodes.csv")
        assert len({key(row) for row in episodes}) == len(episodes) == 2 * 2 * EPISODES

        # Cells ran on both nodes (none on the head, which offers no slot); the lost node's
        # cell went back to the queue with only the episodes it had not delivered, and ran
        # again on the survivor.
        run = json.loads((out / "run.json").read_text())["cluster"]
        by_ip = {node["ip"]: node for node in run["nodes"] if node["cells"] or node["episodes"]}
        assert set(by_ip) == {survivor.node_ip, lost.node_ip}, run
        # (Its "alive" flag waits for Ray's health checks, which may come after the run.)
        assert by_ip[lost.node_ip]["episodes"] >= 1, run
        assert by_ip[survivor.node_ip]["cells"] >= 1 and run["retried_cells"] >= 1, run
        assert run["dropped_duplicates"] == 0, run
        # (Ray may place the next attempt on the lost node before it notices the node is
        # gone: that attempt fails too, and a later one runs on the survivor.)
        log = (out / "logs" / f"{killed_cell}.worker.log").read_text()
        assert any(re.search(rf": attempt [23] of 3 \(\d+ episodes\) on .* "
                             rf"{re.escape(survivor.node_ip)} \(node ", line)
                   for line in log.splitlines()), log
        assert "cells per node: " in cluster_out

        # A lane keeps its actor's stack: each attempt either started a stack (a stack's log
        # lies in its first cell's directory) or played on the one before it on its node (its
        # worker there says so), and some did.
        attempts = _attempt_logs(out / "logs")
        warm = [cell for cell, there in attempts
                if "on the warm stack of" in (there / f"{cell}.worker.log").read_text()]
        started = [cell for cell, there in attempts if (there / f"{cell}.log").exists()]
        assert warm and len(started) + len(warm) == len(attempts), (attempts, warm, started)
        # The lost node's stacks stopped (their keepers died with its Ray worker).
        assert wait_for_cells(str(lost.directory), 60.0)
    finally:
        _kill(driver)


def _fail_without_a_node(tmp_path: Path, other, address: str) -> None:
    """A grid on the cluster at ``address``, whose only node with the resource is ``other``:
    its raylet killed once a cell runs there while the head lives, Ray would keep the cell
    queued forever; after --cluster-wait it fails, saying why and how to resume."""
    driver = None
    try:
        out = tmp_path / "cluster"
        driver = _start(experiment("--human-models", "tired", "--policies", "no_robot",
                                   "--seeds", "0", "--episodes", "40", "--step-limit", "8",
                                   "--no-plots", "--cluster", address,
                                   "--cluster-wait", "3", "--out", str(out)),
                        tmp_path / "cluster.out")
        deadline = time.monotonic() + 300
        while driver.poll() is None and time.monotonic() < deadline:
            if _node_cell(out / "logs", other.node_ip) is not None:
                os.kill(other.raylet_pid(), signal.SIGKILL)
                break
            time.sleep(0.02)
        driver.wait(timeout=600)
        said = (tmp_path / "cluster.out").read_text()
        assert driver.returncode == 1, said[-3000:]
        failed = [line for line in said.splitlines() if "cell failed" in line]
        assert len(failed) == 1, said[-3000:]
        assert "no living node of the cluster has offered the ros_hrc resource for 3 s" in \
            failed[0] and "run again to resume" in failed[0], failed[0]
    finally:
        _kill(driver)


def _sequence_cell_with_the_driver_s_library(tmp_path: Path, address: str) -> None:
    """A sequence cell on the cluster: its whole-sequence line reaches the driver, and the
    stack plays the --library and --selector-model the driver was given, from the node's
    copies (test_shipped_files.py checks the copies load without the driver's folder)."""
    from ros_hrc.agents.library import library_manifest
    driver_models = tmp_path / "mine"
    shutil.copytree(library_manifest("fabric").parent, driver_models)
    out = tmp_path / "out"
    done = subprocess.run(
        experiment("--task", "fabric", "--sequence", "2", "--episodes", "1", "--seeds", "7",
                   "--human-models", "expert_tired_noncollaborative", "--selectors", "bpr",
                   "--library", str(driver_models / "library.toml"),
                   "--selector-model", str(driver_models / "selector_model.json"),
                   "--max-trials", "100", "--no-plots", "--cluster", address,
                   "--out", str(out)),
        capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)
    said = done.stdout[-3000:] + done.stderr[-3000:]
    assert done.returncode == 0, said
    tasks = rows_of(out / "tasks.csv", ())
    assert [int(t["task_index"]) for t in tasks] == [1, 2], said
    assert all(t["selector"] == "bpr" and t["policy"] for t in tasks), tasks
    attempts = _attempt_logs(out / "logs")
    assert len(attempts) == 1, (attempts, said)
    specs = list(attempts[0][1].glob("*.spec.json"))
    assert len(specs) == 1, list(attempts[0][1].rglob("*"))
    given = dict(word.split(":=", 1) for word in json.loads(specs[0].read_text())["extra_args"])
    for name in ("library", "selector_model"):
        assert Path(given[name]).is_relative_to(specs[0].parent / "models"), given
