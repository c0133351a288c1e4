"""Whole lines on a shared terminal (ros_hrc.command_line.WholeLines): a line is passed on as
soon as it ends, also when terminal escape sequences follow its newline, as rospy writes a
coloured warning on a terminal (colour, text, newline, colour reset). A warning once waited in
the writer until the next line, which for a node that logs nothing more was the launch's end.
The child process logs through rospy's own handler into a real terminal (a pty)."""
import io
import os
import select
import subprocess
import sys

from ros_hrc.command_line import WholeLines


def test_a_line_ended_by_a_newline_then_a_colour_reset_is_passed_on_at_once():
    out = io.StringIO()
    lines = WholeLines(out)
    lines.write("\x1b[33m[WARN] step 1 waits\n\x1b[0m")
    assert out.getvalue() == "\x1b[33m[WARN] step 1 waits\n\x1b[0m"
    lines.write("part of a line")
    lines.write("\x1b[0m")     # an escape sequence inside a line does not end it
    assert out.getvalue() == "\x1b[33m[WARN] step 1 waits\n\x1b[0m"
    lines.write(" and its end\n")
    assert out.getvalue().endswith("part of a line\x1b[0m and its end\n")


#: A node's start, as ours do: whole lines first, then rospy's stream handler (which rospy
#: makes as init_node configures logging, on the sys.stderr of then); one warning, then the
#: process says so on stdout and waits for its stdin to close, as a node goes on running.
CHILD = """
import logging, sys
from ros_hrc.command_line import print_whole_lines
print_whole_lines()
from rosgraph.roslogging import RosStreamHandler
log = logging.getLogger("hrc_whole_lines_test")
log.addHandler(RosStreamHandler(colorize=True))
log.warning("step 1 waits for the human's action: 5 s so far")
sys.__stdout__.write("logged\\n"); sys.__stdout__.flush()
sys.stdin.read()
"""


def test_a_rospy_warning_reaches_the_terminal_while_the_node_runs():
    controller, terminal = os.openpty()
    child = subprocess.Popen([sys.executable, "-c", CHILD], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, stderr=terminal, text=True)
    os.close(terminal)
    try:
        assert child.stdout.readline() == "logged\n"
        # The warning was written before "logged": it is in the terminal now, or never was.
        shown = b""
        while select.select([controller], [], [], 0)[0]:
            shown += os.read(controller, 4096)
        assert b"step 1 waits for the human's action: 5 s so far" in shown, shown
        assert shown.startswith(b"\x1b[33m[WARN]")     # rospy saw a terminal: coloured
    finally:
        child.stdin.close()
        child.wait(timeout=60)
        os.close(controller)
