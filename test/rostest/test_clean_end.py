#!/usr/bin/env python3
"""The whole stack ends cleanly, as a user ends it: `roslaunch ros_hrc hrc.launch gui:=true`
under a virtual display of the test's own, on ports of its own, then

* Esc in PyBullet's window while a step is under way,
* Esc in the window after the episode ended (max_steps:=1, on_episode_end:=wait: the stack
  waits for Enter),
* SIGINT to roslaunch while a step is under way, as Ctrl-C in its terminal sends it (to
  roslaunch's process group only: roslaunch runs each node in a session of its own),

and each time roslaunch must exit by itself with status 0, leave no process of the launch
behind, and print no ERROR line, no traceback, no failed step, and after the stop no reset
block, no retried reset and no "the MDP process left" (the processes ending together is the
run's end, not a fault to recover from). Esc also says once that the window was closed."""
import os
import signal
import subprocess
import sys
import tempfile
import time
import unittest
from pathlib import Path

import rostest

from ros_hrc.experiment.stack import pick_ports
from ros_hrc.process_tree import alive, children_of

START_WAIT = 300.0      # a GUI world under a loaded software renderer: generous, not asserted
END_WAIT = 90.0
PORT_TRIES = 3


def descendants(pid):
    """Every process under ``pid``, depth first."""
    found = []
    for child in children_of(pid):
        found.append(child)
        found.extend(descendants(child))
    return found


class CleanEnd(unittest.TestCase):

    def setUp(self):
        read_end, write_end = os.pipe()
        self.xvfb = subprocess.Popen(
            ["Xvfb", "-displayfd", str(write_end), "-screen", "0", "1280x800x24", "-noreset",
             "-nolisten", "tcp"], pass_fds=(write_end,), stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL)
        os.close(write_end)
        with os.fdopen(read_end) as numbers:
            display = numbers.readline().strip()
        self.assertTrue(display, "Xvfb did not start")
        self.display = f":{display}"
        self.env = dict(os.environ, DISPLAY=self.display)
        self.launch = None
        self.pids = set()

    def tearDown(self):
        if self.launch is not None and self.launch.poll() is None:
            os.killpg(self.launch.pid, signal.SIGKILL)
            self.launch.wait(30)
        for pid in self.pids:   # a process the launch left behind (the test failed already)
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
        self.xvfb.terminate()
        self.xvfb.wait(10)

    def xdotool(self, *args):
        return subprocess.run(["xdotool", *args], env=self.env, capture_output=True, text=True,
                              timeout=30)

    def start(self, *args, until):
        """Start the stack on free ports and wait for ``until`` in its output; on fresh ports
        again when another process took one of them first (picked free, they may be taken
        before the stack binds them)."""
        for _ in range(PORT_TRIES):
            self.launch_on_fresh_ports(*args)
            if self.wait_for(until):
                return
            self.assertIn("already in use", self.output(),
                          f"the launch ended before {until!r}:\n" + self.output()[-3000:])
        self.fail(f"no free ports in {PORT_TRIES} tries")

    def launch_on_fresh_ports(self, *args):
        self.ports = pick_ports()
        self.env["ROS_MASTER_URI"] = f"http://127.0.0.1:{self.ports['master']}"
        self.log = Path(tempfile.NamedTemporaryFile(
            prefix="test_clean_end_", suffix=".log", dir=os.environ.get("ROS_LOG_DIR"),
            delete=False).name)
        print(f"hrc.launch output: {self.log}", file=sys.stderr, flush=True)
        with self.log.open("wb") as out:
            self.launch = subprocess.Popen(
                ["roslaunch", "-p", str(self.ports["master"]), "ros_hrc", "hrc.launch",
                 "gui:=true", "viz:=false", "read_stdin:=false", "step_delay:=0",
                 f"pomdp_port:={self.ports['pomdp']}",
                 f"human_port:={self.ports['human']}", *args],
                env=self.env, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                start_new_session=True,
                # SIGINT as a terminal's processes have it, whoever started this test.
                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))

    def output(self):
        return self.log.read_text(errors="replace")

    def wait_for(self, text):
        """True once ``text`` is in the launch's output; False if the launch ended first."""
        deadline = time.monotonic() + START_WAIT
        while text not in self.output():
            if self.launch.poll() is not None:
                return text in self.output()
            self.assertLess(time.monotonic(), deadline, f"no {text!r} in the launch's output")
            time.sleep(0.2)
        return True

    def press_escape(self):
        windows = self.xdotool("search", "--name", "^ros_hrc").stdout.split()
        self.assertTrue(windows, "no window titled ros_hrc")
        self.xdotool("windowfocus", "--sync", windows[0])
        self.xdotool("key", "--window", windows[0], "Escape")

    def end_and_check(self, stop, window_closed):
        """Stop the launch with ``stop()`` and check how it ended."""
        self.pids = set(descendants(self.launch.pid))
        self.assertTrue(self.pids, "the launch has no processes")
        stopped_at = len(self.output())
        stop()
        try:
            self.launch.wait(END_WAIT)
        except subprocess.TimeoutExpired:
            self.fail(f"the launch still runs {END_WAIT:.0f} s after it was stopped:\n"
                      + self.output()[-3000:])
        text = self.output()
        after = text[stopped_at:]
        self.assertEqual(self.launch.returncode, 0, text[-3000:])
        left = [pid for pid in self.pids if alive(pid)]
        self.assertEqual(left, [], "processes of the launch are still there")
        for bad in ("ERROR", "Traceback", "STEP FAILED", "REQUIRED process", "reset failed"):
            self.assertNotIn(bad, text, f"{bad!r} in the launch's output:\n{text[-4000:]}")
        for bad in ("RESET", "retrying", "the MDP process left", "died"):
            self.assertNotIn(bad, after, f"{bad!r} after the stop:\n{after}")
        closed = [line for line in after.splitlines() if "window was closed" in line]
        self.assertEqual(len(closed), 1 if window_closed else 0, after)

    def test_escape_while_a_step_is_under_way(self):
        self.start(until="------ step 0 ------")   # step 1 is under way at once (step_delay 0)
        self.end_and_check(self.press_escape, window_closed=True)

    def test_escape_after_the_episode_ended(self):
        self.start("max_steps:=1", "on_episode_end:=wait", until="episode 1 over")
        self.end_and_check(self.press_escape, window_closed=True)

    def test_ctrl_c_while_a_step_is_under_way(self):
        self.start(until="------ step 0 ------")
        self.end_and_check(lambda: os.killpg(self.launch.pid, signal.SIGINT),
                           window_closed=False)


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "clean_end", CleanEnd, sys.argv)
