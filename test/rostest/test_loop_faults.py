#!/usr/bin/env python3
"""The loop under attack, as a hostile user would try it, on one real stack.

* A second MDP client (the manual-mode recipe without start_mdp:=false) is refused with one
  line and exits, with the launch's token (seat taken) and without it (no token); the served
  MDP keeps stepping.
* Frames without the launch's token, on the human and the robot port (an order to grasp),
  are refused and closed; nothing acts.
* A holder of the token who is not the coordinator sends orders to the robot port: refused.
* 50 concurrent /hrc/reset calls all succeed and are one reset (every answer names the same
  episode), and afterwards the steps run 0, 1, 2 ... in one new epoch, every status
  consistent.
* kill -9 of hrc_robot, hrc_obs, despot_pomdp, despot_mdp and hrc_human: each respawns and the
  run goes on from a reset. kill -9 of hrc_world (required): the whole launch stops.
"""
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
import unittest

import rospy
import websocket
import rostest
from std_srvs.srv import Trigger

from ros_hrc.link.protocol import Action, Error, Reset
from ros_hrc.link.token import read_token
from ros_hrc.link.transport import MessageClient, link_url

from hrc_stack import (WAIT, StatusLog, check_epochs, check_step, fresh_run, node_pids,
                       start_stack, stop_stack, wait_for_pids)


class TestLoopFaults(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_loop_faults", anonymous=True)
        cls.log = StatusLog()
        cls.proc = start_stack("mode:=auto", "on_episode_end:=reset", "max_steps:=6",
                               name="faults")

    @classmethod
    def tearDownClass(cls):
        stop_stack(cls.proc)

    def setUp(self):
        self.assertIsNone(self.proc.poll(), "hrc.launch is not running")
        ok, _ = self.log.wait_for(lambda s: len(s) >= 3)
        self.assertTrue(ok, "the loop is not stepping")

    def test_1_a_second_mdp_client_is_refused_and_the_loop_keeps_stepping(self):
        self.log.clear()
        # The documented way for a process run by hand: the token file hrc.launch made.
        token_file = rospy.get_param("/hrc/config/token_file")
        second = subprocess.run(
            [sys.executable, "-m", "ros_hrc.processes.despot_mdp", "--model", "tired"],
            stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=WAIT,
            env=dict(os.environ, HRC_LINK_TOKEN_FILE=token_file))
        self.assertEqual(second.returncode, 3, second.stdout + second.stderr)
        refusal = [line for line in second.stderr.splitlines() if "already served" in line]
        self.assertEqual(len(refusal), 1, second.stderr)
        self.assertTrue(refusal[0].startswith("despot_mdp: refused"), refusal[0])
        self.assertNotIn("Traceback", second.stderr)
        before = len(self.log.statuses)
        ok, statuses = self.log.wait_for(lambda s: len(s) >= before + 5)
        self.assertTrue(ok, "the served MDP stopped stepping after the refusal")
        self.assertFalse(any(s.fault for s in statuses), [s.fault for s in statuses])
        check_epochs(self, statuses)

    def test_1a_a_solver_run_by_hand_without_the_token_says_so_in_one_line(self):
        env = {k: v for k, v in os.environ.items() if k != "HRC_LINK_TOKEN_FILE"}
        second = subprocess.run(
            [sys.executable, "-m", "ros_hrc.processes.despot_mdp", "--model", "tired"],
            stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=WAIT, env=env)
        self.assertEqual(second.returncode, 2, second.stdout + second.stderr)
        self.assertEqual(second.stderr.strip().splitlines(), [
            "despot_mdp: no link token: the links take only processes of the same launch. "
            "Give --token-file PATH or set HRC_LINK_TOKEN_FILE=PATH (hrc.launch prints the "
            "path when a solver is to be run by hand)"])

    def refused_without_the_token(self, port, frames):
        """What the server at ``port`` answers ``frames`` sent without the launch's token."""
        ws = websocket.create_connection(f"ws://127.0.0.1:{port}", timeout=30)
        answers = []
        try:
            for frame in frames:
                ws.send(frame)
            while True:
                try:
                    answers.append(json.loads(ws.recv()))
                except (websocket.WebSocketException, OSError, ValueError):
                    break   # refused and disconnected
        finally:
            ws.close()
        return answers

    def test_1b_frames_without_the_token_are_refused_and_change_nothing(self):
        ok, statuses = self.log.wait_for(lambda s: len(s) >= 1)
        human = self.refused_without_the_token(9090, [json.dumps({"type": "reset"})])
        # The hostile user's order: before the token, this grasped the object.
        robot = self.refused_without_the_token(8080, [
            json.dumps({"type": "hello", "who": "hrc_human", "version": 2}),
            json.dumps({"type": "action", "step": 0, "action": "rGrasp_obj", "id": 1})])
        for answers in (human, robot):
            self.assertEqual([(a["type"], a.get("code")) for a in answers],
                             [("error", "unauthorized")], answers)
        self.log.clear()
        ok, statuses = self.log.wait_for(lambda s: len(s) >= 5)
        self.assertTrue(ok, "the loop stopped stepping after a stray reset frame")
        self.assertFalse(any(s.fault for s in statuses))
        check_epochs(self, statuses)

    def test_1c_the_robot_port_takes_orders_from_the_coordinator_only(self):
        """Issue #20: any holder of the token could send an action to the robot port, with no
        epoch, and the robot moved. Only the coordinator's connection gives orders."""
        token_file = rospy.get_param("/hrc/config/token_file")
        client = MessageClient(link_url(8080), "intruder", token=read_token(token_file),
                               backoff=(0.05, 0.5)).connect(WAIT)
        try:
            for order in (Action(step=0, action="rGrasp_obj", epoch=1),
                          Action(step=0, action="rPoint_obj"),
                          Reset(reason="intruder")):
                reply = client.request(order, WAIT)
                self.assertIsInstance(reply, Error, reply)
                self.assertEqual(reply.code, "refused", reply)
                self.assertIn("only from the coordinator", reply.message)
        finally:
            client.close()
        self.log.clear()
        ok, statuses = self.log.wait_for(lambda s: len(s) >= 5)
        self.assertTrue(ok, "the loop stopped stepping after the refused orders")
        self.assertFalse(any(s.fault for s in statuses), [s.fault for s in statuses])

    def test_2_fifty_concurrent_resets_then_steps_from_zero(self):
        answers = []
        rospy.wait_for_service("/hrc/reset", WAIT)

        def reset():
            answers.append(rospy.ServiceProxy("/hrc/reset", Trigger)())

        threads = [threading.Thread(target=reset) for _ in range(50)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(WAIT)
        self.assertEqual(len(answers), 50)
        self.assertTrue(all(a.success for a in answers), {a.message for a in answers})
        # Issue #20: they made 5 to 10 resets, the episode number jumping. One reset: every
        # answer names the episode it started (a call that came while the loop reset itself
        # at an episode's end shares that reset, as documented, and names it).
        ours = [a.message for a in answers if "(/hrc/reset called)" in a.message]
        episodes = {re.search(r"episode (\d+)", m).group(1) for m in ours}
        self.assertEqual(len(episodes), 1, {a.message for a in answers})
        self.log.clear()   # everything from now on comes after every reset was answered
        ok, statuses = self.log.wait_for(lambda s: fresh_run(s, 4))
        self.assertTrue(ok, f"no run 0, 1, 2, 3 after the resets: "
                            f"{[(s.epoch, s.step) for s in statuses][:20]}")
        first_epoch = statuses[0].epoch
        self.assertEqual(statuses[0].step, 0, "a step of an older epoch after the reset")
        for status in statuses:
            if status.epoch == first_epoch:
                check_step(self, status)
        check_epochs(self, statuses)

    def kill_and_expect_a_run_from_a_reset(self, name):
        old = node_pids(self.proc, name)
        self.assertTrue(old, f"no {name} process in the launch")
        self.log.clear()
        for pid in old:
            os.kill(pid, signal.SIGKILL)
        new = wait_for_pids(self.proc, name, unlike=old)
        self.assertTrue(new - old, f"roslaunch did not restart {name}")
        # Steps under way at the kill may fail (their status says so); then a reset, and
        # steps run 0, 1, 2, 3 again.
        ok, statuses = self.log.wait_for(lambda s: fresh_run(s, 4))
        self.assertTrue(ok, f"after {name} restarted, no run from a reset; seen: "
                            f"{[(s.epoch, s.step, s.fault[:40]) for s in statuses][:20]}")
        for status in statuses:
            if not status.fault:
                check_step(self, status)
        check_epochs(self, statuses)

    def test_3_killed_hrc_robot_respawns_and_the_run_goes_on_from_a_reset(self):
        self.kill_and_expect_a_run_from_a_reset("hrc_robot")

    def test_4_killed_hrc_obs_respawns_and_the_run_goes_on_from_a_reset(self):
        self.kill_and_expect_a_run_from_a_reset("hrc_obs")

    def test_5_killed_despot_pomdp_respawns_and_the_run_goes_on_from_a_reset(self):
        self.kill_and_expect_a_run_from_a_reset("despot_pomdp")

    def test_6_killed_despot_mdp_respawns_and_the_run_goes_on_from_a_reset(self):
        self.kill_and_expect_a_run_from_a_reset("despot_mdp")

    def test_7_killed_hrc_human_respawns_and_the_run_goes_on_from_a_reset(self):
        self.kill_and_expect_a_run_from_a_reset("hrc_human")

    def test_8_killed_world_stops_the_whole_launch(self):
        world = node_pids(self.proc, "hrc_world")
        self.assertTrue(world, "no hrc_world in the launch")
        children = set()
        for name in ("hrc_human", "hrc_obs", "hrc_robot", "despot_mdp", "despot_pomdp"):
            children |= node_pids(self.proc, name)
        for pid in world:
            os.kill(pid, signal.SIGKILL)
        try:
            self.proc.wait(WAIT)
        except subprocess.TimeoutExpired:
            self.fail("hrc.launch still runs after its world was killed")
        deadline = time.monotonic() + 30
        alive = children
        while alive and time.monotonic() < deadline:
            alive = {pid for pid in alive if os.path.exists(f"/proc/{pid}")
                     and "zombie" not in open(f"/proc/{pid}/status").read().lower()}
            time.sleep(0.2)
        self.assertFalse(alive, f"processes left after the launch stopped: {alive}")


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "hrc_loop_faults", TestLoopFaults, sys.argv)
