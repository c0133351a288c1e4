"""What the launched loop tests share: starting hrc.launch as a user does, watching
/hrc/status, finding a launch's processes, and checking that a step's fields agree."""
import itertools
import math
import os
import subprocess
import sys
import tempfile
import threading
import time

import rospy

from ros_hrc.experiment.stack import pick_ports, stop_launched
from ros_hrc.tasks import seed as task
from ros_hrc.nodes.guard import children_of
from ros_hrc.process_tree import parent_of
from ros_hrc.msg import Status, TaskStatus, WorldState

HUMAN_STATES = list(task.HUMAN_STATES)
HUMAN_ACTIONS = set(task.HUMAN_ACTION_SERVICES)
ROBOT_ACTIONS = set(task.ROBOT_ACTION_SERVICES)
ROBOT_STATES = set(task.ROBOT_STATES)
LEGAL_BITS = set(task.LEGAL_BITS)
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


class TaskLog:
    """Collects /hrc/task_status (one message per task of a sequence)."""

    def __init__(self):
        self.cond = threading.Condition()
        self.items = []
        rospy.Subscriber("/hrc/task_status", TaskStatus, self._on, queue_size=100)

    def _on(self, msg):
        with self.cond:
            self.items.append(msg)
            self.cond.notify_all()

    def wait_for(self, count, timeout=WAIT):
        """The messages so far, once there are ``count`` (or ``timeout`` s have passed)."""
        with self.cond:
            self.cond.wait_for(lambda: len(self.items) >= count, timeout)
            return list(self.items)


def start_stack(*args, name="hrc", cwd=None):
    """roslaunch hrc.launch headless with the given arguments, its stdin ours (to press
    Enter), its output in a log file (rostest captures this process's stdout); run in the
    directory ``cwd`` (this process's by default), as a user runs it from there."""
    cmd = ["roslaunch", "ros_hrc", "hrc.launch", "gui:=false", "real_time_factor:=0",
           "step_delay:=0", "time_per_step:=0.05", "max_trials:=200", "seed:=3"] + list(args)
    # Without RViz's publishers unless the test asks for them (viz.test does): the loop's tests
    # do not read them, and they are three more processes to start (about 1 s of CPU).
    if not any(word.startswith("viz:=") for word in args):
        cmd.append("viz:=false")
    # The links' ports: free ones unless the test names them, never hrc.launch's own 7070
    # and 9090, so that launched tests (and anyone's stack) can run beside each other.
    if not any(word.startswith("pomdp_port:=") or word.startswith("human_port:=")
               for word in args):
        ports = pick_ports()
        cmd += [f"pomdp_port:={ports['pomdp']}", f"human_port:={ports['human']}"]
    log_dir = os.environ.get("ROS_LOG_DIR") or tempfile.gettempdir()
    os.makedirs(log_dir, exist_ok=True)
    log = open(os.path.join(log_dir, f"test_{name}_launch_{time.strftime('%H%M%S')}_"
                                     f"{os.getpid()}_{next(_LAUNCHES)}.log"), "wb")
    print(f"hrc.launch output: {log.name}", file=sys.stderr, flush=True)
    with log:
        return subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=log, stderr=subprocess.STDOUT,
                                env=dict(os.environ), start_new_session=True, cwd=cwd)


stop_stack = stop_launched


def node_pids(proc, name):
    """PIDs of the launch's process ``name`` (a node or a solver: roslaunch gives each
    ``__name:=<name>``): a child of the launch's roslaunch, or a grandchild (hrc_world runs
    under its guard, hrc_guard)."""
    out = subprocess.run(["pgrep", "-f", f"__name:={name}"], capture_output=True,
                         text=True).stdout
    parents = {proc.pid} | set(children_of(proc.pid))
    return {int(pid) for pid in out.split() if parent_of(int(pid)) in parents}


def wait_for_pids(proc, name, unlike=frozenset()):
    """The process's PIDs once there is one that is not in ``unlike``."""
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline:
        pids = node_pids(proc, name)
        if pids - set(unlike):
            return pids
        time.sleep(0.2)
    return set()


def fresh_run(statuses, length=4):
    """True when the statuses hold steps 0, 1, ... length-1 of one epoch, none failed."""
    for i in range(len(statuses) - length + 1):
        run = statuses[i:i + length]
        if [s.step for s in run] == list(range(length)) and len({s.epoch for s in run}) == 1 \
                and not any(s.fault for s in run):
            return True
    return False


def step_record(status):
    """What a user compares between two runs: everything but timing and epochs."""
    return (status.episode, status.step, status.human_action, status.human_state,
            status.human_observation, status.observation_bits, status.robot_state,
            status.robot_action, tuple(round(p, 9) for p in status.belief))


def check_step(case, status):
    """Every field of one (successful) step's status agrees with the others."""
    where = f"epoch {status.epoch} step {status.step}"
    case.assertEqual(status.fault, "", where)
    case.assertIn(status.human_action, HUMAN_ACTIONS, where)
    case.assertEqual(status.human_state, task.HUMAN_STATES[status.human_state_index], where)
    case.assertIn(status.robot_state, ROBOT_STATES, where)
    case.assertIn(status.robot_action, ROBOT_ACTIONS, where)
    case.assertIn(status.observation_bits, LEGAL_BITS, where)
    case.assertEqual(status.robot_observation, f"O{status.observation_bits}", where)
    case.assertEqual(len(status.belief), 7, where)
    case.assertEqual(list(status.belief_states), sorted(ROBOT_STATES), where)
    case.assertAlmostEqual(sum(status.belief), 1.0, places=6, msg=where)
    case.assertTrue(all(p >= 0 for p in status.belief), where)
    # Why the robot acted: a planner's value of each action it compared, its choice the best
    # (DESPOT's ties within 1e-6 relative aside); a baseline robot sends none.
    case.assertEqual(len(status.action_names), len(status.action_values), where)
    if status.action_values:
        values = dict(zip(status.action_names, status.action_values))
        case.assertLessEqual(set(values), ROBOT_ACTIONS, where)
        case.assertTrue(all(math.isfinite(v) for v in values.values()), where)
        best = max(values.values())
        case.assertGreaterEqual(values.get(status.robot_action, -math.inf),
                                best - 1e-6 * max(1.0, abs(best)), where)
    # A robot model of human types sends its belief over them; a robot of no types none.
    case.assertEqual(len(status.type_names), len(status.type_belief), where)
    if status.type_belief:
        case.assertAlmostEqual(sum(status.type_belief), 1.0, places=6, msg=where)
    bits = status.observation_bits
    if status.human_action == "warnRobot":
        case.assertTrue(bits & task.WARNING, f"{where}: warned, but no warning observed ({bits})")
    if status.human_action == "walkAway":
        case.assertFalse(bits & task.IN_RANGE, f"{where}: walked away, yet the object is in range")
    if status.human_action == "graspAttempt" and status.human_state == "success":
        case.assertTrue(bits & task.HAS_OBJECT or "robot" in status.human_observation,
                        f"{where}: a successful grasp, but the human holds nothing")
        case.assertNotIn(status.robot_state, {"S2", "S3"}, where)


def check_epochs(case, statuses):
    """Within an epoch the steps run 0, 1, 2 ... with no gap, each in one episode."""
    by_epoch = {}
    for s in statuses:
        by_epoch.setdefault(s.epoch, []).append(s)
    for epoch, steps in by_epoch.items():
        numbers = [s.step for s in steps]
        case.assertEqual(numbers, list(range(numbers[0], numbers[0] + len(numbers))),
                         f"epoch {epoch}: steps {numbers}")
        case.assertEqual(len({s.episode for s in steps}), 1, f"epoch {epoch}: one episode")
