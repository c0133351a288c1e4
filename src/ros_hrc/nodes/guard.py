"""hrc_guard: the launch-prefix of hrc_world, so that the world's death stops the launch with a
non-zero exit status.

roslaunch (1.15) exits 0 however it ends unless it fails to start (ros_comm #919): when a
``required`` node dies, its process monitor shuts everything down and returns normally, and
SIGINT, SIGTERM and SIGHUP all take the same graceful path. Nothing a node can call changes that.
So the world is started through this guard (``launch-prefix="$(find ros_hrc)/scripts/hrc_guard"``
on the node in world_nodes.launch): roslaunch starts the guard, the guard starts the world as its
own child and waits for it. roslaunch learns nothing until the guard ends, so nothing races.

How the world ends, and what the guard does:

* **the launch stops** (Ctrl-C, Esc in the window, a solver that cannot start): roslaunch sends
  SIGINT to the guard (SIGTERM, SIGKILL if it lingers); the guard passes SIGINT, SIGTERM and
  SIGHUP on to the world, once each, and ends with the world's status. Nothing else happens:
  roslaunch ends as it always does (status 0 after Ctrl-C or Esc).
* **the world ends by itself with status 0** (``rosnode kill /hrc_world``; the window closed
  when no roslaunch runs it): the guard ends with 0, and roslaunch does what it does for a
  required node that ended.
* **the world dies** (a signal the guard did not pass on, or a non-zero status: kill -9, a
  crash, a fault at start-up), and the guard's parent is a roslaunch: the guard stops that
  roslaunch (SIGSTOP: it sees nothing more, respawns nothing), shuts down roslaunch's own
  children as roslaunch would (SIGINT to each one's process group, SIGTERM after 15 s, SIGKILL
  after 2 s more; rosout, then rosmaster, last, and only if that roslaunch started them), kills
  the roslaunch (SIGKILL: its exit status is 137, which the shell shows as "Killed"), then
  prints one line saying the world died (a line that cannot be written, its log on a full
  disk, is dropped: the kill comes first). Under anything else (rostest, rosrun) the guard only says
  the world died and ends with the world's status.

The guard touches no process but the roslaunch that is its parent (checked by its command line)
and that roslaunch's own children. The world dies with the guard (``PR_SET_PDEATHSIG``), so a
guard killed by roslaunch's SIGKILL leaves no world behind.

Once the world is started, the guard re-executes itself as ``python -m ros_hrc.nodes.guard``
(same process, same child), so only the world's own process carries ``__name:=hrc_world``: a
``kill -9`` of the process a user finds by that name is the world's, never the guard's.
"""
from __future__ import annotations

import ctypes
import os
import signal
import subprocess
import sys
import time
from typing import Dict, Iterable, List, Optional, Sequence

from ros_hrc.process_tree import (alive, children_of, command_line, group_alive, group_of,
                                  is_roslaunch, is_stopped)

#: Signals the guard passes on to the world: how roslaunch (or a user) stops a node.
FORWARDED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
#: roslaunch's own waits before it escalates (roslaunch.nodeprocess), s.
SIGINT_TIMEOUT = 15.0
SIGTERM_TIMEOUT = 2.0
SIGKILL_TIMEOUT = 2.0
#: The signal that ends a roslaunch whose world died: one it does not handle, whose shell
#: status needs no explaining (137, "Killed"), and that ends a stopped process too.
LAUNCH_ENDING_SIGNAL = signal.SIGKILL
#: The environment variable that carries the guarded node's name across the re-execution.
NODE_ENV = "HRC_GUARD_NODE"
_GUARDING = "--guarding"
_PR_SET_PDEATHSIG = 1
_POLL = 0.05


def is_guard(pid: int) -> bool:
    """Whether process ``pid`` is a guard waiting for its child (re-executed)."""
    words = command_line(pid)
    return "ros_hrc.nodes.guard" in words[1:3] and _GUARDING in words


class _Target:
    """One child of roslaunch, signalled as roslaunch does: its whole process group when it
    leads one (roslaunch starts every child in a session of its own), else itself."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.group = group_of(pid) == pid

    def alive(self) -> bool:
        return group_alive(self.pid) if self.group else alive(self.pid)

    def send(self, signum: int) -> None:
        try:
            if self.group:
                os.killpg(self.pid, signum)
            else:
                os.kill(self.pid, signum)
        except (ProcessLookupError, PermissionError):
            pass


def shut_down(pids: Iterable[int], timeouts: Sequence[float] = (
        SIGINT_TIMEOUT, SIGTERM_TIMEOUT, SIGKILL_TIMEOUT)) -> List[int]:
    """End processes as roslaunch ends its children, all at once: SIGINT, then SIGTERM to those
    still there after ``timeouts[0]`` s, then SIGKILL after ``timeouts[1]`` s more. The pids
    still alive after the last wait (none, unless something cannot be killed)."""
    targets = [_Target(pid) for pid in pids]
    for signum, timeout in zip((signal.SIGINT, signal.SIGTERM, signal.SIGKILL), timeouts):
        targets = [t for t in targets if t.alive()]
        for target in targets:
            target.send(signum)
        deadline = time.monotonic() + timeout
        while targets and time.monotonic() < deadline:
            time.sleep(_POLL)
            targets = [t for t in targets if t.alive()]
        if not targets:
            break
    return [t.pid for t in targets]


def _is_core(pid: int) -> str:
    """"master" or "rosout" for the core processes a roslaunch started, else ""."""
    words = command_line(pid)
    if any(os.path.basename(word) == "rosmaster" for word in words[:2]):
        return "master"
    if "__name:=rosout" in words:
        return "rosout"
    return ""


def stop_launch(launcher: int, guard: int) -> bool:
    """Stop the roslaunch ``launcher`` whose required world died, so that it exits non-zero:
    freeze it, end its children (but ``guard``) as it would, then kill it. False, and nothing
    done, when it cannot be frozen (gone, or not ours)."""
    try:
        os.kill(launcher, signal.SIGSTOP)
    except (ProcessLookupError, PermissionError):
        return False
    deadline = time.monotonic() + 2.0   # the stop takes effect at once; be sure before looking
    while time.monotonic() < deadline and alive(launcher) and not is_stopped(launcher):
        time.sleep(0.005)
    children = [pid for pid in children_of(launcher) if pid != guard]
    core: Dict[str, List[int]] = {"rosout": [], "master": []}
    nodes = []
    for pid in children:
        kind = _is_core(pid)
        (core[kind] if kind else nodes).append(pid)
    # The nodes first, then rosout, then the master: nodes unregister from it as they end.
    for group in (nodes, core["rosout"], core["master"]):
        if group:
            shut_down(group)
    return True


def describe_end(code: int) -> str:
    """``exit status 3`` or ``killed by SIGKILL`` from a ``waitstatus_to_exitcode`` code."""
    if code >= 0:
        return f"exit status {code}"
    try:
        return f"killed by {signal.Signals(-code).name}"
    except ValueError:
        return f"killed by signal {-code}"


def _die_with_parent(parent: int) -> None:
    """In the world's process, before it runs: die when the guard dies; take signals again."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, FORWARDED)
    if os.getppid() != parent:   # the guard died before the line above
        os._exit(1)


def _node_name(command: Sequence[str]) -> str:
    for word in command:
        if word.startswith("__name:="):
            return word[len("__name:="):]
    return os.path.basename(command[0]) if command else "the guarded process"


def start(command: Sequence[str]) -> None:
    """Start ``command`` (the world) as a child in a process group of its own, then become the
    guard that waits for it (this process re-executed; never returns)."""
    name = _node_name(command)
    # Held back from here to the guard's handlers: a stop asked for meanwhile is passed on.
    signal.pthread_sigmask(signal.SIG_BLOCK, FORWARDED)
    me = os.getpid()
    try:
        child = subprocess.Popen(list(command), process_group=0,
                                 preexec_fn=lambda: _die_with_parent(me))
    except OSError as error:
        print(f"hrc_guard: cannot start {name}: {error.strerror or error}", file=sys.stderr,
              flush=True)
        raise SystemExit(1) from None
    environ = dict(os.environ, **{NODE_ENV: name})
    os.execve(sys.executable, [sys.executable, "-m", "ros_hrc.nodes.guard", _GUARDING,
                               str(child.pid)], environ)


def guard(child: int, name: str) -> int:
    """Wait for the world ``child``; pass stops on to it; when it died, stop the launch. The
    status to end with: the world's (128 + N when a signal N ended it)."""
    stops: List[int] = []

    def pass_on(signum: int, _frame: object) -> None:
        if signum in stops:
            return
        stops.append(signum)
        try:
            os.killpg(child, signum)
        except (ProcessLookupError, PermissionError):
            pass

    for signum in FORWARDED:
        signal.signal(signum, pass_on)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, FORWARDED)
    try:
        _, status = os.waitpid(child, 0)
    except ChildProcessError:    # not ours: nothing to guard
        return 1
    code = os.waitstatus_to_exitcode(status)
    ending = code if code >= 0 else 128 - code
    if stops or code == 0:
        return ending            # asked to stop, or ended by itself: not a death
    for signum in FORWARDED:     # from here on, the launch is ours to stop
        signal.signal(signum, signal.SIG_IGN)
    if stops:                    # the launch began to stop as the world died: roslaunch's
        return ending            # own shutdown goes on
    launcher = os.getppid()
    if not is_roslaunch(launcher):
        say(f"{name} died ({describe_end(code)})")
        return ending
    if not stop_launch(launcher, os.getpid()):
        return ending
    # Killed before it is said: the line goes to the launch's log, which may be on a full
    # disk; a roslaunch left frozen because a print failed would hang its user for good.
    try:
        os.kill(launcher, LAUNCH_ENDING_SIGNAL)   # ends it stopped as it is
    except ProcessLookupError:
        pass
    say(f"{name} died ({describe_end(code)}): it is required, so the launch stops with it; "
        f"roslaunch exits with status {128 + LAUNCH_ENDING_SIGNAL} "
        f"({signal.strsignal(LAUNCH_ENDING_SIGNAL)})")
    return ending


def say(line: str) -> None:
    """One line on stderr, or nothing when it cannot be written (a full disk, a closed
    pipe): what the guard does never waits on what it says."""
    try:
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of ``scripts/hrc_guard COMMAND...`` (roslaunch's launch-prefix)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if len(argv) == 2 and argv[0] == _GUARDING and argv[1].isdigit():
        return guard(int(argv[1]), os.environ.get(NODE_ENV, "the guarded process"))
    if not argv or argv[0].startswith("-"):
        print("usage: hrc_guard COMMAND [ARG...]  (hrc_world's launch-prefix in "
              "world_nodes.launch)", file=sys.stderr)
        return 2
    start(argv)
    return 1   # not reached: start() re-executes this process


if __name__ == "__main__":
    raise SystemExit(main())
