#!/usr/bin/env python3
"""Reproducible studies (issue #21), through the real stacks: one (seed, episode) of a grid
replays alone exactly, and the same cell gives the same rows when its processes are stalled
as a loaded machine stalls them (half of every 100 ms).

Before: the human of (seed, episode) was seeded with seed + episode - 1 and the planner and
the world once per stack, so an episode depended on the episodes run before it in its cell
(a cell of episode 2 alone replayed episode 0); and DESPOT's 0.1 s wall-clock budget grew or
shrank its search with the machine's load, so a loaded run gave other decisions. Now every
episode draws from the streams of (seed, episode, role) and experiments bound DESPOT by
trials, not time."""
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import unittest
from pathlib import Path

import psutil
import rostest

from ros_hrc.experiment.stack import CellSpec, decode_episode, worker_command, write_spec
from ros_hrc.model_files import resolve_model

#: Columns that carry wall time: the only ones a loaded machine may change.
WALL_COLUMNS = ("mean_decision_ms", "wall_seconds")
HUMAN = "tired"
STEP_LIMIT = 8


def run_cell(episodes, log_dir, stalled=False):
    """The cell (HUMAN, pomdp, seed 0) of ``episodes`` on a stack of its own, as
    hrc_experiment's worker runs it: {episode: (episode row, step rows)} as dicts.
    ``stalled``: every process of the cell is stopped for half of each STALL_PERIOD
    (:class:`Stalls`)."""
    spec = CellSpec(HUMAN, "pomdp", 0, episodes, step_limit=STEP_LIMIT, log_dir=str(log_dir),
                    human_model_file=str(resolve_model(HUMAN, "human")),
                    robot_model=str(resolve_model("robot", "robot")))
    proc = subprocess.Popen(worker_command(write_spec(spec, Path(log_dir))),
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    stalls = Stalls(proc.pid) if stalled else None
    try:
        stdout, stderr = proc.communicate(timeout=600)
    finally:
        if stalls:
            stalls.stop()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, stderr[-3000:]
    out = {}
    for line in stdout.splitlines():
        decoded = decode_episode(line)
        if decoded:
            row, steps = decoded
            out[row.episode] = (without_wall_time(row.as_dict()), [s.as_dict() for s in steps])
    return out


def without_wall_time(row):
    """The row without its wall-time columns (simulated times are rounded to the microsecond
    by the scorer, so the rest must be identical)."""
    return {k: v for k, v in row.items() if k not in WALL_COLUMNS}


#: A stalled run's processes are stopped for the first half of each period, run the second.
STALL_PERIOD = 0.1


class Stalls:
    """What a loaded machine does to a run, without loading it: every process of the tree
    under ``pid`` (the driver, its worker, roslaunch, roscore, the nodes and both solvers)
    is stopped (SIGSTOP) for half of every STALL_PERIOD and continued for the other half, so
    that the run's wall time is about twice its CPU time, as beside two processes spinning on
    this machine's two cores. A planner bounded by wall time would search less; one bounded
    by trials, as experiments are, decides the same. Before, two such processes spun for the
    whole run, taking about 60 s of CPU from the tests running beside it."""

    def __init__(self, pid):
        self.root = psutil.Process(pid)
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _tree(self):
        try:
            return [self.root] + self.root.children(recursive=True)
        except psutil.Error:
            return []

    def _signal(self, processes, signum):
        for process in processes:
            try:
                process.send_signal(signum)
            except psutil.Error:
                pass

    def _run(self):
        tree, found = [], 0.0
        while not self.done.is_set():
            if time.monotonic() - found > 0.5:     # new processes: the stack starts them
                tree, found = self._tree(), time.monotonic()
            self._signal(tree, signal.SIGSTOP)
            time.sleep(STALL_PERIOD / 2)
            self._signal(tree, signal.SIGCONT)
            time.sleep(STALL_PERIOD / 2)

    def stop(self):
        self.done.set()
        self.thread.join()
        self._signal(self._tree(), signal.SIGCONT)


class TestReproducibleStudy(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        # The cell as a grid plays it, which each test below plays again another way.
        cls.work = tempfile.mkdtemp(prefix="hrc_streams_")
        cls.grid = run_cell([0, 1, 2, 3], os.path.join(cls.work, "grid"))

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.work, ignore_errors=True)

    def test_one_episode_of_a_cell_replays_alone_exactly(self):
        alone = run_cell([2], os.path.join(self.work, "alone"))
        self.assertEqual(sorted(self.grid), [0, 1, 2, 3])
        self.assertEqual(sorted(alone), [2])
        self.assertEqual(alone[2][1], self.grid[2][1], "episode 2's steps differ when run alone")
        self.assertEqual(alone[2][0], self.grid[2][0], "episode 2's row differs when run alone")
        # No two episodes share a stream: the four are not copies of one another.
        traces = {tuple((s["human_action"], s["human_state"], s["robot_action"])
                        for s in steps) for _, steps in self.grid.values()}
        self.assertGreater(len(traces), 1, "every episode of the cell played the same")

    def test_a_cell_played_again_under_load_gives_the_same_rows(self):
        loaded = run_cell([0, 1, 2, 3], os.path.join(self.work, "loaded"), stalled=True)
        self.assertEqual(sorted(loaded), [0, 1, 2, 3])
        for episode in range(4):
            self.assertEqual(loaded[episode][1], self.grid[episode][1],
                             f"episode {episode}'s steps differ under load")
            self.assertEqual(loaded[episode][0], self.grid[episode][0],
                             f"episode {episode}'s row differs under load")


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "experiment_streams", TestReproducibleStudy, sys.argv)
