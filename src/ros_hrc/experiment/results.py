"""The results of an experiment: rows, their CSV store, statistics, tables and plots.

No ROS, no PyBullet: the runner hands finished rows over and everything here is plain Python
(scipy for the t and normal quantiles, matplotlib for the plots, both imported on first use).

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
    exactly the episodes that are complete, and the runner resumes with the others. On open, a
    partially written last line is cut off and step rows of an episode that has no episode row
    (killed between the two writes) are removed, each with a :class:`ResultsWarning`. One
    writer per directory: nothing locks the files.

Statistics
    :func:`mean_ci` (Student's t), :func:`proportion_ci` (Wilson score), :func:`summarize` (one
    dict per human model x robot policy), :func:`write_summary` (CSV + Markdown table).
    Every episode counts as one independent sample: seeds and episodes are not told apart.

Plots
    :func:`plot_outcomes` (success rate and mean steps, grouped bars with 95 % CIs) and
    :func:`plot_belief` (the robot's belief that the human needs help against the truth, one
    line per robot policy on the same human). Both draw on a bare ``Figure`` rendered by Agg,
    so they work headless and leave pyplot's global state alone.
"""
from __future__ import annotations

import csv
import io
import math
import operator
import os
import warnings
from dataclasses import dataclass, fields
from typing import (Any, ClassVar, Dict, Iterable, List, Mapping, Optional, Sequence, Set, Tuple,
                    Type, TypeVar, Union)

EPISODE_COLUMNS: Tuple[str, ...] = (
    "human_model", "robot_policy", "seed", "episode", "success", "succeeded_by", "end_reason",
    "steps", "sim_seconds", "robot_discounted_reward", "intrusive_actions", "warnings",
    "mean_decision_ms", "wall_seconds")

STEP_COLUMNS: Tuple[str, ...] = (
    "human_model", "robot_policy", "seed", "episode", "step", "human_action", "human_state",
    "robot_state", "robot_action", "observation", "belief_needs_help", "needs_help")

SUCCEEDED_BY: Tuple[str, ...] = ("human", "robot", "none")
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


@dataclass(frozen=True)
class EpisodeRow(_Row):
    """One finished episode.

    success is 1 exactly when end_reason is ``success`` and succeeded_by is ``human`` or
    ``robot``; mean_decision_ms may be NaN (a policy that timed no decisions), every other
    float must be finite.
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
    mean_decision_ms: float
    wall_seconds: float

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
                           "warnings", "wall_seconds")
        if not math.isfinite(self.robot_discounted_reward):
            raise self._bad("robot_discounted_reward", "must be finite")
        self._non_negative("mean_decision_ms", finite=False)
        if math.isinf(self.mean_decision_ms):
            raise self._bad("mean_decision_ms", "must be finite or nan")


@dataclass(frozen=True)
class StepRow(_Row):
    """One step of an episode.

    belief_needs_help is the robot's belief mass on the needs-help states S2..S5 (NaN for a
    policy without a belief); needs_help is 1 when the true robot state is one of them.
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

    def _check(self) -> None:
        self._nonempty("human_model", "robot_policy")
        self._non_negative("seed", "episode", "step")
        self._zero_one("needs_help")
        b = self.belief_needs_help
        if not math.isnan(b) and not -_BELIEF_TOLERANCE <= b <= 1 + _BELIEF_TOLERANCE:
            raise self._bad("belief_needs_help", "must be a probability in [0, 1] or nan")


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
        for path, columns in ((self.episodes_path, EPISODE_COLUMNS),
                              (self.steps_path, STEP_COLUMNS)):
            self._prepare(path, columns)
        episodes = self._read(self.episodes_path, EpisodeRow)
        self._done: Set[EpisodeKey] = set()
        for line, row in episodes:
            if row.key in self._done:
                raise ValueError(f"{self.episodes_path}:{line}: episode {row.key} recorded twice")
            self._done.add(row.key)
        self._drop_orphan_steps()

    # -- opening ------------------------------------------------------------------------------

    def _prepare(self, path: str, columns: Tuple[str, ...]) -> None:
        """Cut a partial last line, and write the header into a missing or empty file."""
        if os.path.exists(path):
            with open(path, "r+b") as f:
                data = f.read()
                if data and not data.endswith(b"\n"):
                    keep = data.rfind(b"\n") + 1  # 0 when even the header is partial
                    lost = data[keep:].decode("utf-8", "replace")
                    line = data.count(b"\n") + 1
                    warnings.warn(f"{path}:{line}: dropped a partially written last line "
                                  f"({len(lost)} characters: {lost[:60]!r}...)", ResultsWarning,
                                  stacklevel=3)
                    f.truncate(keep)
                    f.flush()
                    os.fsync(f.fileno())
                    data = data[:keep]
            if data:
                return
        with open(path, "w", encoding="utf-8", newline="") as f:
            csv.writer(f, lineterminator="\n").writerow(columns)
            f.flush()
            os.fsync(f.fileno())
        _fsync_directory(self.directory)

    @staticmethod
    def _read(path: str, row_type: Type[_R]) -> List[Tuple[int, _R]]:
        """(line number, row) for every row of ``path``; ValueError ``path:line`` if bad."""
        columns = row_type.COLUMNS
        out: List[Tuple[int, _R]] = []
        with open(path, encoding="utf-8", newline="") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            if header is None or tuple(header) != columns:
                raise ValueError(f"{path}:1: header {header!r} differs from the expected "
                                 f"columns {list(columns)!r}")
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

    def _drop_orphan_steps(self) -> None:
        """Remove step rows of episodes without an episode row (written before a kill).

        Left in place, the rerun of that episode would append its steps a second time.
        """
        steps = self._read(self.steps_path, StepRow)
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


# --------------------------------------------------------------------------------------------
# Statistics

def _check_confidence(confidence: float) -> None:
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")


def mean_ci(values: Iterable[float], confidence: float = 0.95) -> Tuple[float, float, float]:
    """(mean, low, high): the mean and its Student's t confidence interval.

    n = 0 gives (nan, nan, nan); n = 1 gives (x, nan, nan): one value says nothing about the
    spread, and a zero-width interval would claim a certainty the data do not have. Values
    must be finite (filter NaNs first, on purpose: dropping them here would change n silently).
    """
    _check_confidence(confidence)
    xs = [float(v) for v in values]
    if not all(math.isfinite(x) for x in xs):
        raise ValueError("mean_ci: values must be finite")
    n = len(xs)
    if n == 0:
        return (math.nan, math.nan, math.nan)
    mean = math.fsum(xs) / n
    if n == 1:
        return (mean, math.nan, math.nan)
    from scipy import stats  # on first use: importing the module stays cheap

    sd = math.sqrt(math.fsum((x - mean) ** 2 for x in xs) / (n - 1))
    half = float(stats.t.ppf((1 + confidence) / 2, n - 1)) * sd / math.sqrt(n)
    return (mean, mean - half, mean + half)


def proportion_ci(successes: int, n: int, confidence: float = 0.95) -> Tuple[float, float, float]:
    """(p, low, high): the success proportion and its Wilson score interval.

    Wilson rather than the normal approximation: it stays inside [0, 1] and keeps a sensible
    width at 0/n and n/n, which small experiments hit often. n = 0 gives (nan, nan, nan).
    """
    _check_confidence(confidence)
    successes, n = operator.index(successes), operator.index(n)
    if n < 0 or not 0 <= successes <= max(n, 0):
        raise ValueError(f"proportion_ci: need 0 <= successes <= n, got {successes}/{n}")
    if n == 0:
        return (math.nan, math.nan, math.nan)
    from scipy import stats

    z = float(stats.norm.ppf((1 + confidence) / 2))
    p = successes / n
    z2n = z * z / n
    centre = (p + z2n / 2) / (1 + z2n)
    half = z * math.sqrt(p * (1 - p) / n + z2n / (4 * n)) / (1 + z2n)
    # At 0/n and n/n the outer end is exactly 0 or 1; rounding would miss it by a hair.
    low = 0.0 if successes == 0 else centre - half
    high = 1.0 if successes == n else centre + half
    return (p, low, high)


#: Keys of each :func:`summarize` dict, in the summary CSV's column order.
SUMMARY_COLUMNS: Tuple[str, ...] = (
    "human_model", "robot_policy", "n", "confidence",
    "successes", "success_rate", "success_low", "success_high",
    "human_successes", "robot_successes", "object_left_belt", "step_limit",
    "steps_mean", "steps_low", "steps_high",
    "sim_seconds_mean", "sim_seconds_low", "sim_seconds_high",
    "reward_mean", "reward_low", "reward_high",
    "intrusive_actions_mean", "intrusive_actions_low", "intrusive_actions_high",
    "warnings_mean", "warnings_low", "warnings_high",
    "mean_decision_ms")

# summary prefix -> EpisodeRow column, for the quantities given as mean + t interval
_MEAN_CI_QUANTITIES: Tuple[Tuple[str, str], ...] = (
    ("steps", "steps"), ("sim_seconds", "sim_seconds"), ("reward", "robot_discounted_reward"),
    ("intrusive_actions", "intrusive_actions"), ("warnings", "warnings"))


def summarize(rows: Iterable[Union[EpisodeRow, Mapping[str, Any]]],
              confidence: float = 0.95) -> List[Dict[str, Any]]:
    """One dict (keys :data:`SUMMARY_COLUMNS`) per (human_model, robot_policy), in order of
    first appearance.

    ``mean_decision_ms`` is the mean of the episodes' means over the episodes that have one
    (NaN if none): a plain number, no interval, since it measures the machine, not the policy.
    Rows may be EpisodeRows or dicts as :meth:`EpisodeRow.from_dict` takes them.
    """
    _check_confidence(confidence)
    groups: Dict[Tuple[str, str], List[EpisodeRow]] = {}
    for row in rows:
        if not isinstance(row, EpisodeRow):
            row = EpisodeRow.from_dict(row)
        groups.setdefault((row.human_model, row.robot_policy), []).append(row)
    summary = []
    for (human_model, robot_policy), group in groups.items():
        successes = sum(r.success for r in group)
        p, low, high = proportion_ci(successes, len(group), confidence)
        entry: Dict[str, Any] = {
            "human_model": human_model, "robot_policy": robot_policy, "n": len(group),
            "confidence": confidence, "successes": successes,
            "success_rate": p, "success_low": low, "success_high": high,
            "human_successes": sum(r.succeeded_by == "human" for r in group),
            "robot_successes": sum(r.succeeded_by == "robot" for r in group),
            "object_left_belt": sum(r.end_reason == "object_left_belt" for r in group),
            "step_limit": sum(r.end_reason == "step_limit" for r in group),
        }
        for prefix, column in _MEAN_CI_QUANTITIES:
            mean, low, high = mean_ci([getattr(r, column) for r in group], confidence)
            entry.update({f"{prefix}_mean": mean, f"{prefix}_low": low, f"{prefix}_high": high})
        timed = [r.mean_decision_ms for r in group if not math.isnan(r.mean_decision_ms)]
        entry["mean_decision_ms"] = math.fsum(timed) / len(timed) if timed else math.nan
        summary.append(entry)
    return summary


def format_ci(mean: float, low: float, high: float, digits: int = 2) -> str:
    """``"0.85 [0.71, 0.93]"``; ``"3.00 [n/a]"`` without an interval; ``"n/a"`` without a mean."""
    if math.isnan(mean):
        return "n/a"
    if math.isnan(low) or math.isnan(high):
        return f"{mean:.{digits}f} [n/a]"
    return f"{mean:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


def _markdown_cell(text: str) -> str:
    return text.replace("|", "\\|")  # a pipe in a name would split the cell


def _ensure_parent(path: str) -> None:
    parent = os.path.dirname(path)
    if parent:
        os.makedirs(parent, exist_ok=True)


def write_summary(summary: Sequence[Mapping[str, Any]], csv_path: Union[str, os.PathLike],
                  markdown_path: Union[str, os.PathLike]) -> Tuple[str, str]:
    """Write the :func:`summarize` output as a CSV (every number, full precision) and as a
    Markdown table of means with their intervals; returns both paths."""
    csv_path, markdown_path = os.fspath(csv_path), os.fspath(markdown_path)
    _ensure_parent(csv_path)
    with open(csv_path, "w", encoding="utf-8", newline="") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(SUMMARY_COLUMNS)
        for entry in summary:
            writer.writerow(repr(v) if isinstance(v, float) else str(v)
                            for v in (entry[c] for c in SUMMARY_COLUMNS))

    levels = {entry["confidence"] for entry in summary} or {0.95}
    level = "/".join(f"{100 * c:g} %" for c in sorted(levels))
    headers = ["Human model", "Robot policy", "n", f"Success rate [{level} CI]",
               "Successes (human / robot)", "Steps", "Sim time (s)", "Discounted reward",
               "Intrusive actions", "Warnings", "Decision time (ms)"]
    lines = ["| " + " | ".join(headers) + " |",
             "|" + "|".join(["---", "---", "--:"] + ["--:"] * (len(headers) - 3)) + "|"]
    for e in summary:
        ms = e["mean_decision_ms"]
        cells = [_markdown_cell(str(e["human_model"])), _markdown_cell(str(e["robot_policy"])),
                 str(e["n"]),
                 format_ci(e["success_rate"], e["success_low"], e["success_high"]),
                 f"{e['human_successes']} / {e['robot_successes']}",
                 format_ci(e["steps_mean"], e["steps_low"], e["steps_high"], 1),
                 format_ci(e["sim_seconds_mean"], e["sim_seconds_low"], e["sim_seconds_high"]),
                 format_ci(e["reward_mean"], e["reward_low"], e["reward_high"]),
                 format_ci(e["intrusive_actions_mean"], e["intrusive_actions_low"],
                           e["intrusive_actions_high"]),
                 format_ci(e["warnings_mean"], e["warnings_low"], e["warnings_high"]),
                 "n/a" if math.isnan(ms) else f"{ms:.1f}"]
        lines.append("| " + " | ".join(cells) + " |")
    note = (f"Mean [{level} confidence interval] over episodes: Wilson score interval for the "
            "success rate, Student's t for the other quantities; [n/a] where an interval "
            "needs two episodes or more.")
    _ensure_parent(markdown_path)
    with open(markdown_path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n\n" + note + "\n")
    return csv_path, markdown_path


# --------------------------------------------------------------------------------------------
# Plots

def _new_figure(width: float, height: float):
    """A Figure outside pyplot: rendered by Agg whatever backend the process chose."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), layout="constrained")


def _save(fig, png_path: Union[str, os.PathLike]) -> str:
    path = os.fspath(png_path)
    _ensure_parent(path)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)  # attach Agg explicitly: no display, no backend lookup
    fig.savefig(path, format="png", dpi=150)
    return path


def _ordered(values: Iterable[Any]) -> List[Any]:
    return list(dict.fromkeys(values))


def _policy_colours(policies: Sequence[str]) -> Dict[str, Any]:
    from matplotlib import colormaps

    cmap = colormaps["tab10"]
    return {p: cmap(i % 10) for i, p in enumerate(policies)}


def plot_outcomes(summary: Sequence[Mapping[str, Any]], png_path: Union[str, os.PathLike]) -> str:
    """Success rate and mean steps, grouped by human model, one bar per robot policy, with
    the summary's confidence intervals as error bars. Returns the PNG's path."""
    if not summary:
        raise ValueError("plot_outcomes: the summary is empty, nothing to plot")
    humans = _ordered(e["human_model"] for e in summary)
    policies = _ordered(e["robot_policy"] for e in summary)
    colours = _policy_colours(policies)
    by_key = {(e["human_model"], e["robot_policy"]): e for e in summary}
    width = 0.8 / len(policies)

    fig = _new_figure(max(8.0, 1.6 * len(humans) * 2 + 2), 4.5)
    ax_rate, ax_steps = fig.subplots(1, 2)
    panels = ((ax_rate, "success_rate", "success_low", "success_high", "Success rate"),
              (ax_steps, "steps_mean", "steps_low", "steps_high", "Mean steps per episode"))
    for ax, mean_key, low_key, high_key, ylabel in panels:
        for j, policy in enumerate(policies):
            xs, heights, below, above = [], [], [], []
            for i, human in enumerate(humans):
                e = by_key.get((human, policy))
                if e is None:
                    continue  # this pair was not run: leave a gap, not a zero bar
                m, lo, hi = e[mean_key], e[low_key], e[high_key]
                xs.append(i - 0.4 + width * (j + 0.5))
                heights.append(m)
                # No interval (n = 1): no error bar rather than a zero-length one.
                below.append(m - lo if math.isfinite(lo) else math.nan)
                above.append(hi - m if math.isfinite(hi) else math.nan)
            ax.bar(xs, heights, width, yerr=[below, above], capsize=3,
                   color=colours[policy], label=policy, error_kw={"elinewidth": 1})
        ax.set_xticks(range(len(humans)), humans)
        ax.set_xlabel("Human model")
        ax.set_ylabel(ylabel)
        ax.grid(axis="y", alpha=0.3)
        ax.set_axisbelow(True)
    ax_rate.set_ylim(0, 1.05)
    ax_steps.set_ylim(bottom=0)
    ax_rate.legend(title="Robot policy", fontsize="small")
    levels = _ordered(e.get("confidence", 0.95) for e in summary)
    ns = [e["n"] for e in summary]
    n_text = f"n = {ns[0]}" if min(ns) == max(ns) else f"n = {min(ns)}–{max(ns)}"
    fig.suptitle("Outcomes by human model and robot policy (mean, "
                 + "/".join(f"{100 * c:g} %" for c in levels)
                 + f" CI; {n_text} episodes per bar)")
    return _save(fig, png_path)


def _select_episode(groups: Mapping[EpisodeKey, List[StepRow]],
                    episode: Optional[Sequence[Any]]) -> EpisodeKey:
    if episode is not None:
        key = tuple(episode)
        if len(key) != 4:
            raise ValueError(f"episode must be (human_model, robot_policy, seed, episode), "
                             f"got {episode!r}")
        if key not in groups:
            raise ValueError(f"no step rows for episode {key}")
        return key  # type: ignore[return-value]
    policies = _ordered(k[1] for k in groups)
    for policy in policies:  # policy by policy, each in order of first appearance
        for key, rows in groups.items():
            if key[1] == policy and any(r.needs_help for r in rows):
                return key
    return next(iter(groups))


def plot_belief(step_rows: Iterable[StepRow], png_path: Union[str, os.PathLike],
                episode: Optional[Sequence[Any]] = None) -> str:
    """The robot's belief that the human needs help (S2..S5), step by step, against the
    human's true need (shaded), for one episode. Returns the PNG's path.

    ``episode`` is a key (human_model, robot_policy, seed, episode); by default the first
    episode of the first policy that has a needs-help step, else the first episode. Every
    robot policy with the same (human_model, seed, episode) gets its own line, so policies
    are compared on the same simulated human. The shaded truth is the union over those runs
    where they agree; where they do not (the robot changed what the human did), the chosen
    run's truth is shown and a ResultsWarning says so.
    """
    groups: Dict[EpisodeKey, List[StepRow]] = {}
    for row in step_rows:
        groups.setdefault(row.key, []).append(row)
    if not groups:
        raise ValueError("plot_belief: no step rows, nothing to plot")
    chosen = _select_episode(groups, episode)
    human_model, _, seed, number = chosen
    same_human = [k for k in groups if (k[0], k[2], k[3]) == (human_model, seed, number)]
    same_human.sort(key=lambda k: k != chosen)  # the chosen run first, the rest in order
    runs = {k[1]: sorted(groups[k], key=lambda r: r.step) for k in same_human}

    # The true need per step: from the chosen run, completed by the others where it ends.
    truth: Dict[int, int] = {}
    conflicts = False
    for rows in runs.values():
        for r in rows:
            if truth.setdefault(r.step, r.needs_help) != r.needs_help:
                conflicts = True
    if conflicts:
        warnings.warn(f"plot_belief: the runs of {human_model}, seed {seed}, episode {number} "
                      f"disagree on when the human needed help; shading the {chosen[1]} run's",
                      ResultsWarning, stacklevel=2)
        truth = {r.step: r.needs_help for r in runs[chosen[1]]}

    from matplotlib.ticker import MaxNLocator

    fig = _new_figure(9.0, 4.0)
    ax = fig.subplots()
    t_steps = sorted(truth)
    # Each step's truth fills [step - 0.5, step + 0.5], so a single needs-help step shows too.
    edges = (t_steps[0] - 0.5, t_steps[-1] + 0.5)
    truth_label = "human needs help (true state S2..S5)"
    if conflicts:
        truth_label += f", {chosen[1]} run"
    # One span per run of needs-help steps (fill_between's where= drops a run's last step).
    start = None
    for s, v in zip(t_steps + [None], [truth[s] for s in t_steps] + [0]):
        if v and start is None:
            start = s
        elif not v and start is not None:
            ax.axvspan(start - 0.5, prev + 0.5, color="0.6", alpha=0.3, linewidth=0,
                       label=truth_label)
            truth_label = "_nolegend_"  # one legend entry for all spans
            start = None
        prev = s
    if truth_label != "_nolegend_":  # no span drawn: still say what shading would mean
        ax.fill_between([], [], color="0.6", alpha=0.3, linewidth=0,
                        label=truth_label + ": never in this episode")

    colours = _policy_colours(list(runs))
    for policy, rows in runs.items():
        beliefs = [r.belief_needs_help for r in rows]
        if all(math.isnan(b) for b in beliefs):
            ax.plot([], [], color=colours[policy], label=f"{policy} (no belief reported)")
            continue
        ax.plot([r.step for r in rows], beliefs, color=colours[policy], marker="o",
                markersize=3, linewidth=1.5, label=policy, clip_on=False)
    ax.set_ylim(0, 1)
    ax.set_xlim(edges[0], edges[-1])
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # steps are whole numbers
    ax.set_xlabel("Step")
    ax.set_ylabel("Robot's belief P(needs help)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1), borderaxespad=0)
    ax.set_title(f"Belief that the human needs help: {human_model}, seed {seed}, "
                 f"episode {number}")
    return _save(fig, png_path)
