#!/usr/bin/env python3
"""The whole loop, as a user runs it: `roslaunch ros_hrc hrc.launch`, headless.

The test starts hrc.launch itself (against rostest's master) so that it holds the launch's
standard input and can press Enter. It checks an auto-mode run of 20+ steps step by step,
a reset through /hrc/reset, a reset through Enter, and a manual-mode episode whose human
states follow the ones injected through /hrc/set_human_state; that two runs with the same
seed print the same steps; and that when a solver process is killed, roslaunch restarts it,
the links reconnect and the run goes on from a reset.
"""
import itertools
import os
import signal
import subprocess
import tempfile
import time
import sys
import threading
import unittest

import rospy
import rostest
from std_srvs.srv import Trigger

from ros_hrc.experiment.stack import stop_launched
from ros_hrc.msg import Status, WorldState
from ros_hrc.srv import SetHumanState

HUMAN_ACTIONS = {"graspAttempt", "lookAround", "idle", "walkAway", "warnRobot"}
HUMAN_STATES = ["task_assigned", "success", "failed_to_grasp", "no_attention", "evaluating",
                "tired", "recovery", "warningTheRobot"]
ROBOT_ACTIONS = {"rIdle", "rPoint_obj", "rGrasp_obj", "rStop_all"}
ROBOT_STATES = {f"S{i}" for i in range(7)}
LEGAL_BITS = {0, 1, 2, 3, 7, 10, 11, 16, 17, 18, 19, 32, 33, 34, 35}
# Generous safety nets, not assertions about speed.
WAIT = 180.0
_LAUNCHES = itertools.count(1)


class StatusLog:
    """Collects /hrc/status and /hrc/world_state messages."""

    def __init__(self):
        self.cond = threading.Condition()
        self.statuses = []
        self.world = None
        rospy.Subscriber("/hrc/status", Status, self._on_status, queue_size=1000)
        rospy.Subscriber("/hrc/world_state", WorldState, self._on_world, queue_size=10)

    def _on_status(self, msg):
        with self.cond:
            self.statuses.append(msg)
            self.cond.notify_all()

    def _on_world(self, msg):
        with self.cond:
            self.world = msg
            self.cond.notify_all()

    def wait_for(self, predicate, timeout=WAIT):
        with self.cond:
            ok = self.cond.wait_for(lambda: predicate(self.statuses), timeout)
            return ok, list(self.statuses)

    def clear(self):
        with self.cond:
            self.statuses.clear()


def start_stack(*args):
    """roslaunch hrc.launch headless with the given arguments, stdin ours."""
    cmd = ["roslaunch", "ros_hrc", "hrc.launch", "gui:=false", "real_time_factor:=0",
           "step_delay:=0", "time_per_step:=0.05", "max_trials:=200", "seed:=3"] + list(args)
    # rostest captures this process's sys.stdout in memory: the launch writes to a log file.
    log_dir = os.environ.get("ROS_LOG_DIR") or tempfile.gettempdir()
    os.makedirs(log_dir, exist_ok=True)
    log = open(os.path.join(log_dir, f"test_hrc_launch_{time.strftime('%H%M%S')}_{os.getpid()}"
                                     f"_{next(_LAUNCHES)}.log"), "wb")
    print(f"hrc.launch output: {log.name}", file=sys.stderr, flush=True)
    with log:
        return subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=log, stderr=subprocess.STDOUT,
                                env=dict(os.environ), start_new_session=True)


def solver_pids(proc, name):
    """PIDs of the solver process ``name`` (despot_mdp or despot_pomdp) of this launch."""
    out = subprocess.run(["pgrep", "-P", str(proc.pid), "-f", f"{name} --model"],
                         capture_output=True, text=True).stdout
    return {int(pid) for pid in out.split()}


def wait_for_pids(proc, name, unlike=frozenset()):
    """The solver's PIDs once there is one that is not in ``unlike``."""
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline:
        pids = solver_pids(proc, name)
        if pids - set(unlike):
            return pids
        time.sleep(0.2)
    return set()


def step_record(status):
    """What a user compares between two runs: everything but timing."""
    return (status.step, status.human_action, status.human_state, status.human_observation,
            status.observation_bits, status.robot_state, status.robot_action,
            tuple(round(p, 9) for p in status.belief))


stop_stack = stop_launched


class TestWholeLoop(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node("test_hrc", anonymous=True)
        cls.log = StatusLog()

    def tearDown(self):
        if getattr(self, "proc", None) is not None:
            stop_stack(self.proc)
            self.proc = None
            rospy.sleep(2.0)  # let the ports go before the next stack binds them

    def check_step(self, status):
        """Every field of one status is consistent with the others."""
        where = f"step {status.step}"
        self.assertIn(status.human_action, HUMAN_ACTIONS, where)
        self.assertEqual(status.human_state, HUMAN_STATES[status.human_state_index], where)
        self.assertIn(status.robot_state, ROBOT_STATES, where)
        self.assertIn(status.robot_action, ROBOT_ACTIONS, where)
        self.assertIn(status.observation_bits, LEGAL_BITS, where)
        self.assertEqual(status.robot_observation, f"O{status.observation_bits}", where)
        self.assertEqual(len(status.belief), 7, where)
        self.assertEqual(list(status.belief_states), sorted(ROBOT_STATES), where)
        self.assertAlmostEqual(sum(status.belief), 1.0, places=6, msg=where)
        self.assertTrue(all(p >= 0 for p in status.belief), where)
        # The world changed as the human's action says.
        bits = status.observation_bits
        if status.human_action == "warnRobot":
            self.assertTrue(bits & 16, f"{where}: warned, but no warning observed ({bits})")
        if status.human_action == "walkAway":
            self.assertFalse(bits & 2, f"{where}: walked away, yet the object is in range")
        if status.human_action == "graspAttempt" and status.human_state == "success":
            self.assertTrue(bits & 8 or "robot" in status.human_observation,
                            f"{where}: a successful grasp, but the human holds nothing")
        if status.human_state == "success" and status.human_action == "graspAttempt":
            self.assertNotIn(status.robot_state, {"S2", "S3"}, where)

    def test_auto_run_resets_and_manual_episode(self):
        self.proc = start_stack("mode:=auto", "on_episode_end:=continue")
        ok, statuses = self.log.wait_for(lambda s: len(s) >= 22)
        self.assertTrue(ok, f"only {len(statuses)} steps came")
        steps = [s.step for s in statuses[:22]]
        self.assertEqual(steps, list(range(22)), "steps are numbered 0, 1, 2, ... in order")
        for status in statuses:
            self.check_step(status)
        self.assertIsNotNone(self.log.world, "no /hrc/world_state")

        # Reset through the service: the next steps start again from 0.
        reset = rospy.ServiceProxy("/hrc/reset", Trigger)
        reset.wait_for_service(WAIT)
        self.log.clear()
        answer = reset()
        self.assertTrue(answer.success, answer.message)
        ok, statuses = self.log.wait_for(lambda s: any(x.step == 0 for x in s)
                                         and s[-1].step >= 2)
        self.assertTrue(ok, "no new episode after /hrc/reset")
        after = [s.step for s in statuses]
        first = after.index(0)
        self.assertEqual(after[first:first + 3], [0, 1, 2])
        self.assertEqual(statuses[first].human_action != "", True)

        # Reset through Enter on the launch's terminal.
        self.log.clear()
        self.proc.stdin.write(b"\n")
        self.proc.stdin.flush()
        ok, statuses = self.log.wait_for(lambda s: any(x.step == 0 for x in s)
                                         and s[-1].step >= 2)
        self.assertTrue(ok, "no new episode after Enter")
        stop_stack(self.proc)
        rospy.sleep(3.0)

        # Manual mode: the human's states follow the injected ones.
        self.log.clear()
        self.proc = start_stack("mode:=manual", "on_episode_end:=continue")
        set_state = rospy.ServiceProxy("/hrc/set_human_state", SetHumanState)
        set_state.wait_for_service(WAIT)
        wanted = [4, 2, 2, 5, 6, 7]
        for i, state in enumerate(wanted):
            answer = None
            for _ in range(600):   # the MDP process may still be connecting
                answer = set_state(state)
                if answer.success:
                    break
                rospy.sleep(0.2)
            self.assertTrue(answer.success, answer.message)
            ok, statuses = self.log.wait_for(lambda s: len(s) > i)
            self.assertTrue(ok, f"no step after injecting state {state}")
            self.assertEqual(statuses[i].step, i)
            self.assertEqual(statuses[i].human_state, HUMAN_STATES[state])
            self.assertEqual(statuses[i].mode, "manual")
            self.check_step(statuses[i])
        # A state that does not exist is refused with a reason, and nothing steps.
        answer = set_state(42)
        self.assertFalse(answer.success)
        self.assertIn("0 to 7", answer.message)


    def run_steps(self, count, *args):
        """Start the stack, take its first ``count`` steps, stop it."""
        self.log.clear()
        self.proc = start_stack(*args)
        ok, statuses = self.log.wait_for(lambda s: len(s) >= count)
        self.assertTrue(ok, f"only {len(statuses)} steps came")
        stop_stack(self.proc)
        self.proc = None
        rospy.sleep(3.0)
        return [step_record(s) for s in statuses[:count]]

    def test_same_seed_same_steps(self):
        # DESPOT is bounded by trials, not time, and the world's clock stands still between
        # actions, so nothing but the seed decides the run.
        same = ("seed:=11", "time_per_step:=30", "max_trials:=100", "on_episode_end:=continue")
        first = self.run_steps(12, *same)
        second = self.run_steps(12, *same)
        for a, b in zip(first, second):
            self.assertEqual(a, b, f"step {a[0]} differs between two runs with one seed")
        self.assertGreater(len({r[1] for r in first}), 1, "the human did just one thing")

    def kill_and_expect_a_fresh_start(self, name):
        """Kill solver ``name``: it comes back and the loop steps again from a reset."""
        ok, statuses = self.log.wait_for(lambda s: len(s) >= 3)
        self.assertTrue(ok, "the loop is not stepping")
        old = solver_pids(self.proc, name)
        self.assertTrue(old, f"no {name} process in the launch")
        self.log.clear()
        for pid in old:
            os.kill(pid, signal.SIGKILL)
        new = wait_for_pids(self.proc, name, unlike=old)
        self.assertTrue(new - old, f"roslaunch did not restart {name}")
        # Steps before the reset may still come in; after it, steps run 0, 1, 2, 3 again.
        def fresh_run(statuses):
            steps = [x.step for x in statuses]
            return any(steps[i:i + 4] == [0, 1, 2, 3] for i in range(len(steps)))

        ok, statuses = self.log.wait_for(fresh_run)
        self.assertTrue(ok, f"after {name} restarted, no run from a reset; steps seen: "
                            f"{[x.step for x in statuses][:20]}")
        for status in statuses:
            self.check_step(status)

    def test_killed_solver_processes_restart_and_the_run_goes_on_from_a_reset(self):
        self.log.clear()
        self.proc = start_stack("mode:=auto", "on_episode_end:=continue")
        self.kill_and_expect_a_fresh_start("despot_pomdp")
        self.kill_and_expect_a_fresh_start("despot_mdp")


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "hrc_loop", TestWholeLoop, sys.argv)
