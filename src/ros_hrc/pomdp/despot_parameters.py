"""DESPOT's parameters, defined once: each one's name, kind, default, the values it takes (and
why those), and its doc.

Three doors take them: :class:`ros_hrc.pomdp.despot.DespotConfig` (the toolkit's), the launch
arguments (:mod:`ros_hrc.settings` makes its ``time_per_step``, ``scenarios``, ``depth``,
``lambda`` and ``max_trials`` rows from :func:`setting_fields`; ``despot_pomdp``,
``hrc_experiment`` and the library manifests read those) and ``hrc_pomdp simulate``'s options
(:mod:`ros_hrc.commands.pomdp_simulate`). Each checks a value with :meth:`DespotParameter.check`
or the settings' parser made from the same fields, so a value is refused with the same limit,
in one line that says it, whichever door it came through.

The "off" word: on a command line and in the settings, 0 is "none" for ``time_per_step`` (no
time budget: the trials alone end a search) and ``max_trials`` (no cap on the trials);
:class:`DespotConfig` holds these as ``inf`` and None (:func:`config_value`).

No numpy here: ``hrc_pomdp`` makes its parser before it imports the toolkit.
"""
from __future__ import annotations

import math
import operator
from dataclasses import dataclass
from typing import Any, Dict, Optional, Tuple

__all__ = ["DespotParameter", "DESPOT_PARAMETERS", "parameter", "config_value",
           "setting_fields", "SETTING_NAMES", "EXACT_BELIEF_MAX_STATES"]


def _number(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else f"{x:g}"


@dataclass(frozen=True)
class DespotParameter:
    """One parameter of DESPOT.

    ``name`` is the launch argument's and, with dashes, ``hrc_pomdp simulate``'s option;
    ``field`` is :class:`~ros_hrc.pomdp.despot.DespotConfig`'s attribute (they differ for λ:
    ``lambda`` is a Python keyword). ``off``: 0 on a command line means "none" (no time budget,
    no trial cap), and a value above 0 is at least ``smallest_nonzero`` when that is given."""

    name: str
    field: str
    symbol: str                  # the paper's name ("" when it has none)
    kind: type                   # int, float or str (a choice)
    default: Any
    doc: str
    low: Optional[float] = None
    high: Optional[float] = None
    choices: Tuple[str, ...] = ()
    unit: str = ""
    off: bool = False
    smallest_nonzero: Optional[float] = None

    @property
    def option(self) -> str:
        """The command-line option: ``--time-per-step``."""
        return "--" + self.name.replace("_", "-")

    def requirement(self) -> str:
        """What a value must be, in the words of the settings' refusals: ``must be an integer
        from 1 to 1000``."""
        if self.choices:
            return f"must be one of {', '.join(self.choices)}"
        noun = "an integer" if self.kind is int else "a number"
        low = self.low
        if self.smallest_nonzero is not None:
            noun, low = f"0 or {noun}", self.smallest_nonzero
        unit = f" ({self.unit})" if self.unit else ""
        return f"must be {noun} from {_number(low)} to {_number(self.high)}{unit}"

    def refusal(self, value: Any) -> str:
        """The one line a refused ``value`` gets (the name, the limits, the value)."""
        return f"DESPOT's {self.name} {self.requirement()}, got {value!r}"

    def accepts(self, value: Any) -> bool:
        """Whether ``value`` (already of the parameter's kind) is in range."""
        if self.choices:
            return value in self.choices
        if isinstance(value, bool):
            return False
        if self.kind is int:
            try:
                value = operator.index(value)
            except TypeError:
                return False
        elif not isinstance(value, (int, float)) or not math.isfinite(value):
            return False
        if self.smallest_nonzero is not None and 0 < value < self.smallest_nonzero:
            return False
        return self.low <= value <= self.high

    def parse(self, text: str) -> Any:
        """A command line's word as the parameter's value (the off value 0 kept as 0: see
        :func:`config_value`); ValueError, one line that says the limits, otherwise."""
        word = text.strip()
        if self.choices:
            value: Any = word
        else:
            try:
                value = self.kind(word)
            except (ValueError, OverflowError):
                raise ValueError(f"{self.requirement()}, got {text!r}") from None
        if not self.accepts(value):
            raise ValueError(f"{self.requirement()}, got {text!r}")
        return value


#: Above this many states DESPOT's belief is a particle filter rather than exact (its default
#: ``particles``).
EXACT_BELIEF_MAX_STATES = 5000

#: The largest integer a launch argument takes: the ROS parameter server's ints are XML-RPC's
#: 32-bit ones (ros_hrc.settings.INT32_MAX, a test checks they agree).
_INT32_MAX = 2**31 - 1

DESPOT_PARAMETERS: Tuple[DespotParameter, ...] = (
    # Up to 60 s: the live robot's step waits on each decision, and hrc_pomdp simulate makes
    # SIM-NUM x SIM-LEN of them (1000 steps at 60 s are 17 hours). 0.1 s keeps the live loop's
    # pace; a study sets 0 and caps the trials (the same decisions on any machine).
    DespotParameter(
        "time_per_step", "time_per_step", "", float, 0.1,
        "DESPOT's time budget per decision (0: none, the decision is bounded by max_trials "
        "alone, the same on any machine: experiments)",
        low=0.0, high=60.0, unit="s", off=True, smallest_nonzero=0.001),
    # Up to 100,000: a search keeps 16·K·(D+2) bytes of random numbers (150 MB at D 90) and
    # steps all K scenarios at each expansion; the paper's K is 500.
    DespotParameter(
        "scenarios", "scenarios", "K", int, 500, "DESPOT's number of sampled scenarios K",
        low=1, high=100_000),
    # From 1 (a tree of depth 0 is no search: its decision is the default policy's) to 1,000:
    # a discount of 0.99 leaves 4e-5 of a reward 1,000 steps away, and each depth costs every
    # scenario its random numbers (1.6 GB at D 1,000 and K 100,000).
    DespotParameter(
        "depth", "depth", "D", int, 90, "DESPOT's maximum search depth D",
        low=1, high=1000),
    # λ is in the model's reward units: a λ above a model's whole value range prunes every
    # tree to its root, so the bound keeps out typos (1e300) and nothing useful: 10^6 is far
    # above the shipped models' rewards (tens).
    DespotParameter(
        "lambda", "pruning", "λ", float, 0.1,
        "DESPOT's regularisation constant λ, the cost of one policy node",
        low=0.0, high=1e6),
    # 0 (no cap) or up to the parameter server's int: a decision of 2^31 trials would take
    # hours anyway.
    DespotParameter(
        "max_trials", "max_trials", "", int, 0,
        "cap on DESPOT trials per decision (0: time only; set it for reproducible runs)",
        low=0, high=_INT32_MAX, off=True),
    # A fraction, by definition.
    DespotParameter(
        "xi", "xi", "ξ", float, 0.95,
        "DESPOT's target gap fraction ξ in the excess uncertainty", low=0.0, high=1.0),
    DespotParameter(
        "upper", "upper", "", str, "mdp",
        "DESPOT's upper bound: mdp (the fully observable MDP's values), fib (the fast "
        "informed bound, small models) or trivial (max R / (1 - discount))", choices=("mdp", "fib", "trivial")),
    DespotParameter(
        "lower", "lower", "", str, "blind",
        "DESPOT's default policy: blind (the best fixed action, valued exactly), "
        "rollout (simulated to depth D, as in the paper; slower) or policy (the best of the "
        "fixed actions and an offline policy's plans)", choices=("blind", "policy", "rollout")),
    # A particle belief's size: 1,000,000 particles are 48 MB, each update steps them all.
    DespotParameter(
        "particles", "particles", "", int, None,
        "particle belief of this many particles (default: the exact belief for models of up "
        f"to {EXACT_BELIEF_MAX_STATES} states)", low=1, high=1_000_000),
)

_BY_NAME: Dict[str, DespotParameter] = {p.name: p for p in DESPOT_PARAMETERS}

#: The parameters that are launch arguments (ros_hrc.settings' rows), in the table's order.
SETTING_NAMES: Tuple[str, ...] = ("time_per_step", "scenarios", "depth", "lambda", "max_trials")


def parameter(name: str) -> DespotParameter:
    """The parameter of launch argument (or option) ``name``."""
    return _BY_NAME[name]


def config_value(name: str, value: Any) -> Any:
    """What DespotConfig's field holds for a command line's ``value``: a parameter's off
    value 0 is ``inf`` (no time budget) or None (no trial cap)."""
    p = _BY_NAME[name]
    if p.off and value == 0:
        return math.inf if p.kind is float else None
    return value


def setting_fields(name: str) -> Dict[str, Any]:
    """A launch argument's kind, default, doc and limits, as ros_hrc.settings' Setting
    takes them."""
    p = _BY_NAME[name]
    fields: Dict[str, Any] = {"kind": "int" if p.kind is int else "float", "default": p.default,
                              "doc": p.doc, "minimum": p.low, "maximum": p.high}
    if p.unit:
        fields["unit"] = p.unit
    if p.smallest_nonzero is not None:
        fields["smallest_nonzero"] = p.smallest_nonzero
    return fields
