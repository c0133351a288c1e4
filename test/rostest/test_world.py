#!/usr/bin/env python3
"""Launched test of hrc_world (world.test, world_sim_time.test).

``~suite`` picks the checks: ``services`` (default) calls every service the way the loop's
nodes do and checks the world answers as a person expects; ``sim_time`` checks that the node,
being the clock under /use_sim_time, publishes /clock and still serves.
"""
import os
import threading
import unittest

import rospy
import rosservice
import rostest
from rosgraph_msgs.msg import Clock
from std_srvs.srv import Trigger

from ros_hrc.msg import WorldState

PKG = "ros_hrc"
#: The seed's Table 3.2, in its order.
TABLE_3_2 = [
    "/human/walk_away", "/human/look_around", "/human/warn_robot", "/human/attempt_grasp",
    "/human/grasp", "/human/is_ov", "/human/is_oir", "/human/is_ho", "/human/is_a0",
    "/human/is_a2", "/human/is_h4", "/human/reset", "/robot/point_to_obj", "/robot/grasp",
    "/robot/cancel_action", "/robot/reset",
]
EXTRA = ["/human/idle", "/hrc/world/snapshot",
         "/robot/grasp_planning"]   # the fabric task's graspPlanning
WAIT = 60.0


class WorldTestBase(unittest.TestCase):
    """Waits for the node and keeps one proxy per service."""

    @classmethod
    def setUpClass(cls):
        for name in TABLE_3_2 + EXTRA:
            rospy.wait_for_service(name, timeout=WAIT)
        cls.proxies = {name: rospy.ServiceProxy(name, Trigger) for name in TABLE_3_2 + EXTRA}

    def call(self, name):
        response = self.proxies[name]()
        return response.success, response.message

    def predicates(self):
        return {name: self.call(f"/human/{name}")[0]
                for name in ("is_ov", "is_oir", "is_ho", "is_a0", "is_a2", "is_h4")}

    def state(self):
        return rospy.wait_for_message("/hrc/world_state", WorldState, timeout=WAIT)


class WorldServices(WorldTestBase):
    """The world's ROS wiring: every service of Table 3.2 as a Trigger, the predicates and an
    action's outcome (or its refusal, with the reason) in its answer, the robot's action by the
    task's name in the published state, snapshots, concurrent callers. What each action does
    is the world's unit tests' (test/unit/world/)."""

    def setUp(self):
        for name in ("/human/reset", "/robot/reset"):
            ok, message = self.call(name)
            self.assertTrue(ok, message)

    def test_all_table_3_2_services_exist_as_trigger(self):
        for name in TABLE_3_2 + EXTRA:
            self.assertEqual(rosservice.get_service_type(name), "std_srvs/Trigger", name)

    def test_after_reset_the_object_is_seen_and_in_reach_and_the_human_idle(self):
        self.assertEqual(self.predicates(), {"is_ov": True, "is_oir": True, "is_ho": False,
                                             "is_a0": False, "is_a2": True, "is_h4": False})

    def test_grasp_in_reach_holds_the_object(self):
        ok, message = self.call("/human/grasp")
        self.assertTrue(ok, message)
        self.assertTrue(self.call("/human/is_ho")[0])
        self.assertEqual(self.state().holder, "human")
        ok, message = self.call("/robot/grasp")
        self.assertFalse(ok)
        self.assertIn("human holds", message)

    def test_point_then_cancel_then_reset(self):
        ok, message = self.call("/robot/point_to_obj")
        self.assertTrue(ok, message)
        # The robot's actions by the task's names, as the step block shows them.
        self.assertEqual(self.state().robot_action, "rPoint_obj")
        ok, message = self.call("/robot/cancel_action")
        self.assertTrue(ok, message)
        self.assertEqual(self.state().robot_action, "rStop_all")
        ok, message = self.call("/robot/reset")
        self.assertTrue(ok, message)
        self.assertEqual(self.state().robot_action, "rIdle")

    def test_world_state_is_published_and_the_belt_carries_the_object(self):
        before = self.state()
        self.call("/human/look_around")
        after = self.state()
        self.assertGreater(after.sim_time, before.sim_time + 2.0)
        moved = after.object_position[0] - before.object_position[0]
        self.assertAlmostEqual(moved, before.belt_speed * (after.sim_time - before.sim_time), delta=0.05)
        self.assertTrue(after.object_visible and after.human_idle)

    def test_snapshot_writes_a_png(self):
        ok, path = self.call("/hrc/world/snapshot")
        self.assertTrue(ok, path)
        with open(path, "rb") as image:
            self.assertEqual(image.read(8), b"\x89PNG\r\n\x1a\n")
        os.remove(path)

    def test_concurrent_calls_all_get_answers(self):
        results, errors = [], []

        def worker(names):
            try:
                proxies = [rospy.ServiceProxy(n, Trigger) for n in names]
                for proxy in proxies:
                    results.append(proxy().message)
            except rospy.ServiceException as error:
                errors.append(error)

        jobs = [["/human/warn_robot", "/human/is_h4"], ["/robot/point_to_obj"],
                ["/human/is_ov", "/human/is_oir"] * 5, ["/robot/cancel_action", "/human/is_a2"] * 3]
        threads = [threading.Thread(target=worker, args=(job,)) for job in jobs]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(WAIT)
        self.assertEqual(errors, [])
        self.assertEqual(len(results), sum(len(job) for job in jobs))


class WorldSimTime(WorldTestBase):
    """Under /use_sim_time the world is the clock and keeps serving."""

    def test_clock_runs_and_services_answer(self):
        self.assertTrue(rospy.get_param("/use_sim_time"))
        first = rospy.wait_for_message("/clock", Clock, timeout=WAIT).clock
        second = rospy.wait_for_message("/clock", Clock, timeout=WAIT).clock
        self.assertGreater(second, first)
        ok, message = self.call("/robot/point_to_obj")
        self.assertTrue(ok, message)
        state = self.state()
        self.assertAlmostEqual(state.header.stamp.to_sec(), state.sim_time, places=3)


if __name__ == "__main__":
    rospy.init_node("test_world", anonymous=True)
    suite = rospy.get_param("~suite", "services")
    rostest.rosrun(PKG, f"test_world_{suite}", WorldSimTime if suite == "sim_time" else WorldServices)
