"""hrc_human's terminal (roslaunch's): Enter resets everything; in manual mode a typed state is
the human's next state, passed on to the MDP (without a display the MDP's prompt shows here,
so what is typed at it must not be taken for Enter); the end of the input is said in one line.

The reading function on a fake node, then the real stack: hrc.launch mode:=manual without a
display, a typed 5 and an Enter through roslaunch's standard input."""
import io
import os
import subprocess
import time
from types import SimpleNamespace

import pytest

from ros_hrc.experiment.stack import stop_launched
from ros_hrc.link.transport import free_port
from ros_hrc.nodes.human_node import HumanNode, input_ended_line, typed_line


@pytest.mark.parametrize("line, mode, expected", [
    ("\n", "auto", ("reset", None)),
    ("5\n", "auto", ("reset", None)),          # auto mode: every line is Enter, as before
    ("\n", "manual", ("reset", None)),
    ("  \n", "manual", ("reset", None)),
    ("5\n", "manual", ("state", 5)),
    (" 0 \n", "manual", ("state", 0)),
    ("-1\n", "manual", ("state", None)),       # negative: the model chooses (as the service)
    ("x\n", "manual", ("state", None)),        # not a number: autogen, as the MDP's prompt says
    ("9\n", "manual", ("state", 9)),           # out of range: the MDP answers why
])
def test_what_a_typed_line_asks_for(line, mode, expected):
    assert typed_line(line, mode) == expected


def test_the_end_of_the_input_is_said():
    assert input_ended_line("auto", True) == (
        "hrc_human: input ended (Ctrl-D): Enter here no longer resets; "
        "`rosservice call /hrc/reset` still does")
    assert input_ended_line("manual", False) == (
        "hrc_human: input ended (standard input closed): Enter here no longer resets; "
        "`rosservice call /hrc/reset` still does, and `rosservice call /hrc/set_human_state N` "
        "gives the human's next state (typed states here no longer reach the MDP)")


def fake_node(mode, answers):
    record = []
    node = SimpleNamespace(
        config=SimpleNamespace(mode=mode),
        runner=SimpleNamespace(request_reset=lambda reason: record.append(("reset", reason))),
        send_next_state=lambda state: (record.append(("state", state)) or answers.pop(0)))
    return node, record


def test_manual_mode_passes_typed_states_on_and_resets_on_enter_alone(capsys):
    node, record = fake_node("manual", [(True, "next state: tired"),
                                        (False, "state must be an integer from 0 to 7, not 9"),
                                        (True, "next state: autogen")])
    HumanNode.read_enter(node, io.StringIO("5\n9\n\nx\n"))
    assert record == [("state", 5), ("state", 9), ("reset", "Enter pressed"), ("state", None)]
    assert capsys.readouterr().out.splitlines() == [
        "hrc_human: typed '5': next state: tired",
        "hrc_human: typed '9' did not reach the MDP: state must be an integer from 0 to 7, "
        "not 9 (Enter alone resets everything)",
        "hrc_human: typed 'x': next state: autogen",
        input_ended_line("manual", False)]


def test_auto_mode_resets_on_every_line(capsys):
    node, record = fake_node("auto", [])
    HumanNode.read_enter(node, io.StringIO("\n5\n"))
    assert record == [("reset", "Enter pressed")] * 2
    assert capsys.readouterr().out.splitlines() == [input_ended_line("auto", False)]


# -- the real stack ---------------------------------------------------------------------------

def wait_for(path, text, timeout=120.0, count=1):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        out = path.read_text(errors="replace") if path.exists() else ""
        if out.count(text) >= count:
            return out
        time.sleep(0.2)
    raise AssertionError(f"{text!r} not printed; got:\n{out}")


def test_manual_mode_without_a_display_types_states_in_the_roslaunch_terminal(tmp_path):
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}",
               ROS_LOG_DIR=str(tmp_path / "log"), PYTHONUNBUFFERED="1")
    env.pop("DISPLAY", None)
    ports = [f"{name}:={free_port()}" for name in ("human_port", "pomdp_port")]
    out = tmp_path / "launch.log"
    with open(out, "wb") as log:
        proc = subprocess.Popen(
            ["roslaunch", "-p", str(port), "ros_hrc", "hrc.launch", "mode:=manual",
             "gui:=false", "real_time_factor:=0", "time_per_step:=0.05", "max_trials:=100",
             "on_episode_end:=continue", *ports],
            stdin=subprocess.PIPE, stdout=log, stderr=subprocess.STDOUT, env=env,
            start_new_session=True)
    try:
        wait_for(out, "despot_mdp: manual mode without a terminal of its own (no display for "
                      "its xterm): type each state in the roslaunch terminal")
        wait_for(out, "hrc_human: press Enter in this terminal to reset the whole scenario; a "
                      "state typed here")
        wait_for(out, "Please enter the next state [integer from 0 to 7")
        proc.stdin.write(b"5\n")       # typed at the MDP's prompt, in the roslaunch terminal
        proc.stdin.flush()
        text = wait_for(out, "State is manually entered: 5 (through hrc_human")
        text = wait_for(out, "human state       : tired (5)")
        assert "Enter pressed" not in text, text
        assert "hrc_human: typed '5': next state: tired" in text
        proc.stdin.write(b"\n")        # Enter alone: a reset, as always
        proc.stdin.flush()
        wait_for(out, "RESET (Enter pressed)")
        proc.stdin.close()             # the end of the input is said
        wait_for(out, "hrc_human: input ended (standard input closed): Enter here no longer "
                      "resets")
    finally:
        stop_launched(proc)
