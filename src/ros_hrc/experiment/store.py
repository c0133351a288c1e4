"""The results of an experiment on disk: rows, their CSV store, resume and the directory lock.

No ROS, no PyBullet, plain Python. The runner hands finished rows over.

Rows
    :class:`EpisodeRow` (one per episode, columns :data:`EPISODE_COLUMNS`) and
    :class:`StepRow` (one per step, :data:`STEP_COLUMNS`). Both are frozen dataclasses that
    check their values when built, so a bad row fails in the runner, not in the analysis.
    ``as_dict()`` gives the CSV cells as strings; ``from_dict()`` parses them back and raises
    ``ValueError`` naming the column and the value of a bad cell.

Store
    :class:`ResultsStore` owns ``episodes.csv`` and ``steps.csv`` in one directory. Each
    :meth:`~ResultsStore.add` appends an episode's steps, then its episode row, and fsyncs each
    file, so the episode row is the commit mark: after a kill, :meth:`~ResultsStore.done` lists
    exactly the episodes that are complete, and the runner resumes with the others. On open,
    both files are checked whole first (UTF-8 text, the header, every row; a file that is
    not, a binary one say, is refused naming it, and nothing is changed); only then is a
    partially written last line cut off and step rows of an episode that has no episode row
    (killed between the two writes) removed, each with a :class:`ResultsWarning`.

Lock
    One writer per directory: :func:`lock_directory` takes an exclusive, non-blocking
    ``flock`` on ``<directory>/.lock`` (which holds the owner's pid) for a whole run; a second
    run on the same directory gets :class:`DirectoryLocked`, naming the directory and the pid
    of the run that holds it, and has touched nothing.
"""
from __future__ import annotations

import csv
import errno
import fcntl
import io
import math
import operator
import os
import warnings
from dataclasses import dataclass, fields
from typing import (Any, ClassVar, Dict, Iterable, List, Mapping, Optional, Sequence, Set, Tuple,
                    Type, TypeVar, Union)

from ros_hrc.errors import HrcError
from ros_hrc.experiment.paired import OUTCOMES as PAIRED_OUTCOMES

EPISODE_COLUMNS: Tuple[str, ...] = (
    "human_model", "robot_policy", "seed", "episode", "success", "succeeded_by", "end_reason",
    "steps", "sim_seconds", "time_to_success", "alone_success", "alone_time_to_success",
    "outcome", "time_gain", "wasted_actions", "against_warning", "in_sample",
    "points", "warnings_after_help", "robot_discounted_reward", "intrusive_actions", "warnings",
    "zero_probability_observations", "mean_decision_ms", "wall_seconds")

STEP_COLUMNS: Tuple[str, ...] = (
    "human_model", "robot_policy", "seed", "episode", "step", "human_action", "human_state",
    "robot_state", "robot_action", "observation", "belief_needs_help", "needs_help",
    "zero_probability")

SUCCEEDED_BY: Tuple[str, ...] = ("human", "robot", "none")
#: The counterfactual outcomes (:data:`ros_hrc.experiment.paired.OUTCOMES`), and ``unpaired``:
#: an episode not (yet) set against the same human stream alone (a worker's row before the
#: driver pairs it; hrc_fit's exploring episodes, which are never paired).
UNPAIRED = "unpaired"
OUTCOME_VALUES: Tuple[str, ...] = PAIRED_OUTCOMES + (UNPAIRED,)
END_REASONS: Tuple[str, ...] = ("success", "object_left_belt", "step_limit")

#: What identifies an episode: (human_model, robot_policy, seed, episode).
EpisodeKey = Tuple[str, str, int, int]

EPISODES_FILE = "episodes.csv"
STEPS_FILE = "steps.csv"

# A belief computed in floating point may sum a hair past 1; more than this is a bug.
_BELIEF_TOLERANCE = 1e-6


class ResultsWarning(UserWarning):
    """The store repaired a file on open (cut a partial line, dropped orphaned step rows)."""


# --------------------------------------------------------------------------------------------
# Rows

_R = TypeVar("_R", bound="_Row")


def _convert(cls_name: str, name: str, kind: str, value: Any, parse: bool) -> Any:
    """``value`` as a ``kind`` ('str', 'int' or 'float'); strings are parsed only if ``parse``.

    Constructors do not parse (``seed="3"`` is a bug in the caller); ``from_dict`` does.
    """
    def bad(why: str) -> ValueError:
        return ValueError(f"{cls_name}: column {name!r}: bad value {value!r} ({why})")

    if kind == "str":
        if not isinstance(value, str):
            raise bad("expected a string")
        # One record per physical line: the store's line numbers and its partial-line repair
        # rely on it.
        if "\n" in value or "\r" in value:
            raise bad("line breaks are not allowed")
        return value
    if isinstance(value, str):
        if not parse:
            raise bad(f"expected {kind}, got a string")
        try:
            return int(value) if kind == "int" else float(value)
        except ValueError:
            raise bad(f"expected {kind}") from None
    if kind == "int":
        if isinstance(value, float):
            raise bad("expected int, got a float")
        try:
            return operator.index(value)  # int, bool, numpy integers
        except TypeError:
            raise bad("expected int") from None
    try:
        return float(value)
    except (TypeError, ValueError):
        raise bad("expected float") from None


class _Row:
    """Shared by the two row types: typed fields in CSV column order."""

    COLUMNS: ClassVar[Tuple[str, ...]] = ()

    def __post_init__(self) -> None:
        self._convert_fields(parse=False)
        self._check()

    def _convert_fields(self, parse: bool) -> None:
        for f in fields(self):  # type: ignore[arg-type]
            value = _convert(type(self).__name__, f.name, str(f.type), getattr(self, f.name), parse)
            object.__setattr__(self, f.name, value)  # frozen: set through object

    def _check(self) -> None:
        """Domain checks of the subclass; raise ValueError naming the column."""

    def _bad(self, name: str, why: str) -> ValueError:
        return ValueError(f"{type(self).__name__}: column {name!r}: bad value "
                          f"{getattr(self, name)!r} ({why})")

    def _nonempty(self, *names: str) -> None:
        for name in names:
            if not getattr(self, name):
                raise self._bad(name, "must not be empty")

    def _zero_one(self, *names: str) -> None:
        for name in names:
            if getattr(self, name) not in (0, 1):
                raise self._bad(name, "must be 0 or 1")

    def _non_negative(self, *names: str, finite: bool = True) -> None:
        for name in names:
            v = getattr(self, name)
            if finite and isinstance(v, float) and not math.isfinite(v):
                raise self._bad(name, "must be finite")
            if v < 0:
                raise self._bad(name, "must be >= 0")

    @property
    def key(self) -> EpisodeKey:
        """(human_model, robot_policy, seed, episode): the episode this row belongs to."""
        return (self.human_model, self.robot_policy, self.seed, self.episode)  # type: ignore

    def as_dict(self) -> Dict[str, str]:
        """The row as CSV cells, keyed by column; floats in their shortest exact form."""
        return {name: (repr(v) if isinstance(v, float) else str(v))
                for name, v in ((n, getattr(self, n)) for n in self.COLUMNS)}

    @classmethod
    def from_dict(cls: Type[_R], d: Mapping[str, Any]) -> _R:
        """Parse a row from CSV cells (strings) or typed values; extra keys are ignored.

        Raises ValueError naming the column and the value when a cell is missing or bad.
        """
        missing = [c for c in cls.COLUMNS if c not in d]
        if missing:
            raise ValueError(f"{cls.__name__}: missing column(s) {', '.join(missing)}")
        row = cls.__new__(cls)
        for name in cls.COLUMNS:
            object.__setattr__(row, name, d[name])
        row._convert_fields(parse=True)
        row._check()
        return row


@dataclass(frozen=True, eq=False)
class EpisodeRow(_Row):
    """One finished episode.

    success is 1 exactly when end_reason is ``success`` and succeeded_by is ``human`` or
    ``robot``; time_to_success is the simulated seconds from the episode's start to the
    success (NaN without one). The counterfactual columns set the episode against the same
    (human model, seed, episode) stream with ``no_robot`` (the human alone):
    alone_success, alone_time_to_success, outcome (one of :data:`OUTCOME_VALUES`) and
    time_gain = alone_time_to_success - time_to_success (NaN unless both succeed). in_sample
    is 1 when the robot's model was fitted on this stream. points counts the robot's points,
    warnings_after_help the warnings given right after its grasp or point
    (:func:`ros_hrc.experiment.episode.warnings_after_help`). mean_decision_ms may be NaN (a
    policy that timed no decisions); the other floats must be finite.
    """

    COLUMNS: ClassVar[Tuple[str, ...]] = EPISODE_COLUMNS

    human_model: str
    robot_policy: str
    seed: int
    episode: int
    success: int
    succeeded_by: str
    end_reason: str
    steps: int
    sim_seconds: float
    robot_discounted_reward: float
    intrusive_actions: int
    warnings: int
    zero_probability_observations: int
    mean_decision_ms: float
    wall_seconds: float
    # Defaults: an unpaired row that wasted nothing; time_to_success None is sim_seconds
    # for a success, NaN otherwise. (The CSV's column order is EPISODE_COLUMNS.)
    time_to_success: Optional[float] = None
    alone_success: int = 0
    alone_time_to_success: float = math.nan
    outcome: str = UNPAIRED
    time_gain: float = math.nan
    wasted_actions: int = 0
    against_warning: int = 0
    in_sample: int = 0
    points: int = 0
    warnings_after_help: int = 0

    def __eq__(self, other: object) -> bool:
        # As their CSV cells: NaN (no time without a success) equals NaN here.
        if not isinstance(other, EpisodeRow):
            return NotImplemented
        return self.as_dict() == other.as_dict()

    def __hash__(self) -> int:
        return hash(tuple(self.as_dict().values()))

    def __post_init__(self) -> None:
        if self.time_to_success is None:
            time = self.sim_seconds if self.success == 1 else math.nan
            object.__setattr__(self, "time_to_success", time)
        super().__post_init__()

    def _check(self) -> None:
        self._nonempty("human_model", "robot_policy")
        self._zero_one("success")
        if self.succeeded_by not in SUCCEEDED_BY:
            raise self._bad("succeeded_by", f"expected one of {', '.join(SUCCEEDED_BY)}")
        if self.end_reason not in END_REASONS:
            raise self._bad("end_reason", f"expected one of {', '.join(END_REASONS)}")
        # The three outcome columns say one thing three ways; disagreeing ones are a runner bug.
        if bool(self.success) != (self.end_reason == "success"):
            raise self._bad("success", f"contradicts end_reason {self.end_reason!r}")
        if bool(self.success) != (self.succeeded_by != "none"):
            raise self._bad("succeeded_by", f"contradicts success {self.success}")
        self._non_negative("seed", "episode", "steps", "sim_seconds", "intrusive_actions",
                           "warnings", "zero_probability_observations", "wall_seconds",
                           "wasted_actions", "against_warning", "points",
                           "warnings_after_help")
        self._zero_one("alone_success", "in_sample")
        if self.outcome not in OUTCOME_VALUES:
            raise self._bad("outcome", f"expected one of {', '.join(OUTCOME_VALUES)}")
        # A time exists exactly when its success does.
        for time_column, succeeded in (("time_to_success", self.success),
                                       ("alone_time_to_success", self.alone_success)):
            value = getattr(self, time_column)
            if self.outcome == UNPAIRED and time_column == "alone_time_to_success":
                succeeded = 0
            if succeeded and not (math.isfinite(value) and value >= 0):
                raise self._bad(time_column, "must be a time >= 0 when it succeeded")
            if not succeeded and not math.isnan(value):
                raise self._bad(time_column, "must be nan without a success")
        if self.outcome == UNPAIRED:
            if self.alone_success:
                raise self._bad("alone_success", "must be 0 in an unpaired row")
        else:
            from ros_hrc.experiment.paired import counterfactual_outcome
            expected = counterfactual_outcome(bool(self.alone_success), bool(self.success),
                                              self.succeeded_by)
            if self.outcome != expected:
                raise self._bad("outcome", f"contradicts alone_success {self.alone_success} "
                                           f"and succeeded_by {self.succeeded_by!r} "
                                           f"({expected})")
        both = self.success and self.alone_success and self.outcome != UNPAIRED
        if both and not math.isfinite(self.time_gain):
            raise self._bad("time_gain", "must be finite when both succeed")
        if not both and not math.isnan(self.time_gain):
            raise self._bad("time_gain", "must be nan unless both succeed")
        if not math.isfinite(self.robot_discounted_reward):
            raise self._bad("robot_discounted_reward", "must be finite")
        self._non_negative("mean_decision_ms", finite=False)
        if math.isinf(self.mean_decision_ms):
            raise self._bad("mean_decision_ms", "must be finite or nan")


@dataclass(frozen=True)
class StepRow(_Row):
    """One step of an episode.

    belief_needs_help is the robot's belief mass on the needs-help states S2..S5 (NaN for a
    policy without a belief); needs_help is 1 when the true robot state is one of them;
    zero_probability is 1 when the robot's model gave the step's observation probability 0.
    """

    COLUMNS: ClassVar[Tuple[str, ...]] = STEP_COLUMNS

    human_model: str
    robot_policy: str
    seed: int
    episode: int
    step: int
    human_action: str
    human_state: str
    robot_state: str
    robot_action: str
    observation: str
    belief_needs_help: float
    needs_help: int
    zero_probability: int

    def _check(self) -> None:
        self._nonempty("human_model", "robot_policy")
        self._non_negative("seed", "episode", "step")
        self._zero_one("needs_help")
        self._zero_one("zero_probability")
        b = self.belief_needs_help
        if not math.isnan(b) and not -_BELIEF_TOLERANCE <= b <= 1 + _BELIEF_TOLERANCE:
            raise self._bad("belief_needs_help", "must be a probability in [0, 1] or nan")



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


# --------------------------------------------------------------------------------------------
# Store

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
    """

    def __init__(self, directory: Union[str, os.PathLike]) -> None:
        self.directory = os.fspath(directory)
        os.makedirs(self.directory, exist_ok=True)
        self.episodes_path = os.path.join(self.directory, EPISODES_FILE)
        self.steps_path = os.path.join(self.directory, STEPS_FILE)
        # Everything is checked before anything is changed: a bad file (binary, another
        # header, a bad row) is refused with both files as they were.
        plans = [self._inspect(path) for path in (self.episodes_path, self.steps_path)]
        (_, episodes_text), (_, steps_text) = plans
        episodes = self._parse(self.episodes_path, episodes_text, EpisodeRow)
        steps = self._parse(self.steps_path, steps_text, StepRow)
        self._done: Set[EpisodeKey] = set()
        for line, row in episodes:
            if row.key in self._done:
                raise ValueError(f"{self.episodes_path}:{line}: episode {row.key} recorded twice")
            self._done.add(row.key)
        for (path, columns), (keep, text) in zip(((self.episodes_path, EPISODE_COLUMNS),
                                                  (self.steps_path, STEP_COLUMNS)), plans):
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
            csv.writer(f, lineterminator="\n").writerow(columns)
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
            writer = csv.writer(f, lineterminator="\n")
            writer.writerow(STEP_COLUMNS)
            for row in kept:
                writer.writerow(row.as_dict()[c] for c in STEP_COLUMNS)
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
        if not isinstance(episode_row, EpisodeRow):
            raise TypeError(f"expected an EpisodeRow, got {type(episode_row).__name__}")
        key = episode_row.key
        if key in self._done:
            raise ValueError(f"episode {key} is already recorded in {self.episodes_path}")
        step_rows = list(step_rows)
        for i, row in enumerate(step_rows):
            if not isinstance(row, StepRow):
                raise TypeError(f"step row {i}: expected a StepRow, got {type(row).__name__}")
            if row.key != key:
                raise ValueError(f"step row {i} belongs to episode {row.key}, not {key}")
        self._append(self.steps_path, STEP_COLUMNS, step_rows)
        self._append(self.episodes_path, EPISODE_COLUMNS, [episode_row])
        self._done.add(key)

    @staticmethod
    def _append(path: str, columns: Tuple[str, ...], rows: Sequence[_Row]) -> None:
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        for row in rows:
            cells = row.as_dict()
            writer.writerow(cells[c] for c in columns)
        data = buf.getvalue().encode("utf-8")
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
        return [row for _, row in self._read(self.episodes_path, EpisodeRow)]

    def steps(self) -> List[StepRow]:
        """Every recorded step, in the order they were added."""
        return [row for _, row in self._read(self.steps_path, StepRow)]



def ensure_parent(path: str) -> None:
    """Create the folder a file is about to be written to."""
    parent = os.path.dirname(path)
    if parent:
        os.makedirs(parent, exist_ok=True)


# --------------------------------------------------------------------------------------------
# Lock

LOCK_FILE = ".lock"


class DirectoryLocked(HrcError):
    """Another run holds the results directory."""

    def __init__(self, directory: str, pid: Optional[int]) -> None:
        self.directory = directory
        self.pid = pid
        who = f"pid {pid}" if pid else "a process whose pid it does not say"
        super().__init__(f"{directory} is in use by another run ({who}); wait for it to end "
                         "or choose another directory")


class DirectoryLock:
    """An exclusive flock on ``<directory>/.lock``, held until :meth:`release` (or the end of
    a ``with`` block, or the process). The file is left behind; only the lock means anything."""

    def __init__(self, directory: str, fd: int) -> None:
        self.directory = directory
        self.path = os.path.join(directory, LOCK_FILE)
        self._fd: Optional[int] = fd

    @property
    def held(self) -> bool:
        return self._fd is not None

    def release(self) -> None:
        if self._fd is not None:
            fd, self._fd = self._fd, None
            try:
                fcntl.flock(fd, fcntl.LOCK_UN)
            finally:
                os.close(fd)

    def __enter__(self) -> "DirectoryLock":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.release()


def _lock_owner(fd: int) -> Optional[int]:
    try:
        text = os.pread(fd, 64, 0).decode("ascii", "replace").strip()
        return int(text) if text.isdigit() else None
    except OSError:
        return None


def lock_directory(directory: Union[str, os.PathLike]) -> DirectoryLock:
    """Lock ``directory`` (created if missing) for this process: an exclusive, non-blocking
    flock on ``<directory>/.lock``, which then holds this process's pid. Raises
    DirectoryLocked (naming the directory and the holder's pid) if another open file holds it,
    without writing anything."""
    directory = os.fspath(directory)
    os.makedirs(directory, exist_ok=True)
    path = os.path.join(directory, LOCK_FILE)
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        owner = _lock_owner(fd)
        os.close(fd)
        if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            raise DirectoryLocked(directory, owner) from None
        raise
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
        os.fsync(fd)
    except BaseException:
        os.close(fd)
        raise
    return DirectoryLock(directory, fd)
