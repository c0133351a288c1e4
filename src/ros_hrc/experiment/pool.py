"""The local pool: an experiment grid's cells played by ``jobs`` workers side by side, each a
process that owns one stack and plays cell after cell on it (:class:`StackWorker`: a warm
stack, handed each next cell through one reconfiguration and reset instead of a new
roslaunch; ``--fresh-stacks``: a new stack per cell, as before), under SIGINT and SIGTERM
(:func:`run_stoppable`; on a cluster, the same queue with
:class:`ros_hrc.experiment.cluster.NodeLane`, an actor on a node, playing each lane's
cells). No ROS here.

A cell goes from the :class:`CellQueue` (the human alone, ``no_robot``, on a stream before the
robots' episodes of that stream) to a lane's worker (:func:`run_grid`), which plays it in up
to three attempts (:func:`play_cell`, :mod:`ros_hrc.experiment.attempts`): a stack that
fails is replaced and the cell's missing episodes run again. SIGINT or SIGTERM stops every
worker's stack
(:class:`Stopper`), keeps what was recorded and says how to resume; so does a full disk under
the run (:mod:`ros_hrc.experiment.disk`: the results' disk or ``$ROS_HOME``'s without room,
or a write of the run's own that found none), in one line naming the disk.
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import signal
import subprocess
import sys
import threading
from collections import defaultdict
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Set, TextIO, Tuple, Union

from ros_hrc.errors import HrcError
from ros_hrc.experiment.attempts import CellAttempts, Deliver
from ros_hrc.experiment.disk import (CHECK_INTERVAL, DiskFull, DiskWatch, full_disk_line,
                                     is_full_disk)
from ros_hrc.experiment.episode import ALONE_POLICY
from ros_hrc.experiment.recording import Progress
from ros_hrc.experiment.stack import (CellSpec, StackKeeper, cell_name, decode_cell_end,
                                      decode_episode, stack_key, worker_command, write_spec)
from ros_hrc.pomdp.output import write_text_atomically


class Stopper:
    """SIGINT / SIGTERM to hrc_experiment, or a full disk under the run (``disks``, looked
    at by :meth:`check_disks`): every worker gets SIGTERM (each stops its own stack), no new
    cell starts, and the run ends with what was recorded."""

    def __init__(self, disks: Optional[DiskWatch] = None) -> None:
        self.signum: Optional[int] = None
        self.disk_full: Optional[DiskFull] = None
        self.disks = disks
        self._lock = threading.Lock()
        self._workers: Set[subprocess.Popen] = set()
        self._previous: Dict[int, object] = {}

    @property
    def stopping(self) -> bool:
        return self.signum is not None or self.disk_full is not None

    def install(self) -> None:
        """Catch SIGINT and SIGTERM (main thread only) until :meth:`uninstall`."""
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._previous[sig] = signal.signal(sig, self._on_signal)

    def uninstall(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)  # type: ignore[arg-type]
        self._previous.clear()

    def _on_signal(self, signum: int, frame) -> None:
        self.stop(signum)

    def stop(self, signum: int) -> None:
        """Stop the run: SIGTERM to every worker (again on a second signal)."""
        if self.signum is None:
            self.signum = signum
        self._terminate_all()

    def stop_for_full_disk(self, full: DiskFull) -> None:
        """Stop the run because ``full`` has no room (the first such disk is the one said)."""
        with self._lock:
            if self.disk_full is None:
                self.disk_full = full
        self._terminate_all()

    def check_disks(self, error: Optional[BaseException] = None) -> bool:
        """Whether the run stops for a full disk: ``error`` is a write that found no room, a
        watched disk has none left now, or one had before. The first two stop it."""
        if error is not None and is_full_disk(error):
            self.stop_for_full_disk(DiskFull.of_error(error))   # type: ignore[arg-type]
        elif self.disk_full is None and self.disks is not None:
            full = self.disks.full()
            if full is not None:
                self.stop_for_full_disk(full)
        return self.disk_full is not None

    def _terminate_all(self) -> None:
        with self._lock:
            workers = list(self._workers)
        for proc in workers:
            self._terminate(proc)

    @staticmethod
    def _terminate(proc: subprocess.Popen) -> None:
        if proc.poll() is None:
            try:
                proc.send_signal(signal.SIGTERM)
            except ProcessLookupError:
                pass

    def add(self, proc: subprocess.Popen) -> None:
        with self._lock:
            self._workers.add(proc)
        if self.stopping:   # the signal came while it was starting
            self._terminate(proc)

    def discard(self, proc: subprocess.Popen) -> None:
        with self._lock:
            self._workers.discard(proc)


def add_stack_argument(parser: argparse.ArgumentParser) -> None:
    """``--fresh-stacks`` / ``--no-fresh-stacks`` (hrc_experiment and hrc_fit)."""
    parser.add_argument("--fresh-stacks", action=argparse.BooleanOptionalAction, default=False,
                        help="start a new stack (roscore, roslaunch, every process) for each "
                             "cell, as before warm stacks; by default each worker keeps its "
                             "stack and hands it the next cell (docs/experiments.md, \"Warm "
                             "stacks\"); the rows are the same either way")


class CellRefused(RuntimeError):
    """A cell's settings were refused before they reached a stack (a bad model): the cell
    fails with the reason, at once; the worker's stack is as it was."""


class StackWorker(StackKeeper):
    """A worker process that owns one stack (``python -m ros_hrc.nodes.experiment_cell
    --serve``, :func:`~ros_hrc.experiment.stack.worker_command`) and plays the cells it is
    handed one after another: the first starts the stack, each next is handed to the running
    stack (docs/experiments.md, "Warm stacks"). A cell its stack cannot take in place (another
    task, other world settings: :func:`~ros_hrc.experiment.stack.stack_key`) gets a new
    worker, as does every cell with ``fresh`` (``--fresh-stacks``: a stack per cell, the old
    one shutting down while the next starts). A worker whose stack fails is gone:
    :meth:`play` raises, and the next cell starts a new one. SIGTERM from ``stopper`` stops
    its stack."""

    def __init__(self, stopper: "Stopper", fresh: bool = False) -> None:
        super().__init__(fresh)
        self.stopper = stopper
        self.proc: Optional[subprocess.Popen] = None
        self._errors: List[str] = []        # its stderr lines since its cell began
        self._errors_lock = threading.Lock()
        self._reader: Optional[threading.Thread] = None

    def stack_running(self) -> bool:
        return self.proc is not None

    def _start(self, cell: CellSpec) -> None:
        self.proc = subprocess.Popen(worker_command(), stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.stopper.add(self.proc)
        self.key = stack_key(cell)
        with self._errors_lock:
            self._errors = []
        proc = self.proc

        def read_errors() -> None:
            for line in proc.stderr:
                with self._errors_lock:
                    self._errors.append(line)
        self._reader = threading.Thread(target=read_errors, name="worker-stderr", daemon=True)
        self._reader.start()

    def _take_errors(self) -> List[str]:
        with self._errors_lock:
            taken, self._errors = self._errors, []
        return taken

    def play(self, cell: CellSpec, deliver: Deliver, log: TextIO) -> None:
        """Play ``cell`` (its episodes still to record) on this worker's stack, starting one
        when there is none or this one cannot take it; ``deliver(row, steps)`` for each
        episode or sequence as it ends; the worker's lines for the cell go into ``log``.
        Raises CellRefused (the cell's settings were refused), RuntimeError with the worker's
        last line when its stack failed (the worker is gone), or what ``deliver`` raised (a
        full disk: the worker is stopped)."""
        if not self.takes(cell):
            self.close()
        if self.proc is None:
            self._start(cell)
        proc = self.proc
        try:
            proc.stdin.write(f"{write_spec(cell, Path(cell.log_dir))}\n")
            proc.stdin.flush()
        except OSError:   # it died before it could read the cell: its reason is on stderr
            pass
        refusal, over = None, False
        try:
            for line in proc.stdout:
                end = decode_cell_end(line)
                if end is not None:
                    over, what = end
                    refusal = None if over else what["reason"]
                    break
                try:
                    episode = decode_episode(line)
                except (ValueError, KeyError) as exc:   # a line cut short: the episode reruns
                    with self._errors_lock:
                        self._errors.append(f"unreadable episode line ({exc}): {line[:80]!r}\n")
                    continue
                if episode is not None:
                    deliver(*episode)
            else:
                # Its output ended before the cell did: the worker (and so its stack) is gone.
                self._worker_gone(proc, log)
                return
        except BaseException:
            # An episode could not be recorded (a full disk): the worker must not run on, nor
            # its stack: SIGTERM makes it stop the stack; the reason goes up.
            if self.proc is proc:
                self._terminate()
            raise
        log.writelines(self._take_errors())
        if over:
            self.played(cell)
        if self.fresh:
            self.close(wait=False)
        if refusal is not None:
            raise CellRefused(refusal)

    def _worker_gone(self, proc: subprocess.Popen, log: TextIO) -> None:
        """The worker's output ended before its cell did: RuntimeError with its last line
        (unless the run is stopping), its messages in ``log``."""
        proc.wait()
        if self._reader is not None:
            self._reader.join(5.0)
        errors = self._take_errors()
        log.writelines(errors)
        self._forget()
        if self.stopper.stopping:
            return
        raise RuntimeError(errors[-1].strip() if errors else f"exit code {proc.returncode}")

    def _terminate(self) -> None:
        proc = self.proc
        Stopper._terminate(proc)
        for _ in proc.stdout:       # drained, so that its last lines never block it
            pass
        proc.wait()
        self._forget()

    def _forget(self) -> None:
        if self.proc is not None:
            self.stopper.discard(self.proc)
        self.proc, self.key = None, None

    def close(self, wait: bool = True) -> None:
        """End the worker: its input closed, it stops its stack as Ctrl-C would and exits.
        ``wait=False``: the stack shuts down in the background (the next cell's stack starts
        meanwhile, with ports of its own)."""
        proc = self.proc
        if proc is None:
            return
        self.proc, self.key = None, None
        try:
            proc.stdin.close()
        except OSError:
            pass

        def reap() -> None:
            for _ in proc.stdout:
                pass
            proc.wait()
            self.stopper.discard(proc)
        if wait:
            reap()
        else:
            threading.Thread(target=reap, name="worker-stop", daemon=True).start()


class CellQueue:
    """The grid's cells, handed out in order as each becomes ready: a robot cell once every
    ``no_robot`` cell of its stream (human model, seed) in the grid is over (the human alone
    comes first); ``gate(cell)`` then gives the cell to run (fewer episodes, or None:
    nothing left). :meth:`take` prefers a cell the asking worker's running stack can take."""

    def __init__(self, cells: Sequence[CellSpec], lock: threading.Lock,
                 gate: Optional[Callable[[CellSpec], Optional[CellSpec]]] = None,
                 stopper: Optional["Stopper"] = None) -> None:
        self._waiting = list(cells)
        self._gate = gate
        self._stopper = stopper
        self._ready = threading.Condition(lock)
        self._alone_left: Dict[Tuple[str, int], int] = defaultdict(int)
        for cell in cells:
            if cell.robot_policy == ALONE_POLICY:
                self._alone_left[(cell.human_model, cell.seed)] += 1

    def _is_ready(self, cell: CellSpec) -> bool:
        return cell.robot_policy == ALONE_POLICY or \
            self._alone_left.get((cell.human_model, cell.seed), 0) == 0

    def take(self, worker: Optional[StackKeeper] = None,
             on_wait: Optional[Callable[[], None]] = None) -> Optional[CellSpec]:
        """The next cell to play (blocking until one is ready), or None when none is left or
        the run stops. ``on_wait()`` is called once, the queue unlocked, before it first
        waits."""
        with self._ready:
            while True:
                if self._stopper is not None and self._stopper.stopping:
                    return None
                ready = [c for c in self._waiting if self._is_ready(c)]
                if not ready and not self._waiting:
                    return None
                if ready:
                    fits = [c for c in ready if worker is not None and worker.warm_for(c)]
                    cell = (fits or ready)[0]
                    self._waiting.remove(cell)
                    if cell.robot_policy != ALONE_POLICY and self._gate is not None:
                        cell = self._gate(cell)
                        if cell is None:
                            continue
                    return cell
                if on_wait is not None:
                    self._ready.release()
                    try:
                        on_wait()
                    finally:
                        self._ready.acquire()
                    on_wait = None
                    continue
                self._ready.wait(1.0)    # a human-alone cell still plays

    def done(self, cell: CellSpec) -> None:
        """``cell`` is over (recorded, failed or stopped): the robot cells of its stream may
        start once it was the last human-alone cell there."""
        with self._ready:
            if cell.robot_policy == ALONE_POLICY:
                self._alone_left[(cell.human_model, cell.seed)] -= 1
            self._ready.notify_all()


def play_cell(worker: StackWorker, cell: CellSpec, deliver: Deliver, log: TextIO,
              program: str) -> None:
    """Play one cell on ``worker`` in attempts (:class:`~ros_hrc.experiment.attempts.CellAttempts`):
    a stack that fails (a port taken by another program between its pick and its bind, a node
    that died, a warm stack that did not take the cell) is replaced and the episodes still
    missing run again on a new one, up to :data:`~ros_hrc.experiment.attempts.MAX_ATTEMPTS`
    attempts, each said in one line; then RuntimeError with the last reason. A cell whose
    settings were refused fails at once. An episode that cannot be recorded (a full disk) is
    not retried: its OSError goes up at once."""
    attempts = CellAttempts(cell, deliver, log, program)

    def attempt(number: int, spec: CellSpec) -> Tuple[str, Sequence[str]]:
        attempts.began(number, len(spec.episodes))
        try:
            worker.play(spec, attempts.take, log)
        except CellRefused as exc:
            raise RuntimeError(f"refused: {exc}") from None
        except RuntimeError as exc:
            if worker.stopper.check_disks():
                return "", ()       # no retry: the run stops for the full disk
            return str(exc), ()
        return "", ()

    attempts.run(attempt, worker.stopper, again="run again on a new stack")


def run_grid(cells: List[CellSpec], store, jobs: int,
             stopper: Optional[Stopper] = None, *, program: str,
             gate: Optional[Callable[[CellSpec], Optional[CellSpec]]] = None,
             remote=None, fresh_stacks: bool = False,
             status: Callable[[], str] = lambda: "") -> dict:
    """Play the cells on ``jobs`` workers, each owning one stack that plays cell after cell
    (:class:`StackWorker`; ``fresh_stacks``: a new stack per cell), and record episodes as
    they come (``store.add(row, steps)``). Returns run figures. ``program`` names the
    progress bar and the messages (hrc_fit runs grids too). Cells come from a
    :class:`CellQueue` (the human alone first; ``gate``). ``remote``: a
    :class:`ros_hrc.experiment.cluster.ClusterRun`: the cells play on the cluster instead,
    each lane on a Ray actor that keeps its stack on a node
    (:class:`~ros_hrc.experiment.cluster.NodeLane`); ``status()`` leads the progress bar's
    text."""
    stopper = stopper or Stopper()
    progress = Progress(store, sum(len(c.episodes) for c in cells), program, status,
                        unit="sequence" if cells[0].sequence else "episode")
    queue = CellQueue(cells, progress.lock, gate, stopper)

    def record(cell: CellSpec, play: Callable[[TextIO], None]) -> None:
        """Play ``cell`` (``play(log)``) with its worker log open; a failure is the cell's,
        or the run's when a disk is full."""
        name = cell_name(cell)
        try:
            cell_logs = Path(cell.log_dir)
            cell_logs.mkdir(parents=True, exist_ok=True)
            with open(cell_logs / f"{name}.worker.log", "a") as log:
                play(log)
        except (RuntimeError, OSError) as exc:
            if not stopper.check_disks(exc):
                progress.cell_failed(name, exc)

    def local_lane() -> None:
        worker = StackWorker(stopper, fresh=fresh_stacks)
        try:
            while (cell := queue.take(worker)) is not None:
                try:
                    record(cell, lambda log: play_cell(worker, cell, progress.deliver, log,
                                                       program))
                finally:
                    queue.done(cell)
        finally:
            worker.close()

    def cluster_lane() -> None:
        lane = remote.lane(stopper, fresh=fresh_stacks)
        try:
            # While it waits for a cell to be ready, its actor's slot goes to a lane that has
            # one: a lane whose node was lost waits for a slot, and may hold the very cell
            # this one waits for.
            while (cell := queue.take(lane, on_wait=lane.close)) is not None:
                try:
                    record(cell, lambda log: lane.run_cell(cell, progress.deliver, log))
                finally:
                    queue.done(cell)
        finally:
            lane.close()

    with progress:
        watcher = DiskWatcher(stopper)
        try:
            lanes = remote.in_flight_limit if remote is not None else max(1, jobs)
            lane = local_lane if remote is None else cluster_lane
            with ThreadPoolExecutor(max_workers=lanes, thread_name_prefix="lane") as pool:
                for future in [pool.submit(lane) for _ in range(lanes)]:
                    future.result()
        finally:
            watcher.stop()
    return progress.figures(jobs)


class DiskWatcher:
    """Looks every :data:`~ros_hrc.experiment.disk.CHECK_INTERVAL` seconds whether a disk
    under the run is full (``stopper.check_disks``), until :meth:`stop`."""

    def __init__(self, stopper: Stopper) -> None:
        self._over = threading.Event()
        self._stopper = stopper
        self._thread = threading.Thread(target=self._watch, name="disk-watch", daemon=True)
        self._thread.start()

    def _watch(self) -> None:
        while not self._over.wait(CHECK_INTERVAL) and not self._stopper.check_disks():
            pass

    def stop(self) -> None:
        self._over.set()
        self._thread.join()


def run_stoppable(cells: List[CellSpec], store, jobs: int, words: Sequence[str],
                  out: Path, *, program: str,
                  gate: Optional[Callable[[CellSpec], Optional[CellSpec]]] = None,
                  cluster: Optional[str] = None, cluster_wait: Optional[float] = None,
                  fresh_stacks: bool = False) -> Tuple[Optional[dict], Optional[int]]:
    """:func:`run_grid` under SIGINT and SIGTERM: ``(figures, None)``, or, when a signal
    stopped it, ``(None, 128 + signal)`` after saying what is kept and how to resume.
    ``cluster`` (``--cluster``): the cells run on Ray actors there
    (:mod:`ros_hrc.experiment.cluster`, the only place Ray is imported); a cluster that cannot
    be joined is one line and ``(None, 2)``. A full disk under the run (``out``'s, or
    ``$ROS_HOME``'s) stops it as a signal does: one line naming the disk, ``(None, 1)``."""
    stopper = Stopper(DiskWatch.of_run(out))
    figures = None
    remote = None
    try:
        if cluster is not None:
            from ros_hrc.experiment.cluster import ClusterRun
            # Joined before the handlers go in: ray.init installs its own for SIGTERM.
            remote = ClusterRun(cluster, program, slots=jobs,
                                **({} if cluster_wait is None else {"no_node_wait": cluster_wait}))
            try:
                remote.connect()
            except HrcError as exc:
                print(f"{program}: {' '.join(str(exc).split())}", file=sys.stderr, flush=True)
                return None, 2
        stopper.install()
        try:
            if remote is None:
                figures = run_grid(cells, store, jobs, stopper, program=program, gate=gate,
                                   fresh_stacks=fresh_stacks)
            else:
                figures = run_grid(cells, store, remote.in_flight_limit, stopper,
                                   program=program, gate=gate, remote=remote,
                                   fresh_stacks=fresh_stacks, status=remote.status)
                figures["cluster"] = remote.report()
        finally:
            stopper.uninstall()
    except KeyboardInterrupt:   # a signal before the handlers were in place
        stopper.stop(signal.SIGINT)
    finally:
        if remote is not None:
            remote.close()
    if not stopper.stopping:
        return figures, None
    command = shlex.join([program] + list(words))
    if stopper.disk_full is not None:
        say_last(full_disk_line(program, stopper.disk_full, len(store.done()), out, command,
                                store.UNIT))
        return None, 1
    name = signal.Signals(stopper.signum).name  # type: ignore[arg-type]
    unit = store.UNIT
    print(f"\n{program}: stopped by {name}; {len(store.done())} {unit} are kept in {out}. "
          f"Resume with: {command}", file=sys.stderr, flush=True)
    return None, 128 + int(stopper.signum)  # type: ignore[arg-type]


def finish_run(program: str, figures: Optional[dict], store, out: Path, words: Sequence[str],
               write_report: Callable[[List[Path]], None]) -> int:
    """A run's end, the same for episodes and sequences: ``run.json`` (when cells ran) and the
    report (``write_report``, given what was written before it, to list with its own files)
    written; a full disk under them is one line and status 1 (every row is kept, and the same
    command writes what is missing); failed cells are one line and status 1 (run again to
    retry them). The exit status."""
    try:
        written: List[Path] = []
        if figures:
            write_text_atomically(out / "run.json", json.dumps(figures, indent=2) + "\n")
            written.append(out / "run.json")
        write_report(written)
    except OSError as exc:
        if not is_full_disk(exc):
            raise
        # Each file is whole or not there (written beside, then renamed).
        say_last(full_disk_line(program, DiskFull.of_error(exc), len(store.done()), out,
                                shlex.join([program] + list(words)), store.UNIT))
        return 1
    if figures and figures["failed_cells"]:
        print(f"{program}: {len(figures['failed_cells'])} cells failed (logs in "
              f"{out / 'logs'}); run again to retry them", file=sys.stderr, flush=True)
        return 1
    return 0


def say_written(program: str, out: Path, paths: Sequence[Union[str, os.PathLike]]) -> None:
    """One line: every file a run's end wrote (``paths``), named within ``out``, and the
    stacks' logs folder when there is one."""
    names = []
    for path in paths:
        path = Path(path)
        names.append(str(path.relative_to(out)) if path.is_relative_to(out) else str(path))
    if (out / "logs").is_dir():
        names.append("logs/ (each stack's log)")
    print(f"{program}: written in {out}: {', '.join(names)}", flush=True)


def say_last(line: str) -> None:
    """A run's last line on stderr; dropped when stderr itself is on the full disk."""
    try:
        print(line, file=sys.stderr, flush=True)
    except OSError:
        pass
