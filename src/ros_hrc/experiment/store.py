"""The results of an experiment on disk: the CSV store of its rows, which a run resumes from.

No ROS, no PyBullet, plain Python. The runner hands finished rows over
(:mod:`ros_hrc.experiment.rows`); one run at a time writes a directory
(:mod:`ros_hrc.experiment.lock`).

:class:`ResultsStore` owns ``episodes.csv`` and ``steps.csv`` in one directory. Each
:meth:`~ResultsStore.add` appends an episode's steps, then its episode row, and fsyncs each
file, so the episode row is the commit mark: after a kill, :meth:`~ResultsStore.done` lists
exactly the episodes that are complete, and the runner resumes with the others. On open,
both files are checked whole first (UTF-8 text, the header, every row; a file that is
not, a binary one say, is refused naming it, and nothing is changed); only then is a
partially written last line cut off and step rows of an episode that has no episode row
(killed between the two writes) removed, each with a :class:`ResultsWarning`.
"""
from __future__ import annotations

import csv
import io
import os
import warnings
from typing import Iterable, List, Optional, Sequence, Set, Tuple, Type, TypeVar, Union

from ros_hrc.experiment.rows import EpisodeKey, EpisodeRow, Row, StepRow

EPISODES_FILE = "episodes.csv"
STEPS_FILE = "steps.csv"

_R = TypeVar("_R", bound=Row)


class ResultsWarning(UserWarning):
    """The store repaired a file on open (cut a partial line, dropped orphaned step rows)."""


def header_mismatch(path: str, header: Optional[Sequence[str]],
                    columns: Sequence[str]) -> str:
    """One line: ``path`` holds other columns than ``columns`` (results of another version,
    or not results at all); rows of two layouts are never mixed in one file."""
    if not header:
        return f"{path}:1: no header; expected the columns {', '.join(columns)}"
    missing = [c for c in columns if c not in header]
    extra = [c for c in header if c not in columns]
    if set(header) == set(columns):
        why = "the same columns in another order"
    else:
        why = "; ".join(part for part in (
            f"missing {', '.join(missing)}" if missing else "",
            f"unknown {', '.join(extra[:5])}{' ...' if len(extra) > 5 else ''}" if extra else "")
            if part)
    return (f"{path}:1: written with other columns ({why}): results of another version are "
            "not mixed with these; choose another directory or move this one away")


def csv_lines(columns: Sequence[str], rows: Iterable[Row] = (), header: bool = False) -> str:
    """``rows`` as the lines of a results file (``\\n``-ended), its header first if asked."""
    text = io.StringIO()
    writer = csv.DictWriter(text, columns, lineterminator="\n")
    if header:
        writer.writeheader()
    writer.writerows(row.as_dict() for row in rows)
    return text.getvalue()


def _fsync_directory(directory: str) -> None:
    """Make a file's creation (or replacement) durable, not only its contents."""
    fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class ResultsStore:
    """``episodes.csv`` and ``steps.csv`` in ``directory``, appended to as episodes finish.

    Opening checks both files (header, every row) and raises ValueError ``"<file>:<line>: ..."``
    on the first problem; it repairs only what a kill can leave behind (see the module doc).

    The same store holds any unit that is written as its parts, then one row that commits
    them: a subclass names the two row types and files (:class:`ROW_TYPE` in
    :data:`ROWS_FILE` commits :class:`PART_TYPE` rows in :data:`PARTS_FILE`; a sequence
    commits its tasks, :mod:`ros_hrc.experiment.sequence_rows`).
    """

    ROW_TYPE: Type[Row] = EpisodeRow
    PART_TYPE: Type[Row] = StepRow
    ROWS_FILE = EPISODES_FILE
    PARTS_FILE = STEPS_FILE
    UNIT = "episodes"     # what a row is, in the run's messages

    def __init__(self, directory: Union[str, os.PathLike]) -> None:
        self.directory = os.fspath(directory)
        os.makedirs(self.directory, exist_ok=True)
        self.episodes_path = os.path.join(self.directory, self.ROWS_FILE)
        self.steps_path = os.path.join(self.directory, self.PARTS_FILE)
        # Everything is checked before anything is changed: a bad file (binary, another
        # header, a bad row) is refused with both files as they were.
        plans = [self._inspect(path) for path in (self.episodes_path, self.steps_path)]
        (_, episodes_text), (_, steps_text) = plans
        episodes = self._parse(self.episodes_path, episodes_text, self.ROW_TYPE)
        steps = self._parse(self.steps_path, steps_text, self.PART_TYPE)
        self._done: Set[EpisodeKey] = set()
        for line, row in episodes:
            if row.key in self._done:
                raise ValueError(f"{self.episodes_path}:{line}: episode {row.key} recorded twice")
            self._done.add(row.key)
        for (path, columns), (keep, text) in zip(
                ((self.episodes_path, self.ROW_TYPE.COLUMNS),
                 (self.steps_path, self.PART_TYPE.COLUMNS)), plans):
            self._repair(path, columns, keep, text)
        self._drop_orphan_steps(steps)

    # -- opening ------------------------------------------------------------------------------

    @staticmethod
    def _inspect(path: str) -> Tuple[Optional[int], str]:
        """(where to cut a partial last line or None, the text kept) of a results file, read
        but not changed; ValueError naming the file when it is not UTF-8 text."""
        try:
            with open(path, "rb") as f:
                data = f.read()
        except FileNotFoundError:
            return None, ""
        nul = data.find(b"\0")
        if nul >= 0:
            raise ValueError(f"{path}: not a results CSV: binary data (a NUL byte at byte "
                             f"{nul}); left as it is")
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ValueError(f"{path}: not a results CSV: byte {exc.start} is not UTF-8 "
                             "text; left as it is") from None
        if data and not data.endswith(b"\n"):
            keep = data.rfind(b"\n") + 1  # 0 when even the header is partial
            return keep, data[:keep].decode("utf-8")
        return None, text

    def _repair(self, path: str, columns: Tuple[str, ...], keep: Optional[int],
                text: str) -> None:
        """Cut a partial last line (``keep``: bytes kept), and write the header into a
        missing or empty file."""
        if keep is not None:
            with open(path, "r+b") as f:
                data = f.read()
                lost = data[keep:].decode("utf-8", "replace")
                line = data.count(b"\n") + 1
                warnings.warn(f"{path}:{line}: dropped a partially written last line "
                              f"({len(lost)} characters: {lost[:60]!r}...)", ResultsWarning,
                              stacklevel=4)
                f.truncate(keep)
                f.flush()
                os.fsync(f.fileno())
        if text:
            return
        with open(path, "w", encoding="utf-8", newline="") as f:
            f.write(csv_lines(columns, header=True))
            f.flush()
            os.fsync(f.fileno())
        _fsync_directory(self.directory)

    @classmethod
    def _read(cls, path: str, row_type: Type[_R]) -> List[Tuple[int, _R]]:
        """(line number, row) for every row of ``path``; ValueError ``path:line`` if bad."""
        keep, text = cls._inspect(path)
        return cls._parse(path, text, row_type)

    @staticmethod
    def _parse(path: str, text: str, row_type: Type[_R]) -> List[Tuple[int, _R]]:
        """(line number, row) for every row of a results file's ``text`` (empty: a file not
        written yet); ValueError ``path:line`` if bad."""
        columns = row_type.COLUMNS
        out: List[Tuple[int, _R]] = []
        if not text:
            return out
        with io.StringIO(text, newline="") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            if header is None or tuple(header) != columns:
                raise ValueError(header_mismatch(path, header, columns))
            for cells in reader:
                # Strings hold no line breaks, so the reader's line number is the file's.
                line = reader.line_num
                if not cells:
                    continue  # a blank line carries nothing
                if len(cells) != len(columns):
                    raise ValueError(f"{path}:{line}: {len(cells)} cells, expected "
                                     f"{len(columns)}")
                try:
                    out.append((line, row_type.from_dict(dict(zip(columns, cells)))))
                except ValueError as e:
                    raise ValueError(f"{path}:{line}: {e}") from None
        return out

    def _drop_orphan_steps(self, steps: List[Tuple[int, "StepRow"]]) -> None:
        """Remove step rows of episodes without an episode row (written before a kill).

        Left in place, the rerun of that episode would append its steps a second time.
        """
        kept = [row for _, row in steps if row.key in self._done]
        if len(kept) == len(steps):
            return
        orphans = sorted({row.key for _, row in steps if row.key not in self._done})
        warnings.warn(f"{self.steps_path}: dropped {len(steps) - len(kept)} step rows of "
                      f"{len(orphans)} unfinished episode(s) {orphans}", ResultsWarning,
                      stacklevel=3)
        # Rewrite beside the file and swap it in, so a kill now leaves the old or the new one.
        tmp = self.steps_path + ".tmp"
        with open(tmp, "w", encoding="utf-8", newline="") as f:
            f.write(csv_lines(self.PART_TYPE.COLUMNS, kept, header=True))
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self.steps_path)
        _fsync_directory(self.directory)

    # -- use ----------------------------------------------------------------------------------

    def done(self) -> Set[EpisodeKey]:
        """Keys (human_model, robot_policy, seed, episode) of the episodes already recorded."""
        return set(self._done)

    def add(self, episode_row: EpisodeRow, step_rows: Iterable[StepRow] = ()) -> None:
        """Append one finished episode and its steps, durably, before returning.

        Steps go first and the episode row last, so an episode counts as done only when all
        of it is on disk. Raises ValueError for an episode already recorded or a step row of
        another episode; on an I/O error the files are cut back to where they were.
        """
        if not isinstance(episode_row, self.ROW_TYPE):
            raise TypeError(f"expected an {self.ROW_TYPE.__name__}, got "
                            f"{type(episode_row).__name__}")
        key = episode_row.key
        if key in self._done:
            raise ValueError(f"episode {key} is already recorded in {self.episodes_path}")
        step_rows = list(step_rows)
        for i, row in enumerate(step_rows):
            if not isinstance(row, self.PART_TYPE):
                raise TypeError(f"step row {i}: expected a {self.PART_TYPE.__name__}, got "
                                f"{type(row).__name__}")
            if row.key != key:
                raise ValueError(f"step row {i} belongs to episode {row.key}, not {key}")
        self._append(self.steps_path, self.PART_TYPE.COLUMNS, step_rows)
        self._append(self.episodes_path, self.ROW_TYPE.COLUMNS, [episode_row])
        self._done.add(key)

    @staticmethod
    def _append(path: str, columns: Tuple[str, ...], rows: Sequence[Row]) -> None:
        data = csv_lines(columns, rows).encode("utf-8")
        if not data:
            return
        with open(path, "ab") as f:
            start = f.tell()
            try:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            except BaseException:
                # A half-written block would read as an orphan or partial line later; cut it
                # now so a caller that retries does not duplicate rows.
                f.truncate(start)
                raise

    def episodes(self) -> List[EpisodeRow]:
        """Every recorded episode, in the order they were added."""
        return [row for _, row in self._read(self.episodes_path, self.ROW_TYPE)]

    def steps(self) -> List[StepRow]:
        """Every recorded step, in the order they were added."""
        return [row for _, row in self._read(self.steps_path, self.PART_TYPE)]



def ensure_parent(path: str) -> None:
    """Create the folder a file is about to be written to."""
    parent = os.path.dirname(path)
    if parent:
        os.makedirs(parent, exist_ok=True)
