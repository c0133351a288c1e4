"""One cell run in attempts, on this machine's pool as on a cluster: a failed attempt (its stack
failed: a port taken between its pick and its bind, a node that died; on a cluster, its node
lost) is followed by another with only the episodes not yet delivered, on fresh ports, up to
:data:`MAX_ATTEMPTS`; then the cell fails with the last reason. Each episode is delivered
once. What one attempt is (a local worker's, a cluster actor's) is the caller's: it is handed
to :meth:`CellAttempts.run`. No ROS here.
"""
from __future__ import annotations

import dataclasses
import sys
from typing import Callable, Optional, Sequence, Set, TextIO, Tuple

from ros_hrc.experiment.rows import EpisodeRow, StepRow
from ros_hrc.experiment.stack import CellSpec, EpisodeRanges, cell_name, contains, without

#: Attempts per cell, on this machine's pool as on a cluster: a cell that fails this many
#: times (its stack failed, its node lost) is reported as failed, with its logs' last lines.
MAX_ATTEMPTS = 3

#: What a cell's episodes go to, one call per episode as it ends.
Deliver = Callable[[EpisodeRow, Sequence[StepRow]], None]
#: One attempt: given its number (from 1) and the cell with only its missing episodes, it runs
#: them, hands each to :meth:`CellAttempts.take`, and returns why it ended short ("" when it
#: cannot tell) and lines to write under that in the cell's log. Raising fails the cell at once.
Attempt = Callable[[int, CellSpec], Tuple[str, Sequence[str]]]


def say(text: str) -> None:
    """A line on stderr, above the progress bar of a grid when there is one."""
    try:
        from tqdm import tqdm
        tqdm.write(text, file=sys.stderr)
    except ImportError:
        print(text, file=sys.stderr, flush=True)


def _stopping(stopper) -> bool:
    return stopper is not None and stopper.stopping


class CellAttempts:
    """A cell's episodes, delivered once each (``deliver(row, steps)``) over its attempts;
    ``on_all_delivered()`` once the last one is in (its stack may still be shutting down).
    ``log`` is the cell's worker log; ``program`` names the command in its lines."""

    def __init__(self, cell: CellSpec, deliver: Deliver, log: TextIO, program: str,
                 on_all_delivered: Optional[Callable[[], None]] = None) -> None:
        self.cell = cell
        self.name = cell_name(cell)
        self.wanted = EpisodeRanges.of(cell.episodes)
        self.delivered: Set[int] = set()
        self.log = log
        self.program = program
        self._deliver = deliver
        self._on_all_delivered = on_all_delivered

    @property
    def complete(self) -> bool:
        """Whether every episode of the cell is delivered."""
        return len(self.delivered) == len(self.wanted)

    def began(self, number: int, episodes: int, where: str = "") -> None:
        """Write in the cell's log that attempt ``number`` runs ``episodes`` episodes
        (``where``: on which node, and where its logs are)."""
        self.log.write(f"{self.program}: {self.name}: attempt {number} of {MAX_ATTEMPTS} "
                       f"({episodes} episodes){where}\n")
        self.log.flush()

    def take(self, row: EpisodeRow, steps: Sequence[StepRow]) -> bool:
        """Deliver one episode unless it is not the cell's or already delivered (an attempt
        that ran it again): each is counted once. Whether it was delivered."""
        if row.episode in self.delivered or not contains(self.wanted, row.episode):
            self.log.write(f"{self.program}: episode {row.key} came again; dropped\n")
            return False
        self._deliver(row, steps)
        self.delivered.add(row.episode)
        if self.complete and self._on_all_delivered is not None:
            self._on_all_delivered()
        return True

    def run(self, attempt: Attempt, stopper=None, again: str = "run again", where: str = "",
            on_retry: Optional[Callable[[], None]] = None) -> None:
        """Run attempts until every episode is in, the run stops (``stopper.stopping``) or
        :data:`MAX_ATTEMPTS` failed: then RuntimeError ``failed N times<where>, the last:
        <why>``. Each failure is written in the cell's log, a retry said on stderr (its
        missing episodes ``again``); ``on_retry()`` before each retry."""
        failure, number = "", 0
        while number < MAX_ATTEMPTS and not self.complete:
            if _stopping(stopper):
                return
            number += 1
            missing = without(self.wanted, self.delivered)
            failure, details = attempt(number, dataclasses.replace(self.cell, episodes=missing))
            if self.complete or _stopping(stopper):
                return
            failure = failure or "the worker ended without all its episodes"
            self.log.write(f"{self.program}: {self.name}: attempt {number} failed: {failure}\n")
            self.log.writelines(f"  {line}\n" for line in details)
            self.log.flush()
            if number < MAX_ATTEMPTS:
                if on_retry is not None:
                    on_retry()
                say(f"{self.program}: cell {self.name}: {failure}; its "
                    f"{len(self.wanted) - len(self.delivered)} episodes still missing {again} "
                    f"(attempt {number + 1} of {MAX_ATTEMPTS})")
        if not self.complete:
            raise RuntimeError(f"failed {number} times{where}, the last: "
                               f"{failure.removeprefix('failed: ')}")
