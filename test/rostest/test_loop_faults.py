#!/usr/bin/env python3
"""The loop under attack, as a hostile user would try it, on one real stack.

* A second MDP client (the manual-mode recipe without start_mdp:=false) is refused with one
  line and exits, with the launch's token (seat taken) and without it (no token); the served
  MDP keeps stepping.
* Frames without the launch's token, on the human and the POMDP port (a reset of the
  robot's belief), are refused and closed; nothing acts.
* A holder of the token who is not the coordinator sends the robot orders: no link takes
  them (hrc_human calls the world's /robot/* services itself; the POMDP port refuses them).
* 50 concurrent /hrc/reset calls are all answered, each naming the reset that served it;
  calls that met a reset under way share it, and none is served by a reset older than one
  another call had seen finish; afterwards the steps run 0, 1, 2 ... in one new epoch,
  every status consistent.
* Sixteen threads calling the world's services (/human/*, /robot/*) while the loop runs: the
  loop keeps stepping, no step fails (the loop's calls go first; the others are answered
  "busy" while the loop acts).
* kill -9 of despot_pomdp, despot_mdp and hrc_human: each respawns and the run goes on from
  a reset; /hrc/reset while despot_pomdp is down answers at once, in one line, what it could
  not reset, and the reset is retried until it works; a decision under way when despot_pomdp
  dies fails its step visibly (STEP FAILED), then a run from a reset. kill -9 of hrc_world
  (required): the whole launch
  stops, with a non-zero status and one line saying so, and no process of it is left; Ctrl-C
  still ends a launch with status 0 (world.launch with a master of its own: that master ends
  too).
"""
import json
import os
import random
import re
import signal
import subprocess
import sys
import threading
import time
import unittest

import rospy
import rostest
from std_srvs.srv import Trigger
from websockets.exceptions import WebSocketException
from websockets.sync.client import connect

from ros_hrc.experiment.stack import pick_ports
from ros_hrc.link.protocol import Action, Error
from ros_hrc.link.token import read_token
from ros_hrc.link.transport import MessageClient, link_url
from ros_hrc.nodes.guard import children_of
from ros_hrc.world import HUMAN_ACTIONS, PREDICATES, ROBOT_ACTIONS

from hrc_stack import (WAIT, StatusLog, check_epochs, check_step, fresh_run, node_pids,
                       start_stack, stop_stack, wait_for_pids)


class TestLoopFaults(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_loop_faults", anonymous=True)
        cls.log = StatusLog()
        cls.ports = pick_ports()   # the links' ports, free (rostest gives the master)
        cls.proc = start_stack("mode:=auto", "on_episode_end:=reset", "max_steps:=6",
                               f"pomdp_port:={cls.ports['pomdp']}",
                               f"human_port:={cls.ports['human']}", name="faults")
        cls.launch_log = os.readlink(f"/proc/{cls.proc.pid}/fd/1")

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
            [sys.executable, "-m", "ros_hrc.processes.despot_mdp", "--model", "tired",
             "--port", str(self.ports["human"])],
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
        ws = connect(f"ws://127.0.0.1:{port}", open_timeout=30, proxy=None, legacy=True)
        answers = []
        try:
            for frame in frames:
                try:
                    ws.send(frame)
                except WebSocketException:
                    # Refused and closed before this frame went out (a CI-like run saw the
                    # unproven hello answered and the connection closed first): as it should.
                    break
            while True:
                try:
                    answers.append(json.loads(ws.recv(timeout=30)))
                except (WebSocketException, OSError, ValueError):
                    break   # refused and disconnected
        finally:
            ws.close()
        return answers

    def test_1b_frames_without_the_token_are_refused_and_change_nothing(self):
        ok, statuses = self.log.wait_for(lambda s: len(s) >= 1)
        human = self.refused_without_the_token(self.ports["human"], [json.dumps({"type": "reset"})])
        # The hostile user's reset of the robot's belief, said as the coordinator says it (the
        # robot port, where an order to grasp once moved the robot, is gone).
        pomdp = self.refused_without_the_token(self.ports["pomdp"], [
            json.dumps({"type": "hello", "who": "hrc_human", "version": 2}),
            json.dumps({"type": "reset", "reason": "intruder", "epoch": 1, "id": 1})])
        for answers in (human, pomdp):
            self.assertEqual([(a["type"], a.get("code")) for a in answers],
                             [("error", "unauthorized")], answers)
        self.log.clear()
        ok, statuses = self.log.wait_for(lambda s: len(s) >= 5)
        self.assertTrue(ok, "the loop stopped stepping after a stray reset frame")
        self.assertFalse(any(s.fault for s in statuses))
        check_epochs(self, statuses)

    def test_1c_no_link_takes_orders_for_the_robot(self):
        """Issue #20: any holder of the token could send an action to the robot port, with no
        epoch, and the robot moved; then the robot port took orders from the coordinator's
        connection only. Now no link takes orders for the robot: hrc_human, which hosts the
        coordinator, calls the world's /robot/* services itself. A token holder's orders on
        the POMDP port, the link of the robot's decisions, are refused."""
        token_file = rospy.get_param("/hrc/config/token_file")
        client = MessageClient(link_url(self.ports["pomdp"]), "intruder",
                               token=read_token(token_file), backoff=(0.05, 0.5)).connect(WAIT)
        try:
            for order in (Action(step=0, action="rGrasp_obj", epoch=1),
                          Action(step=0, action="rPoint_obj")):
                reply = client.request(order, WAIT)
                self.assertIsInstance(reply, Error, reply)
                self.assertEqual(reply.code, "unknown_type", reply)
                self.assertIn("does not take action messages", reply.message)
        finally:
            client.close()
        self.log.clear()
        ok, statuses = self.log.wait_for(lambda s: len(s) >= 5)
        self.assertTrue(ok, "the loop stopped stepping after the refused orders")
        self.assertFalse(any(s.fault for s in statuses), [s.fault for s in statuses])

    def test_2_fifty_concurrent_resets_then_steps_from_zero(self):
        """What /hrc/reset promises (docs/loop.md): every call is answered, once the reset that
        served it is done, naming it; calls that come while a reset is under way (or within
        reset_join_window after it, asked the same way) share it. How many resets fifty calls
        make depends on when rospy's fifty connections reach the node (a CI run saw two,
        episodes 35 and 76: a call that came after the first reset had ended rightly started
        another), so the test asserts what holds for any arrival: the answers, the reset each
        names, and that no call is served by a reset older than one another call saw end."""
        calls = []      # (sent, answered, answer): a clock's order, never a duration
        guard = threading.Lock()
        rospy.wait_for_service("/hrc/reset", WAIT)
        start = threading.Barrier(50)

        def reset():
            proxy = rospy.ServiceProxy("/hrc/reset", Trigger)
            start.wait(WAIT)
            sent = time.monotonic()
            answer = proxy()
            with guard:
                calls.append((sent, time.monotonic(), answer))

        threads = [threading.Thread(target=reset) for _ in range(50)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(WAIT)
        self.assertEqual(len(calls), 50)
        said = {answer.message for _, _, answer in calls}
        self.assertTrue(all(answer.success for _, _, answer in calls), said)
        # Each answer names the reset that served it: one the loop made for /hrc/reset, or
        # the loop's own at an episode's end that the call came during (it shares that one).
        named = re.compile(r"world, robot belief and human MDP reset \((.*)\): episode (\d+)"
                           r"( \(this request joined it: it came as it finished\))?$")
        served = []
        for sent, answered, answer in calls:
            found = named.match(answer.message)
            self.assertIsNotNone(found, answer.message)
            served.append((sent, answered, int(found.group(2)), found.group(1)))
        # Calls that share a reset get the same account of it (a joiner adds that it joined).
        by_episode = {}
        for _, _, episode, reason in served:
            by_episode.setdefault(episode, set()).add(reason)
        self.assertTrue(all(len(reasons) == 1 for reasons in by_episode.values()), said)
        # Issue #20 made a reset per call, answered out of order. A reset served a call only
        # if it ended after that call was sent: a call sent after another call's answer
        # came is never served by an older reset than that answer names.
        for sent, _, episode, _ in served:
            for _, other_answered, other_episode, _ in served:
                if other_answered < sent:
                    self.assertGreaterEqual(episode, other_episode, said)
        self.log.clear()   # everything from now on comes after every reset was answered
        ok, statuses = self.log.wait_for(lambda s: fresh_run(s, 4))
        self.assertTrue(ok, f"no run 0, 1, 2, 3 after the resets: "
                            f"{[(s.epoch, s.step) for s in statuses][:20]}")
        first_epoch = statuses[0].epoch
        # No step of an episode before the last reset's (the loop may have stepped, even
        # ended that episode, between the answers and clear(): its episodes end in a step or
        # two).
        reset_episode = max(by_episode)
        self.assertGreaterEqual(min(s.episode for s in statuses), reset_episode,
                                "a step of an older episode after the reset")
        for status in statuses:
            if status.epoch == first_epoch:
                check_step(self, status)
        check_epochs(self, statuses)

    def test_2b_a_storm_of_world_calls_does_not_starve_the_loop(self):
        """Issue #20: sixteen threads calling world services starved the loop for up to 40 s,
        and no step said why. The loop's calls go first (an outside action under way is
        interrupted, the step's result says so); outside calls for an agent the loop is using
        are answered "busy" at once."""
        services = [f"/human/{a}" for a in HUMAN_ACTIONS + PREDICATES] + \
            [f"/robot/{a}" for a in ROBOT_ACTIONS]
        for name in services:
            rospy.wait_for_service(name, WAIT)
        stop = threading.Event()
        answers = {"busy": 0, "served": 0, "errors": []}
        guard = threading.Lock()

        def storm(seed):
            rng = random.Random(seed)
            proxies = {name: rospy.ServiceProxy(name, Trigger) for name in services}
            while not stop.is_set():
                name = rng.choice(services)
                try:
                    answer = proxies[name]()
                except (rospy.ServiceException, rospy.ROSException) as error:
                    with guard:
                        answers["errors"].append(f"{name}: {error}")
                    continue
                with guard:
                    answers["busy" if answer.message.startswith("busy:") else "served"] += 1

        self.log.clear()
        threads = [threading.Thread(target=storm, args=(i,), daemon=True) for i in range(16)]
        for thread in threads:
            thread.start()
        try:
            ok, statuses = self.log.wait_for(
                lambda s: sum(1 for x in s if not x.fault) >= 12 or any(x.fault for x in s))
        finally:
            stop.set()
            for thread in threads:
                thread.join(WAIT)
        self.assertEqual([s.fault for s in statuses if s.fault], [],
                         "a step failed during the storm")
        self.assertTrue(ok, f"the loop stopped stepping under the storm: {len(statuses)} steps")
        self.assertEqual(answers["errors"], [], "a world service failed under the storm")
        self.assertGreater(answers["busy"], 0, answers)
        self.assertGreater(answers["served"], 0, answers)
        check_epochs(self, statuses)
        for status in statuses:
            if "interrupted" in status.human_result:   # what the storm did is named
                self.assertIn("it first interrupted", status.human_result)

    def expect_a_run_from_a_reset(self, when):
        """Steps 0, 1, 2, 3 of one epoch come, each whole, the epochs in order (steps under
        way at a fault may fail first: their status says so)."""
        ok, statuses = self.log.wait_for(lambda s: fresh_run(s, 4))
        self.assertTrue(ok, f"{when}, no run from a reset; seen: "
                            f"{[(s.epoch, s.step, s.fault[:40]) for s in statuses][:20]}")
        for status in statuses:
            if not status.fault:
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
        self.expect_a_run_from_a_reset(f"after {name} restarted")

    def test_3_a_reset_while_despot_pomdp_is_down_says_so_in_one_line_and_is_retried(self):
        """Was: kill -9 of hrc_robot, the executor between the coordinator and the world's
        /robot/* services (a process that no longer exists: hrc_human calls them itself).
        What the loop promises while a process it needs is down, with hrc_human as the POMDP
        process's client: /hrc/reset answers at once, in one line, what it could and could
        not reset, and the reset is retried until it works; then a run from a reset."""
        rospy.wait_for_service("/hrc/reset", WAIT)
        reset = rospy.ServiceProxy("/hrc/reset", Trigger)
        url = link_url(self.ports["pomdp"])
        for _attempt in range(5):
            old = node_pids(self.proc, "despot_pomdp")
            self.assertTrue(old, "no despot_pomdp process in the launch")
            self.log.clear()
            for pid in old:
                os.kill(pid, signal.SIGKILL)
            time.sleep(0.3)   # for hrc_human to see its link drop (roslaunch waits 1 s)
            asked = time.monotonic()
            answer = reset()
            answered_in = time.monotonic() - asked
            if not answer.success and "is not connected" in answer.message:
                break
            # The respawned process was back before the reset, or the reset went out before
            # the link was seen to drop (it failed on the broken link): once more.
            wait_for_pids(self.proc, "despot_pomdp", unlike=old)
            self.log.wait_for(lambda s: fresh_run(s, 1))
        self.assertFalse(answer.success, answer.message)
        self.assertEqual(answer.message.splitlines(), [answer.message])
        self.assertTrue(answer.message.startswith(
            f"reset failed: not reset: robot planner: the POMDP process is not connected "
            f"({url}): it is down or (re)starting; reset: world; the human MDP is told when "
            "all are; retried in "), answer.message)
        self.assertTrue(answer.message.endswith(" until it works"), answer.message)
        self.assertLess(answered_in, 30.0, "the reset did not answer at once")
        self.assertTrue(wait_for_pids(self.proc, "despot_pomdp", unlike=old) - old,
                        "roslaunch did not restart despot_pomdp")
        self.expect_a_run_from_a_reset("after despot_pomdp restarted")

    def test_4_a_decision_under_way_when_despot_pomdp_dies_fails_its_step_visibly(self):
        """Was: kill -9 of hrc_obs, the relay between the coordinator and the POMDP process:
        the call under way failed, then a run from a reset. hrc_human is the POMDP process's
        client itself now: a decision it waits for when despot_pomdp dies fails its step at
        once (STEP FAILED in the block, the fault on /hrc/status), and the run goes on from a
        reset."""
        # (The one the test before restarted may still be starting on a loaded machine.)
        old = wait_for_pids(self.proc, "despot_pomdp")
        self.assertTrue(old, "no despot_pomdp process in the launch")
        waits = False
        for _attempt in range(5):
            # It must serve: a step it decided after it is there. Stopped while it still
            # started, it never connected, and the loop only retried its reset: no step
            # waited (seen under load, when an attempt had killed the process and the next
            # stopped the one roslaunch had just started again).
            offset = os.path.getsize(self.launch_log)
            self.assertTrue(wait_for_text(self.launch_log, offset, "robot action", 120),
                            "no step decided by the despot_pomdp running now")
            offset = os.path.getsize(self.launch_log)
            self.log.clear()
            # Stopped, the POMDP process answers nothing: the step under way waits for its
            # decision, and says so after wait_note_every (5 s); then it is killed. Stopped
            # during a reset instead, the reset fails after its timeout (10 s): then it is
            # continued, answers, and the loop goes on, to be stopped again.
            for pid in old:
                os.kill(pid, signal.SIGSTOP)
            try:
                said = wait_for_any(self.launch_log, offset, ("waits for the robot planner",
                                                              "not reset: robot planner"), 30)
            except BaseException:
                said = ""
                raise
            finally:
                landed_in_a_reset = said == "not reset: robot planner"
                for pid in old:
                    os.kill(pid, signal.SIGCONT if landed_in_a_reset else signal.SIGKILL)
            if landed_in_a_reset:
                continue
            waits = said == "waits for the robot planner"
            if waits:
                break
            old = wait_for_pids(self.proc, "despot_pomdp", unlike=old)   # restarted
        self.assertTrue(waits, "no step waited for the decision of a stopped despot_pomdp")
        self.assertTrue(wait_for_pids(self.proc, "despot_pomdp", unlike=old) - old,
                        "roslaunch did not restart despot_pomdp")
        ok, statuses = self.log.wait_for(
            lambda s: any(x.fault for x in s) and
            fresh_run(s[[x.fault != "" for x in s].index(True):], 4))
        self.assertTrue(ok, f"no failed step and then a run from a reset: "
                            f"{[(s.epoch, s.step, s.fault[:40]) for s in statuses][:20]}")
        failed = next(s for s in statuses if s.fault)
        self.assertTrue(failed.fault.startswith("the robot planner failed: no decision from "
                                                "the POMDP process"), failed.fault)
        self.assertIn("STEP FAILED       : the robot planner failed",
                      read_from(self.launch_log, offset))
        for status in statuses:
            if not status.fault:
                check_step(self, status)
        check_epochs(self, statuses)

    def test_5_killed_despot_pomdp_respawns_and_the_run_goes_on_from_a_reset(self):
        self.kill_and_expect_a_run_from_a_reset("despot_pomdp")

    def test_6_killed_despot_mdp_respawns_and_the_run_goes_on_from_a_reset(self):
        self.kill_and_expect_a_run_from_a_reset("despot_mdp")

    def test_7_killed_hrc_human_respawns_and_the_run_goes_on_from_a_reset(self):
        self.kill_and_expect_a_run_from_a_reset("hrc_human")

    def test_8_killed_world_stops_the_whole_launch_with_a_non_zero_status(self):
        """Issue #20: killing hrc_world ended the launch, but roslaunch exited 0."""
        world = node_pids(self.proc, "hrc_world")
        self.assertTrue(world, "no hrc_world in the launch")
        everything = launch_processes(self.proc.pid)
        self.assertTrue(world <= everything)
        offset = os.path.getsize(self.launch_log)
        for pid in world:
            os.kill(pid, signal.SIGKILL)
        try:
            self.proc.wait(WAIT)
        except subprocess.TimeoutExpired:
            self.fail("hrc.launch still runs after its world was killed")
        output = read_from(self.launch_log, offset)
        self.assertEqual(self.proc.returncode, -signal.SIGKILL, output[-3000:])   # 137 in a shell
        self.assertEqual([line for line in output.splitlines() if "died" in line], [
            "hrc_world died (killed by SIGKILL): it is required, so the launch stops with it; "
            "roslaunch exits with status 137 (Killed)"])
        self.assertNotIn("REQUIRED process", output)
        self.assertNotIn("Traceback", output)
        self.assertEqual(left_alive(everything), set(), "processes left after the launch stopped")


def launch_processes(pid):
    """Every process under ``pid`` now (its children, theirs, ...)."""
    found, todo = set(), [pid]
    while todo:
        for child in children_of(todo.pop()):
            if child not in found:
                found.add(child)
                todo.append(child)
    return found


def left_alive(pids, timeout=30.0):
    """Those of ``pids`` still running (not ended, not a zombie) after at most ``timeout`` s."""
    deadline = time.monotonic() + timeout
    alive = set(pids)
    while True:
        alive = {pid for pid in alive if os.path.exists(f"/proc/{pid}") and
                 "zombie" not in open(f"/proc/{pid}/status").read().lower()}
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.2)


def read_from(path, offset=0):
    with open(path, "rb") as f:
        f.seek(offset)
        return f.read().decode("utf-8", "replace")


def wait_for_text(path, offset, text, timeout):
    """Whether ``text`` appears in the file at ``path`` after ``offset`` within ``timeout`` s."""
    return wait_for_any(path, offset, (text,), timeout) == text


def wait_for_any(path, offset, texts, timeout):
    """The first of ``texts`` to appear in the file at ``path`` after ``offset`` within
    ``timeout`` s (the one earliest in the file), or "" if none does."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        written = read_from(path, offset)
        found = [(written.index(text), text) for text in texts if text in written]
        if found:
            return min(found)[1]
        time.sleep(0.2)
    return ""


class TestWorldLaunchEnds(unittest.TestCase):
    """world.launch with a master of its own (roslaunch starts it, as a user's first launch
    does): Ctrl-C ends it with status 0; a killed world ends it non-zero, its master too."""

    def start(self):
        port = pick_ports()["master"]
        log_dir = os.environ.get("ROS_LOG_DIR") or "/tmp"
        log = open(os.path.join(log_dir, f"test_world_launch_{os.getpid()}_{port}.log"), "wb")
        with log:
            proc = subprocess.Popen(
                ["roslaunch", "-p", str(port), "ros_hrc", "world.launch", "viz:=false"],
                stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                start_new_session=True,
                env=dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}"))
        self.addCleanup(stop_stack, proc)
        deadline = time.monotonic() + WAIT
        while "services up" not in read_from(log.name) and time.monotonic() < deadline:
            self.assertIsNone(proc.poll(), read_from(log.name)[-3000:])
            time.sleep(0.2)
        self.assertIn("services up", read_from(log.name), "the world did not come up")
        everything = launch_processes(proc.pid)
        masters = {pid for pid in everything if "rosmaster" in " ".join(
            open(f"/proc/{pid}/cmdline").read().split("\0")[:2])}
        self.assertEqual(len(masters), 1, "roslaunch started no master of its own")
        return proc, log.name, everything

    def test_ctrl_c_still_ends_the_launch_with_status_0(self):
        proc, log, everything = self.start()
        os.kill(proc.pid, signal.SIGINT)
        proc.wait(WAIT)
        output = read_from(log)
        self.assertEqual(proc.returncode, 0, output[-3000:])
        self.assertNotIn("died", output)
        self.assertEqual(left_alive(everything), set())

    def test_a_killed_world_ends_the_launch_and_its_master_non_zero(self):
        proc, log, everything = self.start()
        for pid in node_pids(proc, "hrc_world"):
            os.kill(pid, signal.SIGKILL)
        proc.wait(WAIT)
        output = read_from(log)
        self.assertEqual(proc.returncode, -signal.SIGKILL, output[-3000:])
        self.assertEqual(len([line for line in output.splitlines()
                              if line.startswith("hrc_world died (killed by SIGKILL)")]), 1)
        self.assertNotIn("REQUIRED process", output)
        self.assertEqual(left_alive(everything), set())


if __name__ == "__main__":
    # Both classes: the attacked stack's, then world.launch's own ends.
    rostest.rosrun("ros_hrc", "hrc_loop_faults", "__main__", sys.argv)
