"""Where a run's episodes go as its cells deliver them: the results directory locked for the
run, the human alone on each stream (:class:`AloneEpisodes`), every robot episode set against
it (:class:`PairedRecorder`), and the run's progress (:class:`Progress`: the bar, the figures,
the failed cells). No ROS here.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import threading
import time
from collections import defaultdict
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Set, Tuple

from ros_hrc.experiment.episode import ALONE_POLICY, pair, pair_alone, stream_of
from ros_hrc.experiment.grid import ALONE_DIRECTORY, GridError
from ros_hrc.experiment.lock import DirectoryLock, DirectoryLocked, lock_directory
from ros_hrc.experiment.rows import EpisodeRow, StepRow
from ros_hrc.experiment.stack import CellSpec, EpisodeRanges
from ros_hrc.experiment.store import ResultsStore


class AloneEpisodes:
    """The human alone on each stream: ``no_robot`` rows by (human model, seed, episode),
    from the grid's own ``no_robot`` rows and from ``<out>/alone/`` (episodes run only for
    the counterfactual). Recorded once per stream, reused by every policy and resumed run."""

    def __init__(self, store: ResultsStore, out: Path, grid_has_alone: bool) -> None:
        self.store = store
        self.grid_has_alone = grid_has_alone
        self.directory = out / ALONE_DIRECTORY
        self._own: Optional[ResultsStore] = None
        self.rows: Dict[Tuple[str, int, int], EpisodeRow] = {}
        if self.directory.exists():
            self._own = ResultsStore(self.directory)
            for row in self._own.episodes():
                self.rows[stream_of(row)] = row
        for row in store.episodes():
            if row.robot_policy == ALONE_POLICY:
                self.rows[stream_of(row)] = row

    @property
    def own_store(self) -> ResultsStore:
        if self._own is None:
            self._own = ResultsStore(self.directory)
        return self._own

    def episodes_of(self, human: str, seed: int) -> Set[int]:
        return {e for (h, s, e) in self.rows if (h, s) == (human, seed)}

    def adopt_into_grid(self, args: argparse.Namespace) -> int:
        """With ``no_robot`` in the grid: its episodes already run for the counterfactual
        (``<out>/alone/``) become the grid's rows, steps included, instead of running again.
        Returns how many were adopted."""
        if not self.grid_has_alone or self._own is None:
            return 0
        done = self.store.done()
        wanted = [row for row in self._own.episodes()
                  if row.human_model in args.human_models and row.seed in args.seeds
                  and row.episode < args.episodes and row.key not in done]
        if not wanted:
            return 0
        steps: Dict[tuple, List[StepRow]] = defaultdict(list)
        keys = {row.key for row in wanted}
        for step in self._own.steps():
            if step.key in keys:
                steps[step.key].append(step)
        for row in wanted:
            self.store.add(row, steps[row.key])
        return len(wanted)

    def add(self, row: EpisodeRow, steps: Sequence[StepRow]) -> EpisodeRow:
        """Record a ``no_robot`` episode (paired with itself) where it belongs."""
        row = pair_alone(row)
        (self.store if self.grid_has_alone else self.own_store).add(row, steps)
        self.rows[stream_of(row)] = row
        return row


class PairedRecorder:
    """What the cells' episodes go through: a ``no_robot`` episode is the human alone
    (:class:`AloneEpisodes`); any other is set against it (:func:`episode.pair`), marked
    ``in_sample`` when its robot model was fitted on that stream, and stored."""

    UNIT = ResultsStore.UNIT    # what a row is, in the run's messages (as its store's)

    def __init__(self, store: ResultsStore, alone: AloneEpisodes,
                 in_sample: Optional[Dict[Tuple[str, str, int], Set[int]]] = None) -> None:
        self.store = store
        self.alone = alone
        self.in_sample = in_sample or {}

    def add(self, row: EpisodeRow, steps: Sequence[StepRow]) -> None:
        if row.robot_policy == ALONE_POLICY:
            self.alone.add(row, steps)
            return
        alone = self.alone.rows.get(stream_of(row))
        if alone is None:   # the gate runs only streams whose alone episode is in
            raise RuntimeError(f"episode {row.key}: no human-alone episode on its stream")
        marked = row.episode in self.in_sample.get((row.robot_policy, row.human_model,
                                                    row.seed), ())
        self.store.add(pair(row, alone, in_sample=marked), steps)

    def done(self) -> Set[Tuple[str, str, int, int]]:
        return self.store.done()

    def gate(self, cell: CellSpec) -> Optional[CellSpec]:
        """A robot cell's episodes restricted to the streams whose alone episode is in (an
        alone cell that failed leaves its streams for the next run); None if none is."""
        if cell.robot_policy == ALONE_POLICY:
            return cell
        have = self.alone.episodes_of(cell.human_model, cell.seed)
        kept = EpisodeRanges.of(e for e in cell.episodes if e in have)
        if not kept:
            return None
        return dataclasses.replace(cell, episodes=kept)


def open_results(directory: Path, argument: str) -> DirectoryLock:
    """The lock of a results directory (:func:`lock_directory`), or an HrcError in one line
    naming ``argument`` (another run holds it, or it cannot be made)."""
    try:
        return lock_directory(directory)
    except DirectoryLocked as exc:
        raise GridError(str(exc)) from None
    except OSError as exc:
        raise GridError(f"{argument} {directory}: {exc.strerror or exc}") from None


class Progress:
    """A run's episodes as its cells' threads deliver them (:meth:`deliver`): each recorded
    (``store.add(row, steps)``), counted into the run's figures and shown on the progress bar
    (named ``program``; ``status()`` leads its text); and the cells that failed
    (:meth:`cell_failed`), each said above the bar. :attr:`lock` guards all of it, and
    whatever else the run's threads share. Used as a ``with`` block: the bar's lifetime."""

    def __init__(self, store, total: int, program: str,
                 status: Callable[[], str] = lambda: "", unit: str = "episode") -> None:
        self.store = store
        self.total = total
        self.program = program
        self.status = status
        self.unit = unit
        self.lock = threading.Lock()
        self.started = time.monotonic()
        self.episodes = 0
        self.simulated_seconds = 0.0
        self.failures: List[str] = []
        self._bar = None

    def __enter__(self) -> "Progress":
        from tqdm import tqdm
        self._bar = tqdm(total=self.total, unit=self.unit, desc=self.program,
                         dynamic_ncols=True, mininterval=0.5 if sys.stderr.isatty() else 10.0)
        return self

    def __exit__(self, *exc: object) -> None:
        self._bar.close()

    def deliver(self, row: EpisodeRow, steps: Sequence[StepRow]) -> None:
        """Record one episode and show it."""
        with self.lock:
            self.store.add(row, steps)
            self.episodes += 1
            self.simulated_seconds += row.sim_seconds
            self._bar.set_postfix_str(f"{self.status()}{row.progress_text()}")
            self._bar.update(1)

    def cell_failed(self, name: str, reason: Exception) -> None:
        """Keep a failed cell's reason and say it above the bar."""
        with self.lock:
            self.failures.append(f"{name}: {reason}")
            self._bar.write(f"{self.program}: cell failed: {self.failures[-1]}")

    def figures(self, jobs: int) -> dict:
        """The run's figures (run.json), its wall time up to now."""
        wall = time.monotonic() - self.started
        episodes, sim = self.episodes, self.simulated_seconds
        return {"episodes": episodes, "planned": self.total, "wall_seconds": wall,
                "simulated_seconds": sim, "failed_cells": self.failures, "jobs": jobs,
                "episodes_per_minute": episodes / wall * 60.0 if wall > 0 else 0.0,
                "speedup_over_real_time": sim / wall if wall > 0 else 0.0}
