"""hrc_guard (hrc_world's launch-prefix): a world that dies stops its roslaunch with a non-zero
status and leaves nothing; a stop passed on, or a clean end, changes nothing. Checked with a
stand-in roslaunch (a script named roslaunch that starts its children as roslaunch does: each in
a session of its own), no ROS needed."""
import os
import signal
import stat
import subprocess
import sys
import textwrap
import time

import pytest

from ros_hrc.nodes.guard import children_of, describe_end, is_guard

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GUARD = os.path.join(REPO, "scripts", "hrc_guard")
WAIT = 60.0

# The stand-in: starts "the world" through the guard and two other children, each with
# setsid as roslaunch does, says their pids, then waits as roslaunch's monitor does (and, if it
# saw the guard end, says how).
STAND_IN = textwrap.dedent("""\
    import os, subprocess, sys, time
    world = sys.argv[1:]
    guard = subprocess.Popen([{guard!r}] + world, preexec_fn=os.setsid)
    other = subprocess.Popen([sys.executable, "-c", "import signal, sys, time; "
                              "signal.signal(signal.SIGINT, lambda *a: sys.exit(0)); "
                              "time.sleep(600)"], preexec_fn=os.setsid)
    print(guard.pid, other.pid, flush=True)
    while guard.poll() is None:
        time.sleep(0.1)
    print("the guard ended", guard.returncode, flush=True)
    time.sleep(600)
""")


@pytest.fixture
def launch(tmp_path):
    """(start, processes): start(world_command) runs the stand-in roslaunch; every process it
    made is killed at the end whatever happened."""
    script = tmp_path / "roslaunch"
    script.write_text(STAND_IN.format(guard=GUARD))
    started = []

    def start(*world, stderr=subprocess.PIPE):
        proc = subprocess.Popen([sys.executable, str(script)] + list(world),
                                stdout=subprocess.PIPE, stderr=stderr, text=True,
                                env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)))
        guard, other = (int(word) for word in proc.stdout.readline().split())
        deadline = time.monotonic() + WAIT
        while not children_of(guard) and time.monotonic() < deadline:
            time.sleep(0.02)
        world_pid = children_of(guard)[0]
        started.append((proc, [guard, other, world_pid]))
        while not is_guard(guard) and time.monotonic() < deadline:   # re-executed
            time.sleep(0.02)
        return proc, guard, other, world_pid

    yield start
    for proc, pids in started:
        for pid in pids + [proc.pid]:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        proc.wait()


def gone(pid, timeout=WAIT):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            with open(f"/proc/{pid}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] == "Z":
                    return True
        except FileNotFoundError:
            return True
        time.sleep(0.05)
    return False


SLEEPER = [sys.executable, "-c", "import time; time.sleep(600)", "__name:=hrc_world"]


def test_a_world_that_dies_ends_its_roslaunch_non_zero_and_every_child_with_it(launch):
    proc, guard, other, world = launch(*SLEEPER)
    os.kill(world, signal.SIGKILL)
    proc.wait(WAIT)
    err = proc.stderr.read()
    assert proc.returncode == -signal.SIGKILL
    assert err.splitlines() == [
        "hrc_world died (killed by SIGKILL): it is required, so the launch stops with it; "
        "roslaunch exits with status 137 (Killed)"]
    assert gone(other) and gone(guard)
    assert "the guard ended" not in proc.stdout.read()   # roslaunch saw nothing


def test_a_world_that_dies_ends_its_roslaunch_even_when_its_line_cannot_be_written(launch,
                                                                                tmp_path):
    """The launch's log on a full disk (here a private "full" device node, as /dev/full: every
    write fails with ENOSPC; a node of our own, so the test never opens the machine's).
    Before: the guard froze roslaunch, its line failed before the kill, and roslaunch stayed
    frozen for good, its children zombies, and the experiment's cell hung."""
    full_device = tmp_path / "full"
    try:
        os.mknod(full_device, 0o600 | stat.S_IFCHR, os.makedev(1, 7))   # Linux's "full" device
    except PermissionError:
        pytest.skip("making a device node needs root (CAP_MKNOD)")
    with open(full_device, "w") as full_disk:
        proc, guard, other, world = launch(*SLEEPER, stderr=full_disk)
    os.kill(world, signal.SIGKILL)
    proc.wait(WAIT)
    assert proc.returncode == -signal.SIGKILL
    assert gone(other) and gone(guard)


def test_the_guard_names_the_node_and_a_non_zero_status(launch):
    proc, guard, other, world = launch(sys.executable, "-c",
                                       "import sys, time; time.sleep(0.5); sys.exit(3)",
                                       "__name:=hrc_world")
    proc.wait(WAIT)
    assert proc.returncode == -signal.SIGKILL
    assert proc.stderr.read().splitlines() == [
        "hrc_world died (exit status 3): it is required, so the launch stops with it; "
        "roslaunch exits with status 137 (Killed)"]
    assert gone(other)


def test_a_stop_is_passed_on_once_and_nothing_else_happens(launch, tmp_path):
    # The world ends on SIGINT with status 0, as a rospy node does (once it is up).
    ready = tmp_path / "ready"
    proc, guard, other, world = launch(sys.executable, "-c", textwrap.dedent("""\
        import pathlib, signal, sys, time
        signal.signal(signal.SIGINT, lambda *a: sys.exit(0))
        pathlib.Path(sys.argv[1]).touch()
        time.sleep(600)"""), str(ready))
    deadline = time.monotonic() + WAIT
    while not ready.exists() and time.monotonic() < deadline:
        time.sleep(0.02)
    os.killpg(guard, signal.SIGINT)   # as roslaunch stops a child
    assert proc.stdout.readline().split() == ["the", "guard", "ended", "0"]
    assert gone(world)
    assert proc.poll() is None and not gone(other, timeout=0.5)   # roslaunch left alone


def test_a_world_that_ends_by_itself_with_status_0_is_no_death(launch):
    proc, guard, other, world = launch(sys.executable, "-c", "import time; time.sleep(0.5)")
    assert proc.stdout.readline().split() == ["the", "guard", "ended", "0"]
    assert proc.poll() is None


def test_a_killed_guard_takes_its_world_with_it(launch):
    proc, guard, other, world = launch(*SLEEPER)
    os.kill(guard, signal.SIGKILL)
    assert gone(world)


def test_under_something_else_than_roslaunch_the_guard_only_reports(tmp_path):
    run = subprocess.run([GUARD, sys.executable, "-c", "import sys; sys.exit(5)",
                          "__name:=hrc_world"], capture_output=True, text=True, timeout=WAIT,
                         env=dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)))
    assert run.returncode == 5
    assert run.stderr.splitlines() == ["hrc_world died (exit status 5)"]


def test_exit_descriptions():
    assert describe_end(0) == "exit status 0"
    assert describe_end(-9) == "killed by SIGKILL"
    assert describe_end(-11) == "killed by SIGSEGV"
