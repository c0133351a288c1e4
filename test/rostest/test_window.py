#!/usr/bin/env python3
"""Closing PyBullet's window ends the launch, as a user closes it: under Xvfb (the set-up
installs it), `roslaunch ros_hrc world.launch gui:=true`, Esc in the window titled
"ros_hrc ...", and the launch must end by itself, saying why in one line: no FATAL or ERROR
line, no roslaunch "REQUIRED process has died" banner (closing the window is a user's normal
end: roslaunch stops as on Ctrl-C and exits 0)."""
import os
import subprocess
import sys
import tempfile
import time
import unittest
from pathlib import Path

import rostest

WINDOW_WAIT = 120.0     # building the scene under a loaded software renderer
END_WAIT = 60.0


def free_display() -> int:
    for number in range(90, 200):
        if not Path(f"/tmp/.X11-unix/X{number}").exists() and \
                not Path(f"/tmp/.X{number}-lock").exists():
            return number
    raise RuntimeError("no free X display number")


class TestWindowClose(unittest.TestCase):

    def setUp(self):
        self.display = f":{free_display()}"
        self.xvfb = subprocess.Popen(["Xvfb", self.display, "-screen", "0", "1280x800x24"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.env = dict(os.environ, DISPLAY=self.display)
        self.launch = None

    def tearDown(self):
        if self.launch is not None and self.launch.poll() is None:
            self.launch.terminate()
            self.launch.wait(30)
        self.xvfb.terminate()
        self.xvfb.wait(10)

    def xdotool(self, *args, timeout=10.0):
        return subprocess.run(["xdotool", *args], env=self.env, capture_output=True, text=True,
                              timeout=timeout)

    def test_escape_in_the_window_ends_the_launch_with_one_line(self):
        log = tempfile.NamedTemporaryFile(prefix="test_window_launch_", suffix=".log",
                                          dir=os.environ.get("ROS_LOG_DIR"), delete=False)
        self.launch = subprocess.Popen(
            ["roslaunch", "ros_hrc", "world.launch", "gui:=true", "viz:=false"],
            env=self.env, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
            start_new_session=True)
        deadline = time.monotonic() + WINDOW_WAIT
        window = ""
        while not window and time.monotonic() < deadline:
            self.assertIsNone(self.launch.poll(), "the launch ended before its window opened")
            window = self.xdotool("search", "--name", "ros_hrc").stdout.split()
            window = window[0] if window else ""
            time.sleep(1.0)
        self.assertTrue(window, f"no window titled ros_hrc within {WINDOW_WAIT:.0f} s")
        time.sleep(3.0)   # the scene built, the world stepping
        self.xdotool("windowfocus", "--sync", window)
        self.xdotool("key", "--window", window, "Escape")
        try:
            self.launch.wait(END_WAIT)
        except subprocess.TimeoutExpired:
            self.fail(f"the launch still runs {END_WAIT:.0f} s after the window was closed")
        text = Path(log.name).read_text(errors="replace")
        closed = [line for line in text.splitlines() if "window was closed" in line]
        self.assertEqual(len(closed), 1, closed)
        self.assertIn("hrc_world: the PyBullet window was closed: the launch stops", closed[0])
        self.assertNotIn("REQUIRED process", text)
        for level in ("[FATAL]", "[ERROR]", "Traceback"):
            self.assertNotIn(level, text)
        self.assertEqual(self.launch.returncode, 0, text[-2000:])


if __name__ == "__main__":
    rostest.rosrun("ros_hrc", "window_close", TestWindowClose, sys.argv)
