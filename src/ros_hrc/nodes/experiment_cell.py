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
from typing import Callable, List, Optional

import rosgraph
import rospy

from ros_hrc.errors import HrcError
from ros_hrc.experiment.episode import score_episode, step_rows
from ros_hrc.experiment.stack import (CellFailed, CellSpec, StackWatch,
                                      cell_name, encode_episode, encode_sequence, pick_ports,
                                      read_spec, stack_environment, stack_log, start_stack,
                                      stop_launched, stop_stack)
from ros_hrc.experiment.rows import EpisodeRow
from ros_hrc.experiment.sequence_rows import SequenceRow, sequence_row, task_episode, task_row
from ros_hrc.models import load_robot_model, positional_mapping_line
from ros_hrc.msg import Status, TaskStatus
from ros_hrc.nodes.common import init_node_when_master_is_up
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
    (:meth:`_Signals.check`), then the stack (:meth:`StackWatch.check`)."""
    SIGNALS.check()
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


def drive_cell(spec: CellSpec, model: Model, proc: subprocess.Popen,
               deliver: Callable[[EpisodeRow, list], None], name: str, log_dir: Path) -> int:
    """Record ``spec``'s episodes from the stack ``proc`` (``hrc.launch``, already started,
    ending and resetting episodes itself): score and ``deliver`` each. Returns how many were
    delivered."""
    watch = StackWatch(proc, stack_log(spec, log_dir), name)
    wait_for_master(watch)
    init_node_when_master_is_up("hrc_experiment_cell", wait=30.0)
    inbox = EpisodeInbox()
    rospy.Subscriber("/hrc/status", Status, inbox.on_status, queue_size=1000)
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
            still_running(watch)
            # The stack plays the spec's episodes by their numbers (episodes:=), in order;
            # a restarted coordinator plays them from the first again: those are done.
            while True:
                steps, first_arrived, last_arrived = inbox.next_episode(
                    spec.episode_timeout, lambda: still_running(watch))
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
        SIGNALS.disarm()
        if bag is not None:
            stop_launched(bag, SIGNALS.grace())
        rospy.signal_shutdown("cell done")


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


def drive_sequences(spec: CellSpec, proc: subprocess.Popen,
                    deliver: Callable[[SequenceRow, list], None], name: str,
                    log_dir: Path) -> int:
    """Record ``spec``'s sequences (``spec.episodes``: their numbers) from the stack ``proc``
    (``hrc.launch tasks:=L on_episode_end:=reset`` with the sequences' task episodes, already
    started: after a sequence's last task the loop starts the next, and the robot process
    makes a fresh selector for it): collect each task's ``/hrc/task_status`` and ``deliver``
    each sequence whole (its :class:`SequenceRow` and task rows) as it ends. Task ``t`` of
    sequence ``s`` is the loop's episode ``s*L + t - 1``
    (:func:`~ros_hrc.experiment.sequence_rows.task_episode`). Returns the sequences
    delivered."""
    watch = StackWatch(proc, stack_log(spec, log_dir), name)
    wait_for_master(watch)
    init_node_when_master_is_up("hrc_experiment_cell", wait=30.0)
    inbox = TaskInbox()
    rospy.Subscriber("/hrc/task_status", TaskStatus, inbox.on_task, queue_size=1000)
    # The stack waits for a listener of /hrc/status before its first step: subscribed last.
    rospy.Subscriber("/hrc/status", Status, inbox.on_status, queue_size=1000)
    length = spec.sequence
    delivered = 0
    last_arrival: Optional[float] = None
    try:
        for sequence in spec.episodes:
            tasks = []
            began: Optional[float] = None
            for index in range(1, length + 1):
                due = task_episode(sequence, index, length)
                while True:
                    status, arrived = inbox.next_task(spec.episode_timeout,
                                                      lambda: still_running(watch))
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
    finally:
        SIGNALS.disarm()
        rospy.signal_shutdown("cell done")


def run_cell(spec: CellSpec, deliver: Callable[[EpisodeRow, list], None]) -> int:
    """Run the cell's episodes on a stack of its own; ``deliver(episode_row, step_rows)`` for
    each one as it ends. Returns how many episodes were delivered; raises CellFailed if the
    stack fails, ModelError if the robot model does not fit the task."""
    if not spec.episodes:
        return 0
    model = None
    if not spec.sequence:      # a sequence's robot models are its library's (the stack's)
        model = load_robot_model(spec.robot_model, spec.task)
        mapping = positional_mapping_line(model)
        if mapping:   # stdout carries the episodes; stderr goes to the cell's worker log
            print(f"{cell_name(spec)}: {mapping}", file=sys.stderr, flush=True)
    ports = pick_ports()
    log_dir = Path(spec.log_dir)
    # This process's own node talks to the cell's master too.
    os.environ.update(stack_environment(spec, ports, log_dir))
    proc = None
    try:
        with SIGNALS.deferred():   # started means stopped in the finally, even on a signal
            proc = start_stack(spec, ports, log_dir)
        if spec.sequence:
            return drive_sequences(spec, proc, deliver, cell_name(spec), log_dir)
        return drive_cell(spec, model, proc, deliver, cell_name(spec), log_dir)
    finally:
        SIGNALS.disarm()
        if proc is not None:
            left = stop_stack(proc, spec, log_dir, SIGNALS.grace())
            if left:
                print(f"{cell_name(spec)}: hrc.launch left {len(left)} processes running "
                      f"(its nodes run in sessions of their own); stopped them",
                      file=sys.stderr, flush=True)


def main(argv: Optional[List[str]] = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print("usage: python -m ros_hrc.nodes.experiment_cell SPEC_FILE", file=sys.stderr)
        return 2
    try:
        spec = read_spec(argv[0])
    except (OSError, ValueError, TypeError, KeyError) as exc:
        print(f"cell spec {argv[0]}: unreadable ({exc})", file=sys.stderr, flush=True)
        return 2
    label = f"cell {spec.human_model}/{spec.robot_policy}/seed {spec.seed}"

    def deliver(row, parts) -> None:
        line = encode_sequence(row, parts) if isinstance(row, SequenceRow) else \
            encode_episode(row, parts)
        with SIGNALS.deferred():
            print(line, flush=True)

    SIGNALS.install()
    try:
        run_cell(spec, deliver)
    except CellStopped:
        pass
    except (CellFailed, HrcError, OSError, ValueError) as exc:
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
