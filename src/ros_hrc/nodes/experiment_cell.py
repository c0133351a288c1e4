"""The ROS side of one experiment cell, and the worker process that runs it.

``python -m ros_hrc.nodes.experiment_cell SPEC_FILE`` (the cell's spec, a JSON file written by
:func:`ros_hrc.experiment.stack.write_spec`) is what ``hrc_experiment`` starts, one
process per cell (rospy allows one node per process, and each cell has a master of its own).
:func:`run_cell` checks the robot model, starts the cell's ``hrc.launch``
(:func:`ros_hrc.experiment.stack.start_stack`), in which the coordinator ends each episode
and starts the next (``on_episode_end:=reset``), and :func:`drive_cell` collects each
episode's ``/hrc/status`` messages, scores it and hands the row over. The process writes one line per
episode on its standard output, ``EPISODE {json}``, as soon as the episode ends. A sequence
cell (``spec.sequence``: ``hrc.launch tasks:=L``) is driven by :func:`drive_sequences`
instead: it collects each task's ``/hrc/task_status`` and writes one line per whole
sequence, ``SEQUENCE {json}`` (its row and its tasks' rows); all the cell's sequences run on
its one stack, one after the other (the loop starts the next after a sequence's last task,
with a fresh selector). While it
waits (for the master, for a step) it watches the stack
(:class:`ros_hrc.experiment.stack.StackWatch`): a roslaunch that exits, or a link that cannot
bind its port, fails the cell at once with the reason and the last lines of its log.

SIGINT or SIGTERM stops the cell: the stack (roslaunch runs in a session of its own, so no
signal reaches it by itself) is stopped as Ctrl-C would, and the process exits 128 + the
signal's number. Episodes already written are kept by the parent.

This module imports ``ros_hrc.experiment`` (pointing down); nothing there imports it.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Dict, Iterable, List, Optional

import rosgraph
import rospy

from ros_hrc import settings
from ros_hrc.commands.check import check
from ros_hrc.errors import HrcError
from ros_hrc.experiment.episode import score_episode, step_rows
from ros_hrc.experiment.stack import (CellFailed, CellSpec, StackWatch, cell_name,
                                      encode_cell_over, encode_cell_refused, encode_episode,
                                      encode_sequence, launch_arguments, pick_ports, read_spec,
                                      stack_environment, stack_log, start_stack, stop_launched,
                                      stop_stack)
from ros_hrc.link.token import TokenError, replace_session_settings
from ros_hrc.experiment.rows import EpisodeRow
from ros_hrc.experiment.sequence_rows import SequenceRow, sequence_row, task_episode, task_row
from ros_hrc.models import load_robot_model
from ros_hrc.msg import Status, TaskStatus
from ros_hrc.nodes.common import ServiceUnavailable, TriggerCaller, init_node_when_master_is_up
from ros_hrc.pomdp.model import Model

#: Seconds a stopped stack gets to shut down (roslaunch stops its nodes) before SIGKILL.
STOP_GRACE = 60.0
#: The same when the cell is stopped by a signal (Ctrl-C, or hrc_experiment stopping for a
#: full disk): the user is waiting, and a stack cut short loses nothing, since an episode is
#: recorded whole or not at all. What roslaunch leaves then is ended by ``stop_stack``.
INTERRUPT_GRACE = 5.0


class CellStopped(BaseException):
    """SIGINT or SIGTERM arrived: unwind, stopping the stack on the way out. A BaseException,
    so that no ``except Exception`` on the way (retry loops) swallows it."""

    def __init__(self, signum: int) -> None:
        super().__init__(f"stopped by {signal.Signals(signum).name}")
        self.signum = signum


class _Signals:
    """The worker's SIGINT / SIGTERM: the first one raises CellStopped in the main thread,
    unless the cell is already cleaning up (then it is only remembered)."""

    def __init__(self) -> None:
        self.signum: Optional[int] = None
        self.armed = False
        self.cleaning_up = False

    def install(self) -> None:
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self._on_signal)
        self.armed = True

    def _on_signal(self, signum: int, frame) -> None:
        if self.signum is not None:
            return
        self.signum = signum
        if self.armed:
            self.armed = False
            raise CellStopped(signum)

    @contextmanager
    def deferred(self):
        """A section no signal may cut in two (writing an episode's line): a signal that
        comes meanwhile raises CellStopped once the section is over."""
        was, self.armed = self.armed, False
        try:
            yield
        finally:
            if was:
                if self.signum is not None:
                    raise CellStopped(self.signum)
                self.armed = True

    def check(self) -> None:
        """Raise CellStopped if a signal came and its CellStopped was swallowed on the way up:
        rosgraph's ``is_master_online`` catches everything with a bare ``except``, and a
        signal during its XML-RPC call was lost there, so the cell waited on for its master
        (the parent's SIGTERM seemingly ignored). Called by every polling loop."""
        if self.signum is not None and not self.cleaning_up:
            self.armed = False
            raise CellStopped(self.signum)

    def disarm(self) -> None:
        """From here on (stopping the stack), a signal must not cut the cleanup short."""
        self.armed = False
        self.cleaning_up = True

    def grace(self) -> float:
        return INTERRUPT_GRACE if self.signum is not None else STOP_GRACE


SIGNALS = _Signals()


class EpisodeInbox:
    """Whole episodes from /hrc/status, as the stack's coordinator ends them.

    The coordinator numbers epochs and episodes and ends each episode itself (success, the
    object left the belt, the step limit); with ``on_episode_end:=reset`` it starts the next
    one at once. An episode is the steps of one epoch up to the one marked ``episode_over``.
    An epoch cut short by a failed step (``fault``: a process died, the loop reset itself) is
    no episode: it is counted in ``abandoned`` and its steps are dropped."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.current: list = []
        self.started = 0.0           # when the current episode's first step arrived
        self.done: list = []         # finished episodes (steps, first and last arrival), oldest first
        self.abandoned: list = []    # the faults that cut epochs short
        self.last_seen = time.monotonic()

    def on_status(self, msg) -> None:
        with self.cond:
            self.last_seen = time.monotonic()
            if self.current and msg.epoch != self.current[0].epoch:
                self.current = []    # an epoch ended without its episode (a reset)
            if msg.fault:
                self.abandoned.append(msg.fault)
                self.current = []
            elif self.current or msg.step == 0:
                if not self.current:
                    self.started = self.last_seen
                self.current.append(msg)
                if msg.episode_over:
                    self.done.append((self.current, self.started, self.last_seen))
                    self.current = []
            self.cond.notify_all()

    def next_episode(self, timeout: float, check: Callable[[], None] = lambda: None) -> tuple:
        """The oldest finished episode not taken yet: (steps, monotonic time its first step
        arrived, the same for its last step); raises CellFailed after ``timeout`` wall
        seconds without any status. ``check()`` runs every second meanwhile and may raise
        (the stack died)."""
        with self.cond:
            while not self.done:
                check()
                if time.monotonic() - self.last_seen > timeout:
                    raise CellFailed(f"no step for {timeout:.0f} s")
                self.cond.wait(1.0)
            return self.done.pop(0)


#: An epoch cut short by a fault is retried, but not forever.
MAX_ABANDONED = 5
#: Wall seconds a cell's roscore gets to come up while its roslaunch runs.
MASTER_WAIT = 120.0


def still_running(watch: StackWatch) -> None:
    """What every wait of a worker checks between its polls: a signal not yet acted on
    (:meth:`_Signals.check`), then the stack (:meth:`StackWatch.check`). The stack's check is
    deferred (:meth:`_Signals.deferred`): a CellStopped raised inside ``Popen.poll()`` can
    land between its ``_waitpid_lock``'s acquire and release and leave the lock held, so the
    ``wait()`` of the stack's stop blocked for good (seen once under load)."""
    SIGNALS.check()
    with SIGNALS.deferred():
        watch.check()


def wait_for_master(watch: StackWatch, wait: float = MASTER_WAIT) -> None:
    """Until the cell's master (``ROS_MASTER_URI``) answers; CellFailed at once when the stack
    dies meanwhile (``watch``), or after ``wait`` s."""
    deadline = time.monotonic() + wait
    while not rosgraph.is_master_online():
        still_running(watch)
        if time.monotonic() > deadline:
            raise CellFailed(f"no ROS master after {wait:.0f} s; see "
                             f"{watch.log_path}")
        time.sleep(0.25)


class CellTopics:
    """The worker's subscriptions to its stack's ``/hrc/status`` and ``/hrc/task_status``,
    made once for the stack's life: each cell points them at inboxes of its own
    (:meth:`listen`) before its first step, so no cell sees another's messages."""

    def __init__(self, on_status: Callable, on_task: Optional[Callable] = None) -> None:
        self.listen(on_status, on_task)
        rospy.Subscriber("/hrc/task_status", TaskStatus, self._task, queue_size=1000)
        # The stack waits for a listener of /hrc/status before its first step: subscribed last.
        rospy.Subscriber("/hrc/status", Status, self._status, queue_size=1000)

    def listen(self, on_status: Callable, on_task: Optional[Callable] = None) -> None:
        self.on_status, self.on_task = on_status, on_task

    def _status(self, msg) -> None:
        self.on_status(msg)

    def _task(self, msg) -> None:
        if self.on_task is not None:
            self.on_task(msg)


def drive_cell(spec: CellSpec, model: Model, stack: "WarmStack", inbox: EpisodeInbox,
               deliver: Callable[[EpisodeRow, list], None]) -> int:
    """Record ``spec``'s episodes from ``stack`` (its coordinator ending and resetting
    episodes itself, ``inbox`` listening to its /hrc/status): score and ``deliver`` each.
    Returns how many were delivered."""
    name, log_dir = cell_name(spec), Path(spec.log_dir)
    bag = None
    try:
        if spec.record_bag:
            with SIGNALS.deferred():   # started means stopped in the finally, even on a signal
                bag = subprocess.Popen(["rosbag", "record", "-q", "-O",
                                        str(log_dir / f"{name}.bag"), "/hrc/status"],
                                       stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                       stderr=subprocess.STDOUT, start_new_session=True)
        delivered = 0
        previous_end = None
        for episode in spec.episodes:
            stack.still_running()
            # The stack plays the spec's episodes by their numbers (episodes:=), in order;
            # a restarted coordinator plays them from the first again: those are done.
            while True:
                steps, first_arrived, last_arrived = inbox.next_episode(
                    spec.episode_timeout, stack.still_running)
                played = int(steps[0].episode)
                if played == episode:
                    break
                if played > episode:
                    raise CellFailed(f"{name}: the stack played episode {played} where "
                                     f"episode {episode} was due")
                previous_end = last_arrived
            # Wall time of the episode: since the previous one ended (its reset included);
            # the first one from when its first step began, not from the stack's start-up.
            began = previous_end if previous_end is not None else \
                first_arrived - steps[0].step_ms / 1000.0
            previous_end = last_arrived
            if len(inbox.abandoned) > MAX_ABANDONED:
                raise CellFailed(f"{name}: {len(inbox.abandoned)} episodes cut short by "
                                 f"failed steps, the last: {inbox.abandoned[-1]}")
            key = (spec.human_model, spec.robot_policy, spec.seed, episode)
            row = score_episode(key, steps, steps[-1].end_reason, steps[0].episode_start_time,
                                model, last_arrived - began)
            deliver(row, step_rows(key, steps))
            delivered += 1
        return delivered
    finally:
        if bag is not None:
            stop_launched(bag, SIGNALS.grace())


class TaskInbox:
    """The tasks of a sequence cell from ``/hrc/task_status``, as the stack ends them, and
    the stack's liveness from ``/hrc/status`` (any step)."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.tasks: list = []           # (TaskStatus, monotonic arrival), oldest first
        self.last_seen = time.monotonic()
        self.first_step: Optional[float] = None    # when the stack's first step arrived

    def on_status(self, msg) -> None:
        with self.cond:
            self.last_seen = time.monotonic()
            if self.first_step is None:
                self.first_step = self.last_seen - msg.step_ms / 1000.0
            self.cond.notify_all()

    def on_task(self, msg) -> None:
        with self.cond:
            self.last_seen = time.monotonic()
            self.tasks.append((msg, self.last_seen))
            self.cond.notify_all()

    def next_task(self, timeout: float, check: Callable[[], None] = lambda: None) -> tuple:
        """The oldest task status not taken yet and when it arrived; CellFailed after
        ``timeout`` wall seconds without any step or task (``check()`` every second)."""
        with self.cond:
            while not self.tasks:
                check()
                if time.monotonic() - self.last_seen > timeout:
                    raise CellFailed(f"no step for {timeout:.0f} s")
                self.cond.wait(1.0)
            return self.tasks.pop(0)


def drive_sequences(spec: CellSpec, stack: "WarmStack", inbox: TaskInbox,
                    deliver: Callable[[SequenceRow, list], None]) -> int:
    """Record ``spec``'s sequences (``spec.episodes``: their numbers) from ``stack``
    (``hrc.launch tasks:=L on_episode_end:=reset`` with the sequences' task episodes: after a
    sequence's last task the loop starts the next, and the robot process makes a fresh
    selector for it; ``inbox`` listening to its topics): collect each task's
    ``/hrc/task_status`` and ``deliver`` each sequence whole (its :class:`SequenceRow` and
    task rows) as it ends. Task ``t`` of sequence ``s`` is the loop's episode ``s*L + t - 1``
    (:func:`~ros_hrc.experiment.sequence_rows.task_episode`). Returns the sequences
    delivered."""
    name = cell_name(spec)
    length = spec.sequence
    delivered = 0
    last_arrival: Optional[float] = None
    for sequence in spec.episodes:
        tasks = []
        began: Optional[float] = None
        for index in range(1, length + 1):
            due = task_episode(sequence, index, length)
            while True:
                status, arrived = inbox.next_task(spec.episode_timeout, stack.still_running)
                if int(status.episode) == due:
                    break
                if int(status.episode) > due:
                    raise CellFailed(f"{name}: the stack played task episode "
                                     f"{status.episode} where {due} was due")
            if int(status.task_index) != index:
                raise CellFailed(f"{name}: episode {due} was task {status.task_index} "
                                 f"of its sequence, not task {index}")
            if began is None:
                # Its wall time: from its first step (not the stack's start-up) for the
                # cell's first sequence, from the one before's last task for the others.
                began = inbox.first_step if last_arrival is None else last_arrival
            tasks.append(task_row(status, spec.human_model, spec.robot_policy, spec.seed,
                                  sequence))
            last_arrival = arrived
        deliver(sequence_row(tasks, max(0.0, arrived - (began or arrived))), tasks)
        delivered += 1
    return delivered


#: Wall seconds a warm stack gets to take a cell's settings (both solver processes load the
#: cell's models and build its planners; a library of 13 policies takes a few seconds).
CONFIGURE_TIMEOUT = 300.0


class WarmStack:
    """The stack this worker process owns (``hrc.launch``, with a roscore and ports of its
    own), across cells: started with its first cell's settings, then handed each next cell
    through ``/hrc/configure`` (:meth:`take`) instead of a new roslaunch. Every process that
    holds state starts the cell as a fresh stack would: the coordinator is new, both solver
    processes read the cell's settings again and rebuild their models, planners and agents,
    and the world draws each episode from the cell's (seed, episode) stream
    (docs/experiments.md, "Warm stacks")."""

    def __init__(self, first: CellSpec) -> None:
        self.first = first
        self.name = cell_name(first)
        self.log_dir = Path(first.log_dir)
        self.ports = pick_ports()
        self.proc: Optional[subprocess.Popen] = None
        self.watch: Optional[StackWatch] = None
        self.topics: Optional[CellTopics] = None
        self.running: Dict[str, object] = {}     # the launch's resolved settings now
        self.cells = 0                           # cells played on it

    def still_running(self) -> None:
        """What every wait checks between its polls (:func:`still_running`)."""
        still_running(self.watch)

    def _settings(self, spec: CellSpec) -> Dict[str, object]:
        """The cell's launch arguments checked as hrc.launch's pre-flight checks them (the
        models loaded against the task): its resolved settings; HrcError (one line)."""
        notes: List[str] = []
        config = check(launch_arguments(spec, self.ports), port_check=False, notes=notes)
        for note in notes:    # a model named by position: its mapping line, in the worker log
            print(f"{cell_name(spec)}: {note}", file=sys.stderr, flush=True)
        return config

    def start(self, on_status: Callable, on_task: Optional[Callable] = None) -> None:
        """Check the first cell's settings (a refusal is the cell's, before anything starts),
        start the stack on them and listen to its topics."""
        self.running = self._settings(self.first)
        # This process's own node talks to the stack's master too.
        os.environ.update(stack_environment(self.first, self.ports, self.log_dir))
        with SIGNALS.deferred():   # started means stopped, even on a signal
            self.proc = start_stack(self.first, self.ports, self.log_dir)
        self.watch = StackWatch(self.proc, stack_log(self.first, self.log_dir), self.name)
        wait_for_master(self.watch)
        init_node_when_master_is_up("hrc_experiment_cell", wait=30.0)
        self.topics = CellTopics(on_status, on_task)
        # One persistent connection to /hrc/configure for the stack's life, not one per cell.
        self.call = TriggerCaller(CONFIGURE_TIMEOUT)
        self.cells = 1

    def take(self, spec: CellSpec, on_status: Callable, on_task: Optional[Callable] = None
             ) -> None:
        """Hand the running stack the next cell: its settings checked (HrcError: refused,
        the stack as it was), written as the launch's (the session's settings file, and
        /hrc/config), the topics pointed at the cell's inboxes, then ``/hrc/configure``, after
        which the stack plays the cell's episodes. CellFailed when the stack does not take
        them (it is then replaced)."""
        wanted = self._settings(spec)
        moved = settings.needs_new_launch(self.running, wanted)
        if moved:
            raise CellFailed(f"{', '.join(moved)} differ from the stack's: a new launch "
                             "is needed")
        try:
            replace_session_settings(rospy.get_param("/hrc_human/link_session"), wanted)
        except TokenError as exc:
            # The launch removes its session's settings as it stops: a stack that is dying
            # (its roslaunch killed) fails here, not as a refusal of the cell's settings, so
            # the pool replaces it and the cell runs on a new stack.
            raise CellFailed(f"the warm stack of {self.name} cannot take the cell: "
                             f"{exc}") from exc
        shown = dict(wanted, token_file=rospy.get_param("/hrc/config/token_file", ""))
        rospy.set_param("/hrc/config", shown)
        self.topics.listen(on_status, on_task)
        try:
            ok, text = self.call("/hrc/configure")
        except ServiceUnavailable as exc:
            raise CellFailed(f"the warm stack of {self.name} did not take the cell: "
                             f"{exc}") from exc
        if not ok:
            raise CellFailed(f"the warm stack of {self.name} did not take the cell: {text}")
        self.running = wanted
        self.cells += 1
        print(f"{cell_name(spec)}: on the warm stack of {self.name} (cell {self.cells}; its "
              f"log: {stack_log(self.first, self.log_dir)})", file=sys.stderr, flush=True)

    def play(self, spec: CellSpec, deliver: Callable) -> int:
        """Start the stack for ``spec`` (its first cell) or hand it over (:meth:`take`), then
        record the cell's episodes or sequences; how many were delivered."""
        if spec.sequence:
            inbox = TaskInbox()
            listeners = (inbox.on_status, inbox.on_task)
        else:
            inbox = EpisodeInbox()
            listeners = (inbox.on_status, None)
        if self.proc is None:
            self.start(*listeners)
        else:
            self.take(spec, *listeners)
        if spec.sequence:
            return drive_sequences(spec, self, inbox, deliver)
        model = load_robot_model(spec.robot_model, spec.task)
        return drive_cell(spec, model, self, inbox, deliver)

    def stop(self) -> None:
        """Stop the stack as Ctrl-C would, and what roslaunch left running."""
        if self.proc is None:
            return
        left = stop_stack(self.proc, self.first, self.log_dir, SIGNALS.grace())
        if left:
            print(f"{self.name}: hrc.launch left {len(left)} processes running (its nodes "
                  f"run in sessions of their own); stopped them", file=sys.stderr, flush=True)


def serve(spec_files: Iterable[str], deliver: Callable, say: Callable[[str], None]) -> None:
    """Play the cells whose spec files come one per line (``spec_files``: the pool writes
    them as it hands this worker a cell), all on one stack: the first starts it, each next
    is handed to it (:class:`WarmStack`). After each cell ``say`` gets its
    :data:`~ros_hrc.experiment.stack.CELL_OVER_LINE` line, or the
    :data:`~ros_hrc.experiment.stack.CELL_REFUSED_LINE` line when its settings were refused
    (a bad model: the cell fails, the stack stays). A stack that fails raises CellFailed (the
    pool replaces the worker); the stack stops when the lines end."""
    stack: Optional[WarmStack] = None
    try:
        for line in spec_files:
            if not line.strip():
                continue
            spec = read_spec(line.strip())
            if not spec.episodes:
                say(encode_cell_over(spec, 0))
                continue
            if stack is None:
                stack = WarmStack(spec)
            try:
                delivered = stack.play(spec, deliver)
            except HrcError as exc:     # the cell's settings, refused before they reached it
                if stack.proc is None:
                    stack = None
                say(encode_cell_refused(spec, " ".join(str(exc).split())))
                continue
            say(encode_cell_over(spec, delivered))
    finally:
        SIGNALS.disarm()
        if stack is not None:
            stack.stop()
        if not rospy.is_shutdown():
            rospy.signal_shutdown("worker done")


def main(argv: Optional[List[str]] = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv == ["--serve"]:
        spec_files: Iterable[str] = sys.stdin
        label = "worker"
    elif len(argv) == 1 and not argv[0].startswith("-"):
        spec_files = [argv[0]]
        try:
            spec = read_spec(argv[0])
        except (OSError, ValueError, TypeError, KeyError) as exc:
            print(f"cell spec {argv[0]}: unreadable ({exc})", file=sys.stderr, flush=True)
            return 2
        label = f"cell {spec.human_model}/{spec.robot_policy}/seed {spec.seed}"
    else:
        print("usage: python -m ros_hrc.nodes.experiment_cell SPEC_FILE | --serve (spec "
              "files on stdin, one per line)", file=sys.stderr)
        return 2

    def deliver(row, parts) -> None:
        line = encode_sequence(row, parts) if isinstance(row, SequenceRow) else \
            encode_episode(row, parts)
        say(line)

    def say(line: str) -> None:
        with SIGNALS.deferred():
            print(line, flush=True)

    SIGNALS.install()
    try:
        serve(spec_files, deliver, say)
    except CellStopped:
        pass
    except (CellFailed, HrcError, OSError, ValueError, TypeError, KeyError) as exc:
        if SIGNALS.signum is None:
            # The last line the parent shows after the cell's name: the reason alone.
            print(f"failed: {' '.join(str(exc).split())}", file=sys.stderr, flush=True)
            return 1
    if SIGNALS.signum is not None:
        print(f"{label}: stopped by {signal.Signals(SIGNALS.signum).name}; its stack is down",
              file=sys.stderr, flush=True)
        return 128 + SIGNALS.signum
    return 0


if __name__ == "__main__":
    sys.exit(main())
