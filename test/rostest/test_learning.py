#!/usr/bin/env python3
"""`roslaunch ros_hrc hrc.launch tasks:=5 selector:=pomdp_learning`, headless (issue #40).

The robot that learns its human plays a sequence of five tasks with one human who often fails
a grasp (``persistent_failer``), its prior the pooled model priced by the task's utility
(``robot_utility_fitted``). Checked as a user would check it: five /hrc/task_status
messages, each naming the selector and carrying the learnt figure (what it is, a probability,
its spread), the figure not the same after every task (the robot learnt something); every
step's /hrc/status carries the figure the robot planned that task with.
"""
import math
import sys
import unittest

import rospy
import rostest

from hrc_stack import StatusLog, TaskLog, start_stack, stop_stack
from ros_hrc.link.transport import free_port

TASKS = 5
#: Safety net for the whole sequence (not an assertion about speed).
WAIT = 400.0


class TestLearning(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_learning", anonymous=True)
        cls.steps = StatusLog()
        cls.tasks = TaskLog()
        cls.proc = start_stack(f"tasks:={TASKS}", "selector:=pomdp_learning",
                               "robot_model:=robot_utility_fitted",
                               "human_model:=persistent_failer", "learning_draws:=4",
                               f"pomdp_port:={free_port()}", f"human_port:={free_port()}",
                               name="learning")

    @classmethod
    def tearDownClass(cls):
        stop_stack(cls.proc)

    def test_five_tasks_each_with_the_learnt_figure_which_moves(self):
        reports = self.tasks.wait_for(TASKS, timeout=WAIT)
        self.assertEqual(len(reports), TASKS, f"only {len(reports)} task statuses came")
        self.assertEqual([r.task_index for r in reports], list(range(1, TASKS + 1)))
        for report in reports:
            where = f"task {report.task_index}"
            self.assertEqual(report.selector, "pomdp_learning", where)
            self.assertIn("recovers alone", report.learnt_name, where)
            self.assertTrue(0.0 <= report.learnt_value <= 1.0, where)
            self.assertTrue(math.isfinite(report.learnt_spread) and report.learnt_spread >= 0,
                            where)
            self.assertEqual(list(report.type_names), [], f"{where}: the posterior's draws "
                                                          "are no human types")
        values = [r.learnt_value for r in reports]
        self.assertGreater(max(values) - min(values), 1e-6,
                           f"the learnt figure did not move over {TASKS} tasks: {values}")

        # Each step shows the figure the robot planned its task with: the one the task
        # before it ended with (the prior's for the first task).
        _, statuses = self.steps.wait_for(lambda s: True, timeout=1.0)
        for before, report in zip([None] + reports[:-1], reports):
            steps = [s for s in statuses if s.episode == report.episode and not s.fault]
            self.assertTrue(steps, f"task {report.task_index}: no /hrc/status")
            for s in steps:
                self.assertEqual(s.learnt_name, report.learnt_name)
                if before is not None:
                    self.assertAlmostEqual(s.learnt_value, before.learnt_value, places=9)


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "test_learning", TestLearning, sys.argv)
