#!/usr/bin/env python3
"""What RViz shows, as a user would check it with rostopic, rosparam and tf: after a step of
`roslaunch ros_hrc hrc.launch` (headless), /tf holds every link of both agents, the object and
the belt; both agents' joint states and the step's markers are published, their text hrc_world's caption of the step being played
(/hrc/caption); both descriptions are on the parameter server."""
import sys
import unittest
import xml.etree.ElementTree as ElementTree

import rospy
import rostest
import tf2_ros
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from hrc_stack import WAIT, StatusLog, start_stack, stop_stack


class TestViz(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_viz", anonymous=True)
        cls.log = StatusLog()
        # Ports of its own: nothing else of the suite can hold them while it runs.
        cls.proc = start_stack("viz:=true", "mode:=auto", "on_episode_end:=continue",
                               "human_model:=beginner",
                               "pomdp_port:=7371", "human_port:=9371",
                               name="viz")
        cls.buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30))
        cls.listener = tf2_ros.TransformListener(cls.buffer)

    @classmethod
    def tearDownClass(cls):
        stop_stack(cls.proc)

    def test_a_step_is_shown_on_tf_joint_states_markers_and_descriptions(self):
        ok, statuses = self.log.wait_for(lambda s: len(s) >= 2)
        self.assertTrue(ok, f"only {len(statuses)} steps came")

        for agent in ("human", "robot"):
            description = rospy.get_param(f"/{agent}/robot_description")
            links = [link.get("name") for link in ElementTree.fromstring(description).iter("link")]
            self.assertGreater(len(links), 5, agent)
            self.assertTrue(all(name.startswith(f"{agent}/") for name in links), links)

            joints = rospy.wait_for_message(f"/{agent}/joint_states", JointState, timeout=WAIT)
            self.assertGreater(len(joints.name), 3, agent)
            self.assertEqual(len(joints.name), len(joints.position))

            # every link of the agent is a frame of the one tree rooted at world
            for link in links:
                transform = self.buffer.lookup_transform("world", link, rospy.Time(0),
                                                         rospy.Duration(WAIT))
                self.assertEqual(transform.header.frame_id, "world")
        for frame in ("object", "object_floor", "belt"):
            self.buffer.lookup_transform("world", frame, rospy.Time(0), rospy.Duration(WAIT))

        markers = rospy.wait_for_message("/hrc/markers", MarkerArray, timeout=WAIT).markers
        # RViz shows a marker only in a frame /tf knows (the holder's: the floor under the object).
        for marker in markers:
            self.buffer.lookup_transform("world", marker.header.frame_id, rospy.Time(0),
                                         rospy.Duration(WAIT))
        spaces = {m.ns for m in markers}
        self.assertTrue({"belief", "belief_labels", "step", "holder", "scenery"} <= spaces, spaces)
        bars = [m for m in markers if m.ns == "belief"]
        self.assertEqual(len(bars), 7, "one bar per state S0..S6")
        step_text = next(m for m in markers if m.ns == "step").text
        self.assertIn("step", step_text)
        self.assertIn("P(human needs help)", step_text)
        # The text is the caption of the step being played, from the world (not the last
        # report alone): "episode E, step N: playing" while it is played, ": done" after.
        caption = rospy.wait_for_message("/hrc/caption", String, timeout=WAIT).data
        self.assertRegex(caption.splitlines()[0],
                         r"^episode \d+(, step \d+: (playing|done)|: the world was reset)")
        self.assertRegex(step_text.splitlines()[0], r"^episode \d+, step \d+: (playing|done)")


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "rviz_view", TestViz, sys.argv)
