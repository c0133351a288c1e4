#!/usr/bin/env python3
"""`roslaunch ros_hrc hrc.launch task:=fabric`, headless (issue #22): the ROS wiring of the
successor task.

The stack runs fabric with its defaults (a beginner, non-tired, collaborative human; the
authors' robot model) and a robot that explores (a random action each step). /hrc/status
carries the task's names in every field (its states, actions, observations, the belief over
its robot states), steps numbered in order, none failed. How the human reacts to the robot's
grasp and point, rule by rule, in fabric's own world, is test/unit/loop/test_fabric_loop.py's
(the same coordinator, world, MDP process and robot agent, in one thread).
"""
import sys
import unittest

import rospy
import rostest

from hrc_stack import StatusLog, start_stack, stop_stack
from ros_hrc import tasks

FABRIC = tasks.get("fabric")
#: Steps to watch: two episodes of at most 10 steps, through the reset between them.
STEPS = 14


class TestFabric(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_fabric", anonymous=True)
        cls.log = StatusLog()

    def tearDown(self):
        if getattr(self, "proc", None) is not None:
            stop_stack(self.proc)
            self.proc = None

    def test_every_status_field_is_the_task_s(self):
        self.proc = start_stack("task:=fabric", "planner:=explore", "on_episode_end:=reset",
                                "max_steps:=10", name="fabric")
        ok, statuses = self.log.wait_for(lambda s: len(s) >= STEPS)
        self.assertTrue(ok, f"only {len(statuses)} steps came")
        before = None
        for status in statuses:
            where = f"episode {status.episode} step {status.step}"
            self.assertEqual(status.fault, "", where)
            self.assertEqual(status.human_state, FABRIC.human_states[status.human_state_index],
                             where)
            self.assertIn(status.human_action, FABRIC.human_actions, where)
            self.assertIn(status.robot_action, FABRIC.robot_actions, where)
            self.assertIn(status.robot_observation, FABRIC.observations.names, where)
            self.assertIn(status.robot_state, FABRIC.robot_states, where)
            self.assertEqual(list(status.belief_states), list(FABRIC.robot_states), where)
            if before is not None and (before.epoch, before.episode) == (status.epoch,
                                                                         status.episode):
                self.assertEqual(status.step, before.step + 1, where)
            before = status
        self.assertGreater(len({s.episode for s in statuses}), 1, "no reset between episodes")


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "hrc_fabric", TestFabric, sys.argv)
