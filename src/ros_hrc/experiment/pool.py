"""The local pool: an experiment grid's cells run side by side, one stack each, under SIGINT
and SIGTERM (:func:`run_stoppable`; on a cluster, the same schedule with
:class:`ros_hrc.experiment.cluster.ClusterRun` running each cell). No ROS here.

``jobs`` cells step at a time; the human alone (``no_robot``) on a stream runs before the
robots' episodes of that stream; a cell whose episodes are all in gives its place to the next
one while its stack shuts down. Each cell runs in its own worker process
(:func:`ros_hrc.experiment.stack.worker_command`), in up to three attempts
(:mod:`ros_hrc.experiment.attempts`). SIGINT or SIGTERM stops every cell's stack
(:class:`Stopper`), keeps what was recorded and says how to resume; so does a full disk under
the run (:mod:`ros_hrc.experiment.disk`: the results' disk or ``$ROS_HOME``'s without room,
or a write of the run's own that found none), in one line naming the disk.
"""
from __future__ import annotations

import functools
import json
import shlex
import signal
import subprocess
import sys
import threading
from collections import defaultdict
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Set, TextIO, Tuple

from ros_hrc.errors import HrcError
from ros_hrc.experiment.attempts import CellAttempts, Deliver
from ros_hrc.experiment.disk import (CHECK_INTERVAL, DiskFull, DiskWatch, full_disk_line,
                                     is_full_disk)
from ros_hrc.experiment.episode import ALONE_POLICY
from ros_hrc.experiment.recording import Progress
from ros_hrc.experiment.stack import (CellSpec, cell_name, decode_episode, worker_command,
                                      write_spec)
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


def _run_worker(cell: CellSpec, deliver: Deliver, log: TextIO,
                stopper: Optional[Stopper] = None) -> None:
    """Run one attempt at a cell in its own process; ``deliver(row, steps)`` per episode as it
    ends. RuntimeError with the worker's last message when it fails (unless the run stops)."""
    spec_file = write_spec(cell, Path(cell.log_dir))
    proc = subprocess.Popen(worker_command(spec_file), stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if stopper is not None:
        stopper.add(proc)
    try:
        errors: List[str] = []
        reader = threading.Thread(target=lambda: errors.extend(proc.stderr), daemon=True)
        reader.start()
        for line in proc.stdout:
            try:
                episode = decode_episode(line)
            except (ValueError, KeyError) as exc:   # a line cut short: the episode reruns
                errors.append(f"unreadable episode line ({exc}): {line[:80]!r}\n")
                continue
            if episode is not None:
                deliver(*episode)
        proc.wait()
        reader.join(5.0)
    except BaseException:
        # An episode could not be recorded (a full disk): the worker must not run on, nor
        # its stack: SIGTERM makes it stop the stack; the reason goes up.
        Stopper._terminate(proc)
        for _ in proc.stdout:       # drained, so that its last lines never block it
            pass
        proc.wait()
        raise
    finally:
        if stopper is not None:
            stopper.discard(proc)
    if errors:
        log.write("".join(errors))
    if proc.returncode != 0 and not (stopper is not None and stopper.stopping):
        last = errors[-1].strip() if errors else f"exit code {proc.returncode}"
        raise RuntimeError(last)


def run_local_cell(cell: CellSpec, deliver: Deliver, log: TextIO,
                   stopper: Optional[Stopper] = None,
                   on_all_delivered: Optional[Callable[[], None]] = None, *,
                   program: str) -> None:
    """Run one cell on this machine, as :func:`_run_worker` does, in attempts
    (:class:`~ros_hrc.experiment.attempts.CellAttempts`): a failed one (its stack failed: a
    port taken by another program between its pick and its bind, a node that died) runs again
    with the episodes still missing, on fresh ports, up to
    :data:`~ros_hrc.experiment.attempts.MAX_ATTEMPTS` attempts, as on a cluster; then
    RuntimeError with the last reason. Each attempt is written in the cell's worker log, a
    retry said on stderr (``program`` names the command). An episode that cannot be recorded
    (a full disk) is not retried: its OSError goes up at once."""
    attempts = CellAttempts(cell, deliver, log, program, on_all_delivered)

    def attempt(number: int, spec: CellSpec) -> Tuple[str, Sequence[str]]:
        attempts.began(number, len(spec.episodes))
        try:
            _run_worker(spec, attempts.take, log, stopper)
        except RuntimeError as exc:
            if stopper is not None and stopper.check_disks():
                return "", ()       # no retry: the run stops for the full disk
            return str(exc), ()
        return "", ()

    attempts.run(attempt, stopper)


def run_grid(cells: List[CellSpec], store, jobs: int,
             stopper: Optional[Stopper] = None, *, program: str,
             gate: Optional[Callable[[CellSpec], Optional[CellSpec]]] = None,
             worker: Optional[Callable[..., None]] = None,
             status: Callable[[], str] = lambda: "") -> dict:
    """Run the cells side by side; record episodes as they come (``store.add(row, steps)``).
    Returns run figures. ``program`` names the progress bar and the messages (hrc_fit runs
    grids too). A robot cell starts once the ``no_robot`` cells of its (human model, seed) in
    ``cells`` are over (the human alone comes first); ``gate(cell)`` then gives the cell to
    run (fewer episodes, or None: nothing to run). ``worker`` runs one cell (by default
    :func:`run_local_cell`, local processes; on a cluster,
    :meth:`ros_hrc.experiment.cluster.ClusterRun.run_cell`); ``status()`` leads the progress
    bar's text."""
    worker = worker or functools.partial(run_local_cell, program=program)
    stopper = stopper or Stopper()
    progress = Progress(store, sum(len(c.episodes) for c in cells), program, status,
                        unit="sequence" if cells[0].sequence else "episode")
    lock = progress.lock   # the store, the bar and the schedule, from every worker's thread
    Path(cells[0].log_dir).mkdir(parents=True, exist_ok=True)
    with progress:
        # `jobs` cells step at a time. A cell whose episodes are all in gives its place to the
        # next one while its stack shuts down, so that start-up and shut-down overlap.
        stepping = threading.BoundedSemaphore(max(1, jobs))
        # The human alone first: a robot cell waits for the no_robot cells of its stream.
        alone_over: Dict[Tuple[str, int], threading.Event] = {}
        alone_left: Dict[Tuple[str, int], int] = defaultdict(int)
        for cell in cells:
            if cell.robot_policy == ALONE_POLICY:
                alone_over.setdefault((cell.human_model, cell.seed), threading.Event())
                alone_left[(cell.human_model, cell.seed)] += 1

        def alone_cell_over(cell: CellSpec, counted: List[bool]) -> None:
            key = (cell.human_model, cell.seed)
            with lock:
                if counted:
                    return
                counted.append(True)
                alone_left[key] -= 1
                if alone_left[key] == 0:
                    alone_over[key].set()

        def run(cell: CellSpec) -> None:
            if cell.robot_policy == ALONE_POLICY:
                counted: List[bool] = []
                try:
                    # Its robots may start once its episodes are in, while its stack stops.
                    run_cell(cell, lambda: alone_cell_over(cell, counted))
                finally:
                    alone_cell_over(cell, counted)
                return
            over = alone_over.get((cell.human_model, cell.seed))
            while over is not None and not over.wait(0.5):
                if stopper.stopping:
                    return
            if gate is not None:
                with lock:
                    gated = gate(cell)
                if gated is None:
                    return
                cell = gated
            run_cell(cell)

        def run_cell(cell: CellSpec, all_delivered: Callable[[], None] = lambda: None) -> None:
            stepping.acquire()
            released = threading.Event()

            def release() -> None:
                if not released.is_set():
                    released.set()
                    stepping.release()
                    all_delivered()
            try:
                if stopper.stopping:
                    return
                name = cell_name(cell)
                cell_logs = Path(cell.log_dir)
                try:
                    cell_logs.mkdir(parents=True, exist_ok=True)
                    with open(cell_logs / f"{name}.worker.log", "a") as log:
                        worker(cell, progress.deliver, log, stopper, on_all_delivered=release)
                except (RuntimeError, OSError) as exc:
                    # A full disk is no failure of this cell: the whole run stops for it.
                    if not stopper.check_disks(exc):
                        progress.cell_failed(name, exc)
            finally:
                release()

        over = threading.Event()

        def watch_disks() -> None:
            while not over.wait(CHECK_INTERVAL) and not stopper.check_disks():
                pass

        watcher = threading.Thread(target=watch_disks, name="disk-watch", daemon=True)
        watcher.start()
        try:
            with ThreadPoolExecutor(max_workers=2 * max(1, jobs)) as pool:
                list(pool.map(run, cells))
        finally:
            over.set()
            watcher.join()
    return progress.figures(jobs)


def run_stoppable(cells: List[CellSpec], store, jobs: int, words: Sequence[str],
                  out: Path, *, program: str,
                  gate: Optional[Callable[[CellSpec], Optional[CellSpec]]] = None,
                  cluster: Optional[str] = None, cluster_wait: Optional[float] = None
                  ) -> Tuple[Optional[dict], Optional[int]]:
    """:func:`run_grid` under SIGINT and SIGTERM: ``(figures, None)``, or, when a signal
    stopped it, ``(None, 128 + signal)`` after saying what is kept and how to resume.
    ``cluster`` (``--cluster``): the cells run as Ray tasks there
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
                figures = run_grid(cells, store, jobs, stopper, program=program, gate=gate)
            else:
                figures = run_grid(cells, store, remote.in_flight_limit, stopper,
                                   program=program, gate=gate, worker=remote.run_cell,
                                   status=remote.status)
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
               write_report: Callable[[], None]) -> int:
    """A run's end, the same for episodes and sequences: ``run.json`` (when cells ran) and the
    report (``write_report``) written; a full disk under them is one line and status 1 (every
    row is kept, and the same command writes what is missing); failed cells are one line and
    status 1 (run again to retry them). The exit status."""
    try:
        if figures:
            write_text_atomically(out / "run.json", json.dumps(figures, indent=2) + "\n")
        write_report()
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


def say_last(line: str) -> None:
    """A run's last line on stderr; dropped when stderr itself is on the full disk."""
    try:
        print(line, file=sys.stderr, flush=True)
    except OSError:
        pass
