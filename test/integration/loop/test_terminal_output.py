"""What the roslaunch terminal shows for one step of a headless stack: by default hrc_human's
step block alone, each line whole, nothing from the solver processes (their lines go to their
log files) and none of the start-up warnings users met (KDL's root inertia, the latest-log
symlink); with verbose:=true the solvers' lines too, each whole. Runs the real hrc.launch on
private ports, its output captured as a user's terminal would show it."""
import os
import signal
import subprocess
import time

from private_launch import private_launch

WARNINGS = ("KDL", "symlink to latest log directory", "cannot load font", "media_export",
            "RLException", "Traceback")
#: Lines that said nothing a user acts on (issue #41): PyBullet's own, from the world and the
#: viz node as they import it, and the link's greeting (now at debug level).
NOISE = ("pybullet build time", "says hello")


def one_step(tmp_path, *words, wait=120.0):
    """(stdout, stderr) of hrc.launch run until its first episode (one step) is over."""
    (master, pomdp, human), env = private_launch(tmp_path)
    out, err = tmp_path / "stdout.txt", tmp_path / "stderr.txt"
    with open(out, "w") as stdout, open(err, "w") as stderr:
        launch = subprocess.Popen(
            ["roslaunch", "-p", str(master), "ros_hrc", "hrc.launch", f"pomdp_port:={pomdp}",
             f"human_port:={human}", "max_steps:=1", "read_stdin:=false", "step_delay:=0",
             *words], stdin=subprocess.DEVNULL, stdout=stdout, stderr=stderr, env=env,
            cwd=tmp_path, start_new_session=True)
        try:
            deadline = time.monotonic() + wait
            while "episode           : 1 over" not in out.read_text():
                assert launch.poll() is None, err.read_text()
                assert time.monotonic() < deadline, out.read_text()
                time.sleep(0.2)
            time.sleep(1.0)          # what else would print after the step
            launch.send_signal(signal.SIGINT)
            launch.wait(timeout=60)
        finally:
            if launch.poll() is None:      # never leave the stack running
                os.killpg(launch.pid, signal.SIGKILL)
                launch.wait()
    return out.read_text(), err.read_text()


def step_block(stdout):
    lines = stdout.splitlines()
    start = next(i for i, line in enumerate(lines)
                 if line == "------------------------------ step 0 "
                            "------------------------------")
    end = next(i for i in range(start, len(lines)) if lines[i].startswith("episode "))
    return lines[start:end + 1]


#: What a step block's lines begin with after its header, in order (DESPOT sends its action
#: values, so "robot values" is there), then the episode's end.
STEP_BLOCK_FIELDS = ["human action", "human observation", "robot observation", "human state",
                     "robot state", "robot action", "robot values", "robot belief", "object",
                     "episode"]


def fields(block):
    """The step block's lines as the fields they show (its header line kept whole)."""
    return [block[0]] + [line.split(":")[0].strip() for line in block[1:]]


def test_by_default_the_terminal_shows_the_step_block_alone(tmp_path):
    """Before: despot_pomdp's belief and despot_mdp's == RESULTS == between the blocks, glued
    mid-line, and robot_state_publisher's two KDL warnings at start-up."""
    stdout, stderr = one_step(tmp_path)
    block = step_block(stdout)
    assert fields(block) == [block[0]] + STEP_BLOCK_FIELDS, block
    for text in (stdout, stderr):
        assert "== RESULTS ==" not in text
        # (roslaunch's own lines name them: its summary, "process[despot_mdp-8]: started")
        assert not [line for line in text.splitlines()
                    if line.startswith(("despot_pomdp:", "despot_mdp:"))], text
        assert "- Belief:" not in text and "- Action = " not in text
        assert "-----Step" not in text and "Round 1" not in text
        for warning in WARNINGS + NOISE:
            assert warning not in text, warning


def test_verbose_shows_the_solvers_lines_each_whole(tmp_path):
    stdout, stderr = one_step(tmp_path, "verbose:=true")
    lines = stdout.splitlines()
    assert "== RESULTS ==" in lines                  # despot_mdp's, a line of its own
    assert any(line.startswith("despot_pomdp: ") for line in lines)
    assert any(line.startswith("despot_mdp: ") for line in lines)
    assert any(line.startswith("- Action = ") for line in lines)
    # each line whole: no process's line starts inside another's
    for line in lines:
        for piece in ("== RESULTS ==", "------------------------------ step", "despot_pomdp:",
                      "despot_mdp:", "-----Step", "-----Round"):
            at = line.find(piece)
            assert at <= 0 or line.startswith(("[", "- ")), line
    block = step_block(stdout)
    assert fields(block) == [block[0]] + STEP_BLOCK_FIELDS, block
    for warning in WARNINGS:
        assert warning not in stdout + stderr, warning
