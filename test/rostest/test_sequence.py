#!/usr/bin/env python3
"""`roslaunch ros_hrc hrc.launch task:=fabric tasks:=5 selector:=bpr`, headless (issue #30).

The stack plays a sequence of five tasks: two by one human type, three by another (the
schedule), the robot's BPR selector choosing a policy of fabric's library before each. Its
selector model is a fixture written here (hand-chosen numbers, see
:func:`fixture_selector_model`; the shipped model comes from `make train-selector`). Checked
as a user would check it: five /hrc/task_status messages, one per task in order, each with the
chosen policy and the selector's belief over the types; the world reset between tasks (each
task's first /hrc/status is its step 0, the object on the belt); the tasks' steps as
/hrc/status showed them; after the fifth the loop waits.
"""
import math
import sys
import tempfile
import unittest
from pathlib import Path

import rospy
import rostest

from hrc_stack import StatusLog, TaskLog, start_stack, stop_stack
from ros_hrc import tasks
from ros_hrc.agents.library import load_library
from ros_hrc.agents.selector_model import TrainingTask, from_tasks, write_selector_model
from ros_hrc.link.transport import free_port
from ros_hrc.model_files import model_names
from ros_hrc.tasks.utility import OUTCOMES

FABRIC = tasks.get("fabric")
TASKS = 5
FIRST, SECOND = "expert_tired_noncollaborative", "beginner_nontired_collaborative"
SCHEDULE = f"{FIRST}*2,{SECOND}*3"
#: Safety net for the whole sequence (not an assertion about speed).
WAIT = 600.0


def fixture_selector_model(path):
    """A selector model of hand-chosen numbers, a fixture for this test (not trained: `make
    train-selector` writes the shipped one): every fabric type with every library policy, a
    utility of 0.8 for the pair (type i, policy i mod 13) and 0.3 otherwise, and a signature
    of the codes 1 (in range) and 32 + 1 (idle) for the odd types, 1 and 16 + 1 (a warning)
    for the even ones."""
    policies = load_library("auto", FABRIC).names()
    types = model_names(FABRIC.model_dirs["human"])
    rows = [TrainingTask(name, policy, 0.8 if p == t % len(policies) else 0.3,
                         (1, 33, 1) if t % 2 else (1, 17, 1))
            for t, name in enumerate(types) for p, policy in enumerate(policies)]
    write_selector_model(from_tasks(rows, task="fabric", policies=policies, types=types,
                                    header={"how": "test_sequence.py's fixture: hand-chosen "
                                                   "numbers", "from": "nothing run",
                                            "seeds": [], "command": "", "date": ""}), path)
    return policies, types


class TestSequence(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_sequence", anonymous=True)
        cls.steps = StatusLog()
        cls.tasks = TaskLog()
        cls.folder = tempfile.TemporaryDirectory()
        model = Path(cls.folder.name) / "selector_model.json"
        cls.policies, cls.types = fixture_selector_model(model)
        cls.proc = start_stack("task:=fabric", f"tasks:={TASKS}", "selector:=bpr",
                               f"selector_model:={model}", f"schedule:={SCHEDULE}",
                               "task_timeout:=40", f"pomdp_port:={free_port()}",
                               f"human_port:={free_port()}", name="sequence")

    @classmethod
    def tearDownClass(cls):
        stop_stack(cls.proc)
        cls.folder.cleanup()

    def test_five_tasks_each_with_its_policy_and_belief_the_world_reset_between(self):
        reports = self.tasks.wait_for(TASKS, timeout=WAIT)
        self.assertEqual(len(reports), TASKS, f"only {len(reports)} task statuses came")
        self.assertEqual([r.task_index for r in reports], list(range(1, TASKS + 1)))
        for report in reports:
            where = f"task {report.task_index}"
            self.assertEqual(report.tasks, TASKS, where)
            expected = FIRST if report.task_index <= 2 else SECOND
            self.assertEqual((report.human_model, report.true_type), (expected, expected), where)
            self.assertEqual(report.selector, "bpr", where)
            self.assertIn(report.policy, self.policies, where)
            self.assertEqual(list(report.type_names), list(self.types), where)
            self.assertEqual(len(report.type_belief), len(self.types), where)
            self.assertAlmostEqual(sum(report.type_belief), 1.0, places=6, msg=where)
            best = max(range(len(self.types)), key=lambda i: report.type_belief[i])
            self.assertEqual(report.estimation_correct, self.types[best] == expected, where)
            self.assertIn(report.outcome, OUTCOMES, where)
            self.assertEqual(report.who_succeeded != "", report.outcome == "success", where)
            self.assertGreater(report.steps, 0, where)
            self.assertEqual(len(report.signature), report.steps, where)
            self.assertTrue(all(0 <= code <= 63 for code in report.signature), where)
            self.assertTrue(0.0 <= report.duration, where)
            self.assertTrue(math.isfinite(report.utility) and -1.6 <= report.utility <= 1.0,
                            where)
        self.assertEqual(len({r.episode for r in reports}), TASKS, "one episode per task")

        # The world was reset between tasks: each task's steps, as /hrc/status showed them,
        # start at step 0 with the object on the belt, and are as many as the task says.
        _, statuses = self.steps.wait_for(lambda s: True, timeout=1.0)
        for report in reports:
            where = f"task {report.task_index}"
            steps = [s for s in statuses if s.episode == report.episode and not s.fault]
            self.assertTrue(steps, f"{where}: no /hrc/status of episode {report.episode}")
            first = steps[0]
            self.assertEqual(first.step, 0, where)
            if report.steps > 1:
                self.assertEqual(first.object_holder, "none", f"{where}: the object is not "
                                                              "back on the belt at its start")
                self.assertFalse(first.object_left_belt, where)
            self.assertEqual(len(steps), report.steps, where)
            self.assertEqual(steps[-1].end_reason, report.end_reason, where)
            # The policy its selector chose is known from the task's start (issue #41): every
            # step of it names that policy, and the task's report names what it acts by.
            self.assertEqual({s.policy for s in steps}, {report.policy}, where)
            self.assertTrue(report.robot_model, where)

        # After the last task the loop waits: no sixth task, no step of another episode.
        rospy.sleep(3.0)
        self.assertEqual(len(self.tasks.items), TASKS)
        _, later = self.steps.wait_for(lambda s: True, timeout=1.0)
        self.assertLessEqual({s.episode for s in later}, {r.episode for r in reports})


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "test_sequence", TestSequence, sys.argv)
