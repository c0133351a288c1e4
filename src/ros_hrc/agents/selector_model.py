"""The selector model file: what a selector knows of the library's policies on each human type.

A Bayesian policy-reuse selector (:mod:`ros_hrc.agents.selectors`) needs, for every (human
type, library policy) pair, the *performance model* (the mean and standard deviation of the
task utility, a Gaussian) and the *signature model* (how likely each step's signature code is:
one distribution over the 64 codes per (policy, type)). ``hrc_train_selector`` measures both
from runs of the real stack and writes them as one JSON object (docs/selectors.md, "The model
file")::

    {"format": "ros_hrc selector model 1", "task": "fabric",
     "library": {"manifest": "models/fabric/library.toml", "policies": ["base", ...]},
     "types": ["expert_tired", ...], "signature_codes": 64, "utility": "<its definition>",
     "mean": [[types x policies]], "std": [[types x policies]],
     "signature": [[[policies x types x codes]]], "tasks_per_pair": [[types x policies]],
     "header": {"how": ..., "from": ..., "seeds": [...], "command": ..., "date": ...}}

  SelectorModel          the file's content, checked (a frozen dataclass of read-only arrays)
  from_tasks             the trainer's arithmetic: rows (type, policy, utility, codes) -> model
  write_selector_model   write it whole or not at all
  load_selector_model    read and check it against the run's task and library (HrcError, one line)

No ROS: numpy and the standard library.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from ros_hrc.errors import HrcError, ModelError, ModelFormatError
from ros_hrc.pomdp.output import write_text_atomically

__all__ = ["FORMAT", "SIGNATURE_CODES", "HEADER_KEYS", "STD_FLOOR", "SIGNATURE_PRIOR",
           "UTILITY_DEFINITION", "SelectorModel", "TrainingTask", "from_tasks",
           "write_selector_model", "load_selector_model"]

#: The format tag of the file's first key: a reader refuses any other.
FORMAT = "ros_hrc selector model 1"
#: A signature code is 6 bits (FABRIC's six human observables): 0..63.
SIGNATURE_CODES = 64
#: What the header says of the model's making; :func:`from_tasks` and the reader want all five.
HEADER_KEYS: Tuple[str, ...] = ("how", "from", "seeds", "command", "date")
#: The smallest standard deviation the trainer writes (utility units). A pair whose few tasks
#: happened to end alike would otherwise get a σ near 0, and the Gaussian performance model a
#: spike that makes BPR's probability and expected improvement all-or-nothing for it; 0.05 is
#: a twentieth of a success's utility, below the spread any real pair shows.
STD_FLOOR = 0.05
#: The additive (Laplace) prior of the signature model, in pseudo-counts per code: a code never
#: seen with a (policy, type) pair gets probability 1 / (steps + 64) instead of 0, so one
#: unusual step (observation noise) lowers a type's belief instead of ruling it out for good.
#: FABRIC adds 1e-4 to the probabilities at use instead (their smoothing; ``bpr-fabric`` does).
SIGNATURE_PRIOR = 1.0
#: The utility the mean and std are of (ros_hrc.tasks.utility.task_utility), in one line.
UTILITY_DEFINITION = ("task_utility: 1 for a success, minus 0.5 x min(duration / task_timeout, 1),"
                      " minus 0.1 a warning, minus 0.5 a pre-emption (about -1.5 .. 1)")

# The tolerance of a signature row's sum (the file holds decimal text of binary floats).
_SUM_TOLERANCE = 1e-6


def _frozen(values: Any, dtype: Any) -> np.ndarray:
    array = np.array(values, dtype=dtype)
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class SelectorModel:
    """A selector model: the library's policies on each human type, checked on construction
    (ValueError, one line, naming what is wrong).

    ``mean``/``std``/``tasks_per_pair``: types x policies; ``signature``: policies x types x
    64, each (policy, type) row a distribution over the codes. ``path``: the file it was read
    from (None when built in memory)."""

    task: str
    policies: Tuple[str, ...]
    types: Tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray
    signature: np.ndarray
    tasks_per_pair: np.ndarray
    header: Mapping[str, Any]
    path: Optional[Path] = None
    #: The library manifest the policies came from, relative to the package.
    manifest: str = ""
    #: The utility's one-line definition (what ``mean`` and ``std`` measure).
    utility: str = UTILITY_DEFINITION

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        # Names as given: str() made the types 0..9 of a file the names "0".."9", which no
        # human's type matched (the oracle then identified nobody, silently).
        set_(self, "policies", tuple(self.policies))
        set_(self, "types", tuple(self.types))
        set_(self, "mean", _frozen(self.mean, float))
        set_(self, "std", _frozen(self.std, float))
        set_(self, "signature", _frozen(self.signature, float))
        set_(self, "tasks_per_pair", _frozen(self.tasks_per_pair, float))
        set_(self, "header", dict(self.header))
        problem = _problem(self)
        if problem:
            raise ValueError(problem)
        set_(self, "tasks_per_pair", _frozen(self.tasks_per_pair, int))

    def policy_index(self, name: str) -> int:
        """The row of policy ``name``; ValueError naming the model's policies otherwise."""
        try:
            return self.policies.index(name)
        except ValueError:
            raise ValueError(f"policy {name!r} is not in the selector model; its policies: "
                             f"{', '.join(self.policies)}") from None

    def type_index(self, name: str) -> Optional[int]:
        """The row of human type ``name``; None for a type the model was not trained on."""
        return self.types.index(name) if name in self.types else None


def _not_a_name(what: str, names: Sequence[Any]) -> str:
    """The first of ``names`` that is not a string, said in one line ('' when all are)."""
    for index, name in enumerate(names):
        if not isinstance(name, str):
            return (f"{what}[{index}] is {json.dumps(name, default=repr)}, not a name: each of "
                    f"the {what} is named by a string")
    return ""


def _names_problem(what: str, names: Sequence[str]) -> str:
    if not names:
        return f"no {what}"
    if _not_a_name(what, names):
        return _not_a_name(what, names)
    if any(not n for n in names):
        return f"an empty name among the {what}"
    if len(set(names)) != len(names):
        return f"a name twice among the {what}: {', '.join(names)}"
    return ""


def _problem(model: SelectorModel) -> str:
    """What is wrong with ``model``, in one line ('' when nothing)."""
    for what, names in (("policies", model.policies), ("types", model.types)):
        problem = _names_problem(what, names)
        if problem:
            return problem
    n_types, n_policies = len(model.types), len(model.policies)
    pair_shape = (n_types, n_policies)
    for name in ("mean", "std", "tasks_per_pair"):
        array = getattr(model, name)
        if array.shape != pair_shape:
            return (f"{name} is {_shape(array)}, expected types x policies = "
                    f"{n_types} x {n_policies}")
    expected = (n_policies, n_types, SIGNATURE_CODES)
    if model.signature.shape != expected:
        return (f"signature is {_shape(model.signature)}, expected policies x types x codes = "
                f"{n_policies} x {n_types} x {SIGNATURE_CODES}")
    for name in ("mean", "std", "signature", "tasks_per_pair"):
        if not np.all(np.isfinite(getattr(model, name))):
            return f"{name} holds a value that is not a finite number"
    bad = np.argwhere(model.std <= 0)
    if bad.size:
        t, p = bad[0]
        return (f"std of type {model.types[t]!r} with policy {model.policies[p]!r} is "
                f"{model.std[t, p]:g}: a standard deviation must be positive")
    counts = model.tasks_per_pair
    if np.any(counts < 0) or np.any(counts != np.round(counts)):
        return "tasks_per_pair must hold whole numbers >= 0"
    bad = np.argwhere(model.signature < 0)
    if bad.size:
        p, t, c = bad[0]
        return (f"signature of policy {model.policies[p]!r} on type {model.types[t]!r} gives "
                f"code {c} the negative probability {model.signature[p, t, c]:g}")
    sums = model.signature.sum(axis=2)
    bad = np.argwhere(np.abs(sums - 1.0) > _SUM_TOLERANCE)
    if bad.size:
        p, t = bad[0]
        return (f"signature of policy {model.policies[p]!r} on type {model.types[t]!r} sums to "
                f"{sums[p, t]:.9g}, not 1")
    missing = [k for k in HEADER_KEYS if k not in model.header]
    if missing:
        return f"the header lacks {', '.join(missing)} (it needs {', '.join(HEADER_KEYS)})"
    return ""


def _shape(array: np.ndarray) -> str:
    return " x ".join(str(n) for n in array.shape) or "a single number"


# -- the trainer's arithmetic --------------------------------------------------------------------
@dataclass(frozen=True)
class TrainingTask:
    """One task of the training runs: who played it, which policy ran, its utility and the
    signature codes of its steps (:func:`ros_hrc.agents.selectors.signature_code`)."""

    human_type: str
    policy: str
    utility: float
    signature: Tuple[int, ...]


def from_tasks(rows: Iterable[TrainingTask], *, task: str, policies: Sequence[str],
               types: Sequence[str], header: Mapping[str, Any], manifest: str = "",
               utility: str = UTILITY_DEFINITION, std_floor: float = STD_FLOOR,
               signature_prior: float = SIGNATURE_PRIOR) -> SelectorModel:
    """The selector model of the training tasks ``rows``, for the library ``policies`` and the
    human ``types`` (both in the file's order).

    Per (type, policy): ``mean`` the utilities' mean; ``std`` their sample standard deviation
    (n - 1 in the denominator), raised to ``std_floor`` (a single task's is the floor);
    ``signature[policy, type, code]`` = (the steps showing the code + ``signature_prior``) /
    (all the pair's steps + 64 ``signature_prior``). Every pair needs at least one task.
    ValueError (one line) for a row of an unknown type or policy, a code outside 0..63, a
    utility that is not a finite number, or a pair with no task."""
    policies, types = tuple(policies), tuple(types)
    if not std_floor > 0:
        raise ValueError(f"std_floor must be positive, got {std_floor!r}")
    if not signature_prior > 0:
        raise ValueError(f"signature_prior must be positive, got {signature_prior!r}")
    for what, names in (("policies", policies), ("types", types)):
        problem = _names_problem(what, names)
        if problem:
            raise ValueError(problem)
    utilities: Dict[Tuple[int, int], List[float]] = {}
    counts = np.zeros((len(policies), len(types), SIGNATURE_CODES))
    for row in rows:
        if row.human_type not in types:
            raise ValueError(f"a training task of human type {row.human_type!r}, not one of "
                             f"{', '.join(types)}")
        if row.policy not in policies:
            raise ValueError(f"a training task of policy {row.policy!r}, not one of the "
                             f"library's {', '.join(policies)}")
        value = float(row.utility)
        if not math.isfinite(value):
            raise ValueError(f"a training task of {row.human_type} with {row.policy} has the "
                             f"utility {row.utility!r}")
        t, p = types.index(row.human_type), policies.index(row.policy)
        utilities.setdefault((t, p), []).append(value)
        for code in row.signature:
            if not (isinstance(code, (int, np.integer)) and 0 <= code < SIGNATURE_CODES):
                raise ValueError(f"signature code {code!r} of a task of {row.human_type} with "
                                 f"{row.policy} is outside 0..{SIGNATURE_CODES - 1}")
            counts[p, t, code] += 1
    missing = [f"{types[t]} with {policies[p]}" for t in range(len(types))
               for p in range(len(policies)) if (t, p) not in utilities]
    if missing:
        raise ValueError(f"no training task of {missing[0]}"
                         + (f" (and {len(missing) - 1} more pairs)" if len(missing) > 1 else "")
                         + ": every (type, policy) pair needs one")
    mean = np.zeros((len(types), len(policies)))
    std = np.zeros_like(mean)
    tasks_per_pair = np.zeros_like(mean)
    for (t, p), values in utilities.items():
        mean[t, p] = np.mean(values)
        spread = float(np.std(values, ddof=1)) if len(values) > 1 else 0.0
        std[t, p] = max(spread, std_floor)
        tasks_per_pair[t, p] = len(values)
    signature = (counts + signature_prior) / (
        counts.sum(axis=2, keepdims=True) + SIGNATURE_CODES * signature_prior)
    return SelectorModel(task=str(task), policies=policies, types=types, mean=mean, std=std,
                         signature=signature, tasks_per_pair=tasks_per_pair, header=header,
                         manifest=str(manifest), utility=str(utility))


# -- the file ------------------------------------------------------------------------------------
def _as_json(model: SelectorModel) -> Dict[str, Any]:
    return {
        "format": FORMAT,
        "task": model.task,
        "library": {"manifest": model.manifest, "policies": list(model.policies)},
        "types": list(model.types),
        "signature_codes": SIGNATURE_CODES,
        "utility": model.utility,
        "mean": model.mean.tolist(),
        "std": model.std.tolist(),
        "signature": model.signature.tolist(),
        "tasks_per_pair": model.tasks_per_pair.tolist(),
        "header": dict(model.header),
    }


def write_selector_model(model: SelectorModel, path: Union[str, Path]) -> None:
    """Write ``model`` to ``path`` as the file's JSON, whole or not at all (OSError when the
    path cannot be written)."""
    text = json.dumps(_as_json(model), indent=1, allow_nan=False) + "\n"
    write_text_atomically(path, text)


def load_selector_model(path: Union[str, Path], task: Any, policies: Sequence[str]
                        ) -> SelectorModel:
    """The selector model in ``path``, checked against the run: its task must be ``task`` (a
    :class:`~ros_hrc.tasks.Task` or its name) and its policies the library's ``policies``, in
    that order. Raises :class:`~ros_hrc.errors.HrcError` in one line naming the file for a
    missing or unreadable file, malformed JSON (with its line), another format, another task,
    another library, or tables that disagree (shapes, a signature row that does not sum to 1,
    a std that is not positive)."""
    path = Path(path)
    task_name = str(getattr(task, "name", task))
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise HrcError(f"{path}: no such selector model file (make train-selector writes "
                       "one)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise HrcError(f"{path}: cannot read the selector model: "
                       f"{getattr(exc, 'strerror', None) or exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ModelFormatError(str(path), str(exc.lineno),
                               f"not JSON: {exc.msg} (column {exc.colno})") from None
    if not isinstance(data, dict):
        raise ModelFormatError(str(path), None, "a selector model is one JSON object")
    if data.get("format") != FORMAT:
        raise ModelFormatError(str(path), None, f"format is {data.get('format')!r}, expected "
                                                f"{FORMAT!r}")
    if data.get("task") != task_name:
        raise ModelError(f"{path}: a selector model of task {data.get('task')!r}, not "
                         f"{task_name!r}")
    library = data.get("library")
    if not isinstance(library, dict) or not isinstance(library.get("policies"), list):
        raise ModelFormatError(str(path), None, "library must be an object with a list "
                                                "'policies'")
    problem = _not_a_name("policies", library["policies"])
    if problem:
        raise ModelError(f"{path}: library.{problem}")
    trained, wanted = list(library["policies"]), [str(p) for p in policies]
    if trained != wanted:
        raise ModelError(f"{path}: trained on the policies {', '.join(trained) or '(none)'}; "
                         f"the library's are {', '.join(wanted) or '(none)'} (retrain: make "
                         "train-selector)")
    if data.get("signature_codes") != SIGNATURE_CODES:
        raise ModelError(f"{path}: signature_codes is {data.get('signature_codes')!r}, "
                         f"expected {SIGNATURE_CODES}")
    for key, kind in (("types", list), ("mean", list), ("std", list), ("signature", list),
                      ("tasks_per_pair", list), ("header", dict)):
        if not isinstance(data.get(key), kind):
            raise ModelFormatError(str(path), None, f"{key} must be a JSON "
                                                    f"{'array' if kind is list else 'object'}")
    try:
        return SelectorModel(
            task=task_name, policies=tuple(trained), types=tuple(data["types"]),
            mean=_table(data["mean"]), std=_table(data["std"]),
            signature=_table(data["signature"]), tasks_per_pair=_table(data["tasks_per_pair"]),
            header=data["header"], path=path, manifest=str(library.get("manifest", "")),
            utility=str(data.get("utility", "")))
    except ValueError as exc:
        raise ModelError(f"{path}: {exc}") from None


def _table(values: Any) -> np.ndarray:
    """A nested JSON array as a float array; ragged rows or non-numbers: ValueError."""
    try:
        return np.array(values, dtype=float)
    except (ValueError, TypeError):
        raise ValueError("a table has rows of different lengths or a value that is not a "
                         "number") from None
