#!/usr/bin/env python3
"""`hrc_experiment` on a tiny grid, as a researcher runs it: two robot policies against one
kind of human, through the real stack, each episode set against the same human stream alone
(run by hrc_experiment itself) with the paired tests in the summary; then the same command
again resumes and adds nothing, the human alone included. And one cell whose model files are
typed relative to the directory the command runs in."""
import csv
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

import rostest

from ros_hrc.experiment.rows import EPISODE_COLUMNS, STEP_COLUMNS

#: On one stack: the robots' cells wait for their human's alone cell (their paired
#: counterfactual), and a second stack's start costs more CPU than the four episodes it
#: would share; stacks side by side are experiment_sequence.test's first run.
GRID = ["--human-models", "expert", "--policies", "pomdp,reactive", "--seeds", "0",
        "--episodes", "2", "--step-limit", "8", "--jobs", "1"]
OUTCOMES = ("both_succeed", "rescued", "pre_empted", "hindered", "both_fail")


MODELS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "models")


def run_experiment(out, grid=GRID, cwd=None):
    # The devel-space command, as `rosrun ros_hrc hrc_experiment` would start it.
    cmd = [sys.executable, "-m", "ros_hrc.experiment.cli"] + grid + ["--out", out]
    return subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                          timeout=800, cwd=cwd)


def read_csv(path):
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        return reader.fieldnames, list(reader)


class TestExperiment(unittest.TestCase):

    def test_tiny_grid_end_to_end_then_resume(self):
        out = tempfile.mkdtemp(prefix="hrc_experiment_")
        self.addCleanup(shutil.rmtree, out, ignore_errors=True)
        first = run_experiment(out)
        self.assertEqual(first.returncode, 0, first.stdout[-3000:] + first.stderr[-3000:])

        header, episodes = read_csv(os.path.join(out, "episodes.csv"))
        self.assertEqual(tuple(header), EPISODE_COLUMNS)
        self.assertEqual(len(episodes), 4, "2 policies x 1 seed x 2 episodes")
        self.assertEqual({(e["robot_policy"], e["episode"]) for e in episodes},
                         {("pomdp", "0"), ("pomdp", "1"), ("reactive", "0"), ("reactive", "1")})
        # The human alone on the same two streams, run once for both policies.
        _, alone = read_csv(os.path.join(out, "alone", "episodes.csv"))
        self.assertEqual(sorted((a["robot_policy"], a["episode"]) for a in alone),
                         [("no_robot", "0"), ("no_robot", "1")])
        alone_success = {a["episode"]: a["success"] for a in alone}
        for e in episodes:
            self.assertIn(e["outcome"], OUTCOMES, e)
            self.assertEqual(e["alone_success"], alone_success[e["episode"]], e)
            self.assertEqual(e["in_sample"], "0")
            self.assertEqual(e["time_to_success"] == "nan", e["success"] == "0", e)
            self.assertGreaterEqual(int(e["wasted_actions"]), 0)
            self.assertGreaterEqual(int(e["against_warning"]), 0)
            steps = int(e["steps"])
            self.assertTrue(1 <= steps <= 8, e)
            self.assertIn(e["end_reason"], ("success", "object_left_belt", "step_limit"))
            self.assertEqual(e["success"] == "1", e["end_reason"] == "success", e)
            self.assertGreater(float(e["sim_seconds"]), 0.0, e)
        for a in alone:
            self.assertNotEqual(a["succeeded_by"], "robot", "a robot that never acts")
            self.assertEqual(a["intrusive_actions"], "0")

        header, steps = read_csv(os.path.join(out, "steps.csv"))
        self.assertEqual(tuple(header), STEP_COLUMNS)
        self.assertEqual(len(steps), sum(int(e["steps"]) for e in episodes))
        for s in steps:
            self.assertTrue(0.0 <= float(s["belief_needs_help"]) <= 1.0 + 1e-9, s)
        for name in ("summary.csv", "summary.md", "outcomes.png", "time_gain.png", "belief.png",
                     "run.json"):
            self.assertTrue(os.path.getsize(os.path.join(out, name)) > 0, name)
        with open(os.path.join(out, "outcomes.png"), "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        summary = open(os.path.join(out, "summary.md")).read()
        # (tabulate pads the cells)
        self.assertRegex(summary, r"\| expert +\| pomdp +\| reactive +\| +2 \|")  # the best budget
        self.assertRegex(summary, r"\| expert +\| pomdp +\| no_robot +\| +2 \|")  # the human alone
        self.assertIn("p (McNemar)", summary)
        self.assertIn("p (Wilcoxon)", summary)
        _, table = read_csv(os.path.join(out, "summary.csv"))
        pomdp = next(t for t in table if t["robot_policy"] == "pomdp")
        self.assertEqual(pomdp["best_reactive"], "reactive")
        for column in ("vs_reactive_success_p", "vs_alone_success_p", "vs_alone_pre_empted_p"):
            self.assertTrue(0.0 <= float(pomdp[column]) <= 1.0, (column, pomdp[column]))
        self.assertIn("episodes/min", first.stdout)
        self.assertIn("speed-up over real time", first.stdout)
        # The run's end: the headline, not the whole summary; every file written listed; no lock.
        self.assertNotIn("## Paired comparisons", first.stdout)
        written = [line for line in first.stdout.splitlines()
                   if line.startswith(f"hrc_experiment: written in {out}: ")]
        self.assertEqual(len(written), 1, first.stdout[-3000:])
        for name in ("run.json", "summary.md", "success.png", "logs/"):
            self.assertIn(name, written[0])
        self.assertFalse(os.path.exists(os.path.join(out, ".lock")))

        # The same command again: everything is recorded, nothing runs, nothing is doubled.
        again = run_experiment(out)
        self.assertEqual(again.returncode, 0, again.stderr[-3000:])
        self.assertIn("0 to run", again.stdout)
        self.assertNotIn("of the human alone", again.stdout)
        self.assertEqual(len(read_csv(os.path.join(out, "episodes.csv"))[1]), 4)
        self.assertEqual(len(read_csv(os.path.join(out, "alone", "episodes.csv"))[1]), 2)

    def test_relative_model_paths_run_their_cell(self):
        """Before: the robot process, started by roslaunch in $ROS_HOME, found no
        `mine/robot.pomdp`, respawned every second, and the cell failed after 600 s."""
        work = tempfile.mkdtemp(prefix="hrc_experiment_relative_")
        self.addCleanup(shutil.rmtree, work, ignore_errors=True)
        os.makedirs(os.path.join(work, "mine"))
        shutil.copy(os.path.join(MODELS, "robot", "robot.pomdp"), os.path.join(work, "mine"))
        shutil.copy(os.path.join(MODELS, "human", "expert.pomdpx"), os.path.join(work, "mine"))
        grid = ["--robot-model", "mine/robot.pomdp", "--human-models", "mine/expert.pomdpx",
                "--policies", "pomdp", "--seeds", "0", "--episodes", "1", "--step-limit", "3",
                "--jobs", "1", "--no-plots"]
        done = run_experiment("results", grid, cwd=work)
        self.assertEqual(done.returncode, 0, done.stdout[-3000:] + done.stderr[-3000:])
        _, episodes = read_csv(os.path.join(work, "results", "episodes.csv"))
        self.assertEqual([(e["human_model"], e["robot_policy"], e["episode"]) for e in episodes],
                         [("mine/expert.pomdpx", "pomdp", "0")])
        self.assertTrue(1 <= int(episodes[0]["steps"]) <= 3, episodes[0])


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "hrc_experiment_tiny_grid", TestExperiment, sys.argv)
