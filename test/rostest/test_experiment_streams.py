#!/usr/bin/env python3
"""Reproducible studies (issue #21), through the real stacks: one (seed, episode) of a grid
replays alone exactly, and the same grid gives the same rows with the machine loaded.

Before: the human of (seed, episode) was seeded with seed + episode - 1 and the planner and
the world once per stack, so an episode depended on the episodes run before it in its cell
(a cell of episode 2 alone replayed episode 0); and DESPOT's 0.1 s wall-clock budget grew or
shrank its search with the machine's load, so a loaded run gave other decisions. Now every
episode draws from the streams of (seed, episode, role) and experiments bound DESPOT by
trials, not time."""
import csv
import os
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

import rostest

from ros_hrc.experiment.stack import CellSpec, decode_episode, worker_command, write_spec
from ros_hrc.model_files import resolve_model

#: Columns that carry wall time: the only ones a loaded machine may change.
WALL_COLUMNS = ("mean_decision_ms", "wall_seconds")
HUMAN = "tired"
STEP_LIMIT = 8


def run_cell(episodes, log_dir):
    """The cell (HUMAN, pomdp, seed 0) of ``episodes`` on a stack of its own, as
    hrc_experiment's worker runs it: {episode: (episode row, step rows)} as dicts."""
    spec = CellSpec(HUMAN, "pomdp", 0, episodes, step_limit=STEP_LIMIT, log_dir=str(log_dir),
                    human_model_file=str(resolve_model(HUMAN, "human")),
                    robot_model=str(resolve_model("robot", "robot")))
    done = subprocess.run(worker_command(write_spec(spec, Path(log_dir))),
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    out = {}
    for line in done.stdout.splitlines():
        decoded = decode_episode(line)
        if decoded:
            row, steps = decoded
            out[row.episode] = (without_wall_time(row.as_dict()), [s.as_dict() for s in steps])
    return out


def without_wall_time(row):
    """The row without its wall-time columns (simulated times are rounded to the microsecond
    by the scorer, so the rest must be identical)."""
    return {k: v for k, v in row.items() if k not in WALL_COLUMNS}


def run_experiment(out):
    cmd = [sys.executable, "-m", "ros_hrc.experiment.cli", "--human-models", HUMAN,
           "--policies", "pomdp", "--seeds", "0", "--episodes", "3", "--step-limit",
           str(STEP_LIMIT), "--jobs", "1", "--no-plots", "--out", out]
    done = subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                          timeout=800)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]


def read_rows(path):
    with open(path, newline="") as f:
        return [without_wall_time(row) for row in csv.DictReader(f)]


class TestReproducibleStudy(unittest.TestCase):

    def test_one_episode_of_a_cell_replays_alone_exactly(self):
        work = tempfile.mkdtemp(prefix="hrc_streams_")
        grid = run_cell([0, 1, 2, 3], os.path.join(work, "grid"))
        alone = run_cell([2], os.path.join(work, "alone"))
        self.assertEqual(sorted(grid), [0, 1, 2, 3])
        self.assertEqual(sorted(alone), [2])
        self.assertEqual(alone[2][1], grid[2][1], "episode 2's steps differ when run alone")
        self.assertEqual(alone[2][0], grid[2][0], "episode 2's row differs when run alone")
        # No two episodes share a stream: the four are not copies of one another.
        traces = {tuple((s["human_action"], s["human_state"], s["robot_action"])
                        for s in steps) for _, steps in grid.values()}
        self.assertGreater(len(traces), 1, "every episode of the cell played the same")

    def test_a_grid_run_twice_once_under_load_gives_the_same_rows(self):
        quiet = tempfile.mkdtemp(prefix="hrc_quiet_")
        loaded = tempfile.mkdtemp(prefix="hrc_loaded_")
        run_experiment(quiet)
        # Two processes spinning for the whole run (this machine's two cores), stopped by
        # their own PIDs after.
        burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"])
                   for _ in range(2)]
        try:
            run_experiment(loaded)
        finally:
            for burner in burners:
                burner.kill()
                burner.wait()
        for name in ("episodes.csv", "steps.csv", os.path.join("alone", "episodes.csv")):
            first = read_rows(os.path.join(quiet, name))
            second = read_rows(os.path.join(loaded, name))
            self.assertTrue(first, name)
            self.assertEqual(second, first, f"{name} differs under load")


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "experiment_streams", TestReproducibleStudy, sys.argv)
