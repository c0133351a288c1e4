#!/usr/bin/env python3
"""`hrc_experiment --sequence` on a tiny grid, as a researcher runs it: one kind of human,
a fixed library policy and the random selector, two sequences of three tasks per cell through
the real stack (a cell's sequences one after the other on its one stack), one row per task in
tasks.csv, the summary with the paired tests and the learning curve; then the same study with
one sequence more per cell runs only the new sequences and keeps every row of the first
run."""
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import rostest

from ros_hrc.experiment.sequence_rows import SEQUENCE_COLUMNS, TASK_COLUMNS

GRID = ["--sequence", "3", "--human-models", "expert", "--selectors", "fixed:authors,random",
        "--seeds", "0", "--step-limit", "8", "--jobs", "2"]


def run_experiment(out, *more):
    # The devel-space command, as `rosrun ros_hrc hrc_experiment` would start it.
    cmd = [sys.executable, "-m", "ros_hrc.experiment.cli"] + GRID + list(more) + ["--out", out]
    return subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                          timeout=800)


def read_csv(path):
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        return reader.fieldnames, list(reader)


class TestExperimentSequences(unittest.TestCase):

    def test_tiny_sequence_grid_end_to_end_then_grown_by_a_sequence(self):
        out = tempfile.mkdtemp(prefix="hrc_experiment_sequence_")
        self.addCleanup(shutil.rmtree, out, ignore_errors=True)
        first = run_experiment(out, "--episodes", "2")
        self.assertEqual(first.returncode, 0, first.stdout[-3000:] + first.stderr[-3000:])
        header, tasks = read_csv(os.path.join(out, "tasks.csv"))
        self.assertEqual(tuple(header), TASK_COLUMNS)
        self.assertEqual(len(tasks), 12, "2 selectors x 2 sequences x 3 tasks")
        for t in tasks:
            self.assertEqual((t["schedule"], t["human_model"], t["true_type"], t["seed"]),
                             ("expert", "expert", "expert", "0"), t)
            self.assertIn(t["outcome"], ("success", "fail", "timeout"), t)
            self.assertEqual(t["success"] == "1", t["outcome"] == "success", t)
            self.assertTrue(-2.0 <= float(t["utility"]) <= 1.0, t)
            self.assertTrue(1 <= int(t["steps"]) <= 8, t)
            # Task t of sequence s is the loop's episode 3s + t - 1: its own streams.
            self.assertEqual(int(t["task_episode"]),
                             3 * int(t["episode"]) + int(t["task_index"]) - 1, t)
        fixed = [t for t in tasks if t["selector"] == "fixed:authors"]
        self.assertEqual([t["task_index"] for t in fixed], ["1", "2", "3"] * 2)
        self.assertEqual({t["policy"] for t in fixed}, {"authors"})
        chosen = {t["policy"] for t in tasks if t["selector"] == "random"}
        self.assertTrue(chosen, "random chose a policy for every task")
        header, sequences = read_csv(os.path.join(out, "sequences.csv"))
        self.assertEqual(tuple(header), SEQUENCE_COLUMNS)
        # Each cell's two sequences, played one after the other on the cell's stack.
        self.assertEqual(sorted((s["selector"], s["episode"], s["tasks"]) for s in sequences),
                         [("fixed:authors", "0", "3"), ("fixed:authors", "1", "3"),
                          ("random", "0", "3"), ("random", "1", "3")])
        for name in ("summary.md", "summary.csv", "learning_curve.csv", "learning_curve.png",
                     "run.json"):
            self.assertTrue(os.path.getsize(os.path.join(out, name)) > 0, name)
        summary = open(os.path.join(out, "summary.md")).read()
        # random against the best fixed policy, on the same six tasks.
        self.assertRegex(summary, r"\| expert +\| random +\| fixed:authors \(best fixed\) +\| +6 \|")
        with open(os.path.join(out, "run.json")) as f:
            run = json.load(f)
        self.assertEqual((run["sequences"], run["tasks"]), (4, 12))
        self.assertIn("tasks/min", first.stdout)

        # One sequence more per cell: only sequence 2 of each cell runs. On one stack (the
        # first run took both cores' stacks side by side): both cells follow each other on
        # it, and a second stack would only cost its start.
        again = run_experiment(out, "--episodes", "3", "--jobs", "1")
        self.assertEqual(again.returncode, 0, again.stdout[-3000:] + again.stderr[-3000:])
        self.assertIn("4 already in", again.stdout)
        _, grown = read_csv(os.path.join(out, "tasks.csv"))
        self.assertEqual(grown[:12], tasks, "the first run's rows are kept as they were")
        self.assertEqual(sorted({(t["selector"], t["episode"]) for t in grown[12:]}),
                         [("fixed:authors", "2"), ("random", "2")])
        for t in grown[12:]:
            self.assertEqual(int(t["task_episode"]), 6 + int(t["task_index"]) - 1, t)
        # The same human streams under both selectors: their nine tasks are paired.
        summary = open(os.path.join(out, "summary.md")).read()
        self.assertRegex(summary, r"\| expert +\| random +\| fixed:authors \(best fixed\) +\| +9 \|")


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "hrc_experiment_tiny_sequences", TestExperimentSequences,
                   sys.argv)
