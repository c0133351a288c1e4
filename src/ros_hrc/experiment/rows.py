"""The rows of an experiment's results: one per episode, one per step. No ROS, no PyBullet.

:class:`EpisodeRow` (one per episode, columns :data:`EPISODE_COLUMNS`) and :class:`StepRow` (one
per step, :data:`STEP_COLUMNS`) are frozen dataclasses that check their values when built, so a
bad row fails in the runner, not in the analysis. ``as_dict()`` gives the CSV cells as strings;
``from_dict()`` parses them back and raises ``ValueError`` naming the column and the value of a
bad cell. The files that hold them are :mod:`ros_hrc.experiment.store`'s.
"""
from __future__ import annotations

import math
import operator
from dataclasses import dataclass, fields
from typing import Any, ClassVar, Dict, Mapping, Optional, Tuple, Type, TypeVar

from ros_hrc.command_line import counted
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

# A belief computed in floating point may sum a hair past 1; more than this is a bug.
_BELIEF_TOLERANCE = 1e-6


_R = TypeVar("_R", bound="Row")


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


class Row:
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
class EpisodeRow(Row):
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

    def progress_text(self) -> str:
        """What the progress bar says of it."""
        return (f"{self.human_model}/{self.robot_policy} seed {self.seed}: {self.end_reason} "
                f"in {counted(self.steps, 'step')}")

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
class StepRow(Row):
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
