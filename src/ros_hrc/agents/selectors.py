"""Selectors: which library policy the robot runs for the next task of a sequence.

A sequence is many short tasks with one human (or a human who changes). Before each task the
robot process asks its selector for a policy of the library (``choose``); after the task it
tells the selector what happened (``observe``: the policy, the steps' signature codes, the
task's utility). docs/selectors.md says what each one does and why; in short:

  fixed:<policy>  always that policy
  random          a policy drawn uniformly from the library, each task
  bpr             Bayesian policy reuse, BPR-EI: a belief over human types from the tasks'
                  signatures, the policy of largest expected improvement over the best
                  expected utility (Rosman, Hawasly & Ramamoorthy, "Bayesian policy reuse",
                  Machine Learning 104, 2016)
  bpr-pi          the same belief, the policy of largest probability of improvement (BPR-PI)
  bpr-fabric      FABRIC's BPR (their belief update and their "EI" score, see below)
  bandit          UCB1 over the policies from the utilities alone (MABWiser), no model
  oracle          told the human's true type, the policy best for it in the model

Each is a :class:`Selector` found by name in :mod:`ros_hrc.registry` (``ros_hrc.selectors``),
as a selector of the user's own package is (docs/extending.md); ``fixed:<policy>`` is made
here.

The signature of a step (:func:`signature_code`) is FABRIC's six human observables packed in
six bits. The performance model is Gaussian, N(mean[τ, π], std[τ, π]) of the task utility,
and the signature model a distribution over the 64 codes per (policy, type): both come from
the selector model file (:mod:`ros_hrc.agents.selector_model`).

No ROS. numpy and scipy; the bandit imports MABWiser when one is made, the Gaussian
scores import scipy.stats when first computed, and the posteriors scipy.special (0.4 s and
0.1 s of a process's start that the launch's pre-flight and every robot process whose
selector scores nothing need not pay: docs/performance.md, "Stack start-up").
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Dict, Optional, Sequence, Tuple, Type

import numpy as np

from ros_hrc import registry
from ros_hrc.agents.selector_model import SIGNATURE_CODES, SelectorModel
from ros_hrc.tasks.utility import UTILITY_MAX

__all__ = ["FIXED", "DEFAULT_FORGETTING", "SIGNATURE_OBSERVABLES",
           "TaskResult", "Selector", "selector_class", "signature_code", "make_selector",
           "signature_log_likelihood", "type_posterior", "mix_with_uniform",
           "expected_utilities", "utility_ceiling", "improvement_target",
           "probability_of_improvement", "expected_improvement",
           "fabric_type_posterior", "fabric_scores", "bandit_reward",
           "FixedSelector", "RandomSelector", "BprSelector", "FabricBprSelector",
           "BanditSelector", "OracleSelector"]

#: ``selector:=fixed`` alone is today's single robot (the robot process keeps its one planner,
#: no selector is made); ``fixed:<policy>`` is made here. Every other selector is registered.
FIXED = "fixed"
#: ``bpr_forgetting``'s default: after each task, 5 % of the belief is spread evenly over the
#: types (docs/selectors.md, "Forgetting").
DEFAULT_FORGETTING = 0.05


@dataclass(frozen=True)
class TaskResult:
    """What a selector learns from one task: the policy that ran it, its steps' signature
    codes (:func:`signature_code`) and its utility (``ros_hrc.tasks.utility.task_utility``)."""

    policy: str
    signature: Tuple[int, ...]
    utility: float


class Selector:
    """A selector, as the robot process drives it (one per sequence). Every ability the
    process uses is declared here, with the default of a selector without it; a selector is
    made by :meth:`create`."""

    #: "bpr", "fixed:policy3", ...
    name: str = ""
    #: Whether it cannot run without a selector model (``selector_model:=``, make
    #: train-selector); the held-out rule of a trained model applies to it (hrc_experiment).
    needs_model: ClassVar[bool] = False
    #: The human types its belief is over; () for a selector with no type belief.
    type_names: Tuple[str, ...] = ()
    #: One line on something worth saying about its last choice or update ("" when nothing).
    note: str = ""

    @classmethod
    def create(cls, policies: Tuple[str, ...], model: Optional[SelectorModel],
               rng: np.random.Generator, forgetting: float) -> "Selector":
        """A fresh selector for one sequence over the library's ``policies`` (the selector
        model ``model``: None without one; of these policies when given), drawing from
        ``rng``, with the BPR belief's floor ``forgetting``. By default ``cls(policies, rng)``."""
        return cls(policies, rng)

    def choose(self) -> str:
        """The policy for the next task (draws from the selector's own generator)."""
        raise NotImplementedError

    def observe(self, result: TaskResult) -> None:
        """Learn from the task just played (by default nothing)."""

    def belief(self) -> np.ndarray:
        """The belief over ``type_names`` (an empty array when it has none)."""
        return np.zeros(0)

    def tell_true_type(self, name: str) -> None:
        """The human's true type for the next task: only the oracle uses it."""


def selector_class(name: str) -> Type[Selector]:
    """The selector ``name`` names (``selector:=``, not ``fixed``): a registered name or
    ``module:Class`` (:mod:`ros_hrc.registry`). RegistryError (a ValueError, one line)."""
    return registry.load(registry.SELECTORS, name, Selector)


# -- the signature --------------------------------------------------------------------------------
#: FABRIC's six human observables, bit i of the code being 2**i, in their order
#: (``TaskManager::ObsUpdater``, hrc_ros/src/task_manager/TaskManager.cpp at 1fe698b: the
#: ``human_observables`` vector of TaskState; policy_selector_bpr.py packs it as
#: sum(2**i * observable[i])); the second column says which of our bits gives each.
SIGNATURE_OBSERVABLES: Tuple[Tuple[str, str], ...] = (
    ("human detected", "in_range"),
    ("looking around", "not visible"),
    ("grasped successfully", "grasp_attempt and the object taken"),
    ("failed to grasp", "grasp_attempt and the object not taken"),
    ("warning", "warning"),
    ("idle", "idle"),
)
# The bit of a task's observation that says the object is held: the fabric task's name, then
# the seed's.
_TAKEN_NAMES = ("object_taken", "has_object")
_NEEDED = ("visible", "in_range", "grasp_attempt", "warning", "idle")
_BITS_OF_TASK: Dict[str, Tuple[int, int, int, int, int, int, int]] = {}


def _bits_of(task) -> Tuple[int, int, int, int, int, int, int]:
    """(visible, in_range, grasp_attempt, taken, warning, idle, max_bits) of ``task``."""
    cached = _BITS_OF_TASK.get(task.name)
    if cached is not None:
        return cached
    by_name = {name: bit for bit, name in task.observations.bit_names}
    taken = next((by_name[n] for n in _TAKEN_NAMES if n in by_name), None)
    missing = [n for n in _NEEDED if n not in by_name] + (
        [" or ".join(_TAKEN_NAMES)] if taken is None else [])
    if missing:
        raise ValueError(f"task {task.name!r} has no observation bit {', '.join(missing)}: "
                         "the signature needs them")
    bits = (by_name["visible"], by_name["in_range"], by_name["grasp_attempt"], taken,
            by_name["warning"], by_name["idle"], task.observations.max_bits)
    _BITS_OF_TASK[task.name] = bits
    return bits


def signature_code(bits: int, task) -> int:
    """One step's signature, 0..63: FABRIC's six human observables (:data:`SIGNATURE_OBSERVABLES`,
    bit i = 2**i) from the observation ``bits`` the robot saw (after noise) in ``task``.

    1 human detected = in_range; 2 looking around = not visible; 4 grasped successfully = a
    grasp attempt with the object taken; 8 failed to grasp = a grasp attempt with the object
    not taken; 16 warning; 32 idle. Our bits with no observable of theirs (the object taken
    without a grasp, the object having left the belt) do not enter the code."""
    visible, in_range, grasp, taken, warning, idle, max_bits = _bits_of(task)
    if isinstance(bits, bool) or not isinstance(bits, (int, np.integer)) or not \
            0 <= bits <= max_bits:
        raise ValueError(f"observation bits {bits!r} outside 0..{max_bits} of task {task.name!r}")
    code = 0
    if bits & in_range:
        code |= 1
    if not bits & visible:
        code |= 2
    if bits & grasp:
        code |= 4 if bits & taken else 8
    if bits & warning:
        code |= 16
    if bits & idle:
        code |= 32
    return code


def _codes(codes: Sequence[int]) -> np.ndarray:
    array = np.asarray(codes, dtype=np.int64).reshape(-1)
    if array.size and (array.min() < 0 or array.max() >= SIGNATURE_CODES):
        raise ValueError(f"signature codes must be 0..{SIGNATURE_CODES - 1}, got "
                         f"{[int(c) for c in array if not 0 <= c < SIGNATURE_CODES][:3]}")
    return array


# -- Bayesian policy reuse (the paper) --------------------------------------------------------
def signature_log_likelihood(signature: np.ndarray, codes: Sequence[int]) -> np.ndarray:
    """log P(σ | τ, π) for each type τ, of a task's signature σ = its steps' ``codes``, from
    the signature model of the policy π that ran it (``signature``: types x 64). Steps are
    taken as independent given the type and the policy: the product of their codes'
    probabilities (-inf for a type that gives a step probability 0)."""
    rows = np.asarray(signature, dtype=float)
    with np.errstate(divide="ignore"):
        return np.log(rows[:, _codes(codes)]).sum(axis=1)


def type_posterior(belief: np.ndarray, log_likelihood: np.ndarray) -> Optional[np.ndarray]:
    """BPR's type-belief update (Rosman et al. 2016, Sect. 3, the belief over types after a
    signal): β'(τ) ∝ P(σ | τ, π) β(τ), here from log P(σ | τ, π). None when the signature
    has probability 0 under every type the belief allows (Bayes' rule is then undefined)."""
    with np.errstate(divide="ignore"):
        log_posterior = np.log(np.asarray(belief, dtype=float)) + log_likelihood
    if not np.isfinite(log_posterior).any():
        return None
    return np.exp(log_posterior - _logsumexp(log_posterior))


def mix_with_uniform(belief: np.ndarray, forgetting: float) -> np.ndarray:
    """The forgetting floor: (1 - ε) β + ε / N. Every type keeps at least ε / N, so a switched
    human is recognised after a bounded amount of new evidence (docs/selectors.md)."""
    belief = np.asarray(belief, dtype=float)
    return (1.0 - forgetting) * belief + forgetting / belief.size


def expected_utilities(belief: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """Σ_τ β(τ) E[U | τ, π] for each policy π (``mean``: types x policies)."""
    return np.asarray(belief, dtype=float) @ np.asarray(mean, dtype=float)


def utility_ceiling(mean: np.ndarray, std: np.ndarray, top: float = UTILITY_MAX) -> float:
    """U_max, the largest utility a task can reach: the largest μ + 3σ over all (type,
    policy) pairs (3σ leaves out 0.13 % of a Gaussian), but never above the utility's own
    top (``top``, :data:`~ros_hrc.tasks.utility.UTILITY_MAX`). The cap matters: a policy
    that fails some tasks of a type has a bimodal utility and a wide σ, and a Gaussian with
    that σ puts chances above what any task can score; without the cap, BPR-EI paid for that
    impossible upside and chose the erratic policy over the sure one (docs/selectors.md)."""
    return float(min(np.max(np.asarray(mean) + 3.0 * np.asarray(std)), top))


def _norm():
    """scipy.stats.norm, imported when a selector first scores (the module's docstring)."""
    from scipy.stats import norm
    return norm


def _logsumexp(values: np.ndarray) -> float:
    """scipy.special.logsumexp, imported when a posterior is first updated (the module's
    docstring)."""
    from scipy.special import logsumexp
    return logsumexp(values)


def improvement_target(u_bar: float, u_max: float) -> float:
    """BPR-PI's U⁺ (Ū < U⁺ ≤ U_max): halfway from Ū to U_max. Our choice (docs/selectors.md):
    the paper leaves U⁺ to the user; halfway asks for a clear improvement, not a tie."""
    return u_bar + 0.5 * (u_max - u_bar)


def probability_of_improvement(belief: np.ndarray, mean: np.ndarray, std: np.ndarray,
                               u_plus: float) -> np.ndarray:
    """BPR-PI's score (Rosman et al. 2016, Sect. 4, probability of improvement):
    Σ_τ β(τ) P(U ≥ U⁺ | τ, π) for each policy π, with U | τ, π ~ N(mean, std)."""
    return np.asarray(belief, dtype=float) @ _norm().sf(u_plus, loc=mean, scale=std)


def _tail_integral(u: float, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """An antiderivative of u ↦ P(U ≥ u) for U ~ N(mean, std): (u - μ) P(U ≥ u) - σ φ(z),
    z = (u - μ)/σ; 0 at u = +inf."""
    if math.isinf(u) and u > 0:
        return np.zeros(np.broadcast(mean, std).shape)
    z = (u - mean) / std
    norm = _norm()
    return (u - mean) * norm.sf(z) - std * norm.pdf(z)


def expected_improvement(belief: np.ndarray, mean: np.ndarray, std: np.ndarray, u_bar: float,
                         u_max: float) -> np.ndarray:
    """BPR-EI's score (Rosman et al. 2016, Sect. 4, expected improvement):
    ∫ from Ū to U_max of Σ_τ β(τ) P(U ≥ U⁺ | τ, π) dU⁺ for each policy π — the expected
    improvement over Ū, capped at U_max — in closed form for U | τ, π ~ N(mean, std)."""
    mean, std = np.asarray(mean, dtype=float), np.asarray(std, dtype=float)
    per_pair = _tail_integral(u_max, mean, std) - _tail_integral(u_bar, mean, std)
    return np.asarray(belief, dtype=float) @ per_pair


# -- FABRIC's BPR ------------------------------------------------------------------------------
# FABRIC (cangorur/human_robot_collaboration, GPL-3.0), hrc_ros/src/policy_selector_bpr/
# policy_selector_bpr.py: belief_updater and computeEI/evaluateFSample (stored versions
# 4d8c00a and 1381476 read). Their numbers, our code:
#: Added to each type's prior belief before the update (so no type is ever ruled out for
#: good; their TODO asks for it, the issue's reading of their update has it).
FABRIC_BELIEF_EPSILON = 1e-5
#: Added to each step's signature probability (their "+1e-4", the smoothing of the counts).
FABRIC_SIGNATURE_EPSILON = 1e-4
#: Added to every std in the "EI" score (their "sigs[:, pol] + 2").
FABRIC_STD_WIDENING = 2.0
#: Points of their grid from Ū up to max μ + max σ (range(0, 600, 6) / 600: 0, 0.01, ... 0.99).
FABRIC_GRID_POINTS = 100
#: Their tie-break: a uniform draw in [0, 1e-5) added to each score before the argmax.
FABRIC_TIE_NOISE = 1e-5


def fabric_type_posterior(belief: np.ndarray, signature: np.ndarray,
                          codes: Sequence[int]) -> np.ndarray:
    """FABRIC's belief update: β'(τ) ∝ (β(τ) + 1e-5) · Π_steps (O[π, τ, code] + 1e-4), with O
    the signature model of the policy π that ran the task (``signature``: types x 64).
    Evaluated in logarithms (their float product underflows to 0/0 past ~80 steps of rare
    codes); the same numbers where theirs are finite."""
    rows = np.asarray(signature, dtype=float)
    log_posterior = (np.log(np.asarray(belief, dtype=float) + FABRIC_BELIEF_EPSILON)
                     + np.log(rows[:, _codes(codes)] + FABRIC_SIGNATURE_EPSILON).sum(axis=1))
    return np.exp(log_posterior - _logsumexp(log_posterior))


def fabric_scores(belief: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """FABRIC's "EI" score of each policy π: Σ_k Σ_τ β(τ) N(U_k; μ[τ, π], σ[τ, π] + 2), the
    Gaussian *density* summed over 100 points U_k = Ū + k (max μ + max σ - Ū) / 100,
    k = 0..99, with Ū = max_π Σ_τ β(τ) μ[τ, π]. (Up to the grid's step this is the
    probability mass above Ū, a probability of improvement, not the paper's EI.)"""
    belief = np.asarray(belief, dtype=float)
    mean, std = np.asarray(mean, dtype=float), np.asarray(std, dtype=float)
    u_bar = float(np.max(expected_utilities(belief, mean)))
    top = float(mean.max() + std.max())
    grid = u_bar + np.arange(FABRIC_GRID_POINTS) * (top - u_bar) / FABRIC_GRID_POINTS
    density = _norm().pdf(grid[:, None, None], loc=mean[None], scale=std[None] + FABRIC_STD_WIDENING)
    return np.einsum("kti,t->i", density, belief)


# -- the bandit's reward -----------------------------------------------------------------------
#: The utility's range (ros_hrc.tasks.utility.task_utility: 1 at best; a failure at the
#: timeout with a pre-emption, -1.0, or with warnings, lower): the bandit maps it onto [0, 1].
BANDIT_UTILITY_RANGE = (-1.5, 1.0)


def bandit_reward(utility: float) -> float:
    """A task's utility as UCB1's reward in [0, 1]: clipped to :data:`BANDIT_UTILITY_RANGE`
    and scaled linearly (UCB1's confidence bound is for rewards in [0, 1])."""
    low, high = BANDIT_UTILITY_RANGE
    return (min(max(float(utility), low), high) - low) / (high - low)


# -- the selectors -------------------------------------------------------------------------------
def _uniform(n: int) -> np.ndarray:
    return np.full(n, 1.0 / n) if n else np.zeros(0)


class FixedSelector(Selector):
    """``fixed:<policy>``: always that policy."""

    def __init__(self, policy: str) -> None:
        self.policy = policy
        self.name = f"fixed:{policy}"
        self.note = ""

    def choose(self) -> str:
        return self.policy


class RandomSelector(Selector):
    """``random``: a policy drawn uniformly from the library for each task."""

    name = "random"

    def __init__(self, policies: Sequence[str], rng: np.random.Generator) -> None:
        self.policies = tuple(policies)
        self.rng = rng
        self.note = ""

    def choose(self) -> str:
        return self.policies[int(self.rng.integers(len(self.policies)))]


class BprSelector(Selector):
    """``bpr`` (rule "ei") and ``bpr-pi`` (rule "pi", :class:`BprPiSelector`): Bayesian
    policy reuse over the model's types. The belief starts uniform; after each task it is
    updated from the task's signature (:func:`type_posterior`) and mixed with uniform by
    ``forgetting`` (:func:`mix_with_uniform`). ``choose`` takes the policy of largest expected
    improvement (or probability of improvement) over Ū = max_π Σ_τ β(τ) E[U | τ, π]; ties go
    to the library's first."""

    needs_model = True
    #: Its score: "ei" (expected improvement) or "pi" (probability of improvement).
    RULE = "ei"

    @classmethod
    def create(cls, policies, model, rng, forgetting) -> "BprSelector":
        return cls(model, cls.RULE, float(forgetting))

    def __init__(self, model: SelectorModel, rule: str, forgetting: float) -> None:
        if rule not in ("ei", "pi"):
            raise ValueError(f"unknown BPR rule {rule!r}: ei or pi")
        self.model = model
        self.rule = rule
        self.name = "bpr" if rule == "ei" else "bpr-pi"
        self.forgetting = float(forgetting)
        self.type_names = model.types
        self.note = ""
        self._belief = _uniform(len(model.types))
        self._u_max = utility_ceiling(model.mean, model.std)

    def scores(self) -> np.ndarray:
        """The rule's score of each library policy under the current belief."""
        m = self.model
        u_bar = float(np.max(expected_utilities(self._belief, m.mean)))
        if self.rule == "ei":
            return expected_improvement(self._belief, m.mean, m.std, u_bar, self._u_max)
        return probability_of_improvement(self._belief, m.mean, m.std,
                                          improvement_target(u_bar, self._u_max))

    def choose(self) -> str:
        return self.model.policies[int(np.argmax(self.scores()))]

    def observe(self, result: TaskResult) -> None:
        m = self.model
        log_likelihood = signature_log_likelihood(m.signature[m.policy_index(result.policy)],
                                                  result.signature)
        posterior = type_posterior(self._belief, log_likelihood)
        if posterior is None:
            self.note = ("the task's signature has probability 0 under every type: the belief "
                         "is kept")
            posterior = self._belief
        else:
            self.note = ""
        self._belief = mix_with_uniform(posterior, self.forgetting)

    def belief(self) -> np.ndarray:
        return self._belief.copy()


class BprPiSelector(BprSelector):
    """``bpr-pi``: :class:`BprSelector` scoring by the probability of improvement."""

    RULE = "pi"


class FabricBprSelector(Selector):
    """``bpr-fabric``: FABRIC's BPR — their belief update (:func:`fabric_type_posterior`, which
    forgets nothing beyond its 1e-5) and their score (:func:`fabric_scores`), ties broken by
    their 1e-5 uniform noise drawn from the selector's generator."""

    name = "bpr-fabric"
    needs_model = True

    @classmethod
    def create(cls, policies, model, rng, forgetting) -> "FabricBprSelector":
        return cls(model, rng)

    def __init__(self, model: SelectorModel, rng: np.random.Generator) -> None:
        self.model = model
        self.rng = rng
        self.type_names = model.types
        self.note = ""
        self._belief = _uniform(len(model.types))

    def scores(self) -> np.ndarray:
        """FABRIC's "EI" score of each library policy under the current belief."""
        return fabric_scores(self._belief, self.model.mean, self.model.std)

    def choose(self) -> str:
        scores = self.scores()
        noisy = scores + self.rng.random(scores.size) * FABRIC_TIE_NOISE
        return self.model.policies[int(np.argmax(noisy))]

    def observe(self, result: TaskResult) -> None:
        m = self.model
        self._belief = fabric_type_posterior(
            self._belief, m.signature[m.policy_index(result.policy)], result.signature)

    def belief(self) -> np.ndarray:
        return self._belief.copy()


class BanditSelector(Selector):
    """``bandit``: UCB1 (MABWiser's ``LearningPolicy.UCB1``, α = 1: Auer et al.'s bound
    mean + sqrt(2 ln n / n_π)) over the library, rewarded with :func:`bandit_reward` of each
    task's utility. Each policy is played once first (UCB1's start), in an order drawn from the
    selector's generator; no model, no types."""

    name = "bandit"

    def __init__(self, policies: Sequence[str], rng: np.random.Generator) -> None:
        from mabwiser.mab import MAB, LearningPolicy   # pandas and scikit-learn: only when used

        self.policies = tuple(policies)
        self.rng = rng
        self.note = ""
        self._decisions: list = []
        self._rewards: list = []
        self._mab = MAB(arms=list(self.policies), learning_policy=LearningPolicy.UCB1(alpha=1.0),
                        seed=int(rng.integers(2 ** 31)))

    def choose(self) -> str:
        untried = [p for p in self.policies if p not in self._decisions]
        if untried:
            return untried[int(self.rng.integers(len(untried)))]
        self._mab.fit(decisions=self._decisions, rewards=self._rewards)
        return str(self._mab.predict())

    def observe(self, result: TaskResult) -> None:
        if result.policy not in self.policies:
            raise ValueError(f"policy {result.policy!r} is not in the library: "
                             f"{', '.join(self.policies)}")
        self._decisions.append(result.policy)
        self._rewards.append(bandit_reward(result.utility))


class OracleSelector(Selector):
    """``oracle``: told the human's true type before each task (``tell_true_type``), it takes
    the policy of largest mean utility for that type in the model. A type the model was not
    trained on (or none told yet) gets the policy best on average over the model's types, and
    ``note`` says so. Its belief is all on the told type (uniform when it is unknown)."""

    name = "oracle"
    needs_model = True

    @classmethod
    def create(cls, policies, model, rng, forgetting) -> "OracleSelector":
        return cls(model)

    def __init__(self, model: SelectorModel) -> None:
        self.model = model
        self.type_names = model.types
        self.note = ""
        self._true_type: Optional[str] = None

    def tell_true_type(self, name: str) -> None:
        self._true_type = str(name)

    def choose(self) -> str:
        m = self.model
        row = m.type_index(self._true_type) if self._true_type is not None else None
        if row is None:
            told = (f"human type {self._true_type!r} is not one the model was trained on"
                    if self._true_type is not None else "no human type told")
            self.note = f"{told}: the policy best on average over the model's types"
            return m.policies[int(np.argmax(m.mean.mean(axis=0)))]
        self.note = ""
        return m.policies[int(np.argmax(m.mean[row]))]

    def belief(self) -> np.ndarray:
        row = self.model.type_index(self._true_type) if self._true_type is not None else None
        if row is None:
            return _uniform(len(self.model.types))
        belief = np.zeros(len(self.model.types))
        belief[row] = 1.0
        return belief


def make_selector(spec: str, policies: Sequence[str], model: Optional[SelectorModel],
                  seed: int, forgetting: float) -> Selector:
    """The selector ``spec`` names ('fixed:<policy>', or a registered selector: 'random', 'bpr',
    'bpr-pi', 'bpr-fabric', 'bandit', 'oracle', an installed package's, or 'module:Class')
    over the library ``policies``, with the selector model ``model`` (one that
    ``needs_model`` needs one; it must be of these policies), its generator seeded with
    ``seed`` (the caller's ``streams.stream_seed(run seed, sequence, "selector")``) and
    ``forgetting`` the BPR belief's floor (``bpr_forgetting``, 0 <= ε < 1). ValueError with
    one line for anything else."""
    text = str(spec).strip()
    name, colon, argument = text.partition(":")
    policies = tuple(str(p) for p in policies)
    if not policies or len(set(policies)) != len(policies):
        raise ValueError(f"the library's policies must be distinct and at least one, got "
                         f"{', '.join(policies) or '(none)'}")
    if name == FIXED:
        if not argument:
            raise ValueError("selector 'fixed' names no policy: 'fixed' alone is the launch's "
                             "single robot, 'fixed:<policy>' a library policy")
        if argument not in policies:
            raise ValueError(f"selector {text!r}: no policy {argument!r} in the library; its "
                             f"policies: {', '.join(policies)}")
        return FixedSelector(argument)
    if colon and name in registry.names(registry.SELECTORS):
        raise ValueError(f"selector {name!r} takes no argument, got {text!r}")
    try:
        kind = selector_class(text)    # a registered name or module:Class
    except registry.RegistryError as exc:
        raise ValueError(f"{exc}; also fixed:<policy>") from None
    if isinstance(forgetting, bool) or not isinstance(forgetting, (int, float)) or not \
            0.0 <= float(forgetting) < 1.0:
        raise ValueError(f"bpr_forgetting must be a number from 0 to below 1, got {forgetting!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"a selector's seed must be an integer >= 0, got {seed!r}")
    if kind.needs_model:
        if model is None:
            raise ValueError(f"selector {text!r} needs a selector model; none was given (make "
                             "train-selector writes one)")
        if model.policies != policies:
            raise ValueError(f"the selector model is of the policies {', '.join(model.policies)}; "
                             f"the library's are {', '.join(policies)} (make train-selector)")
    selector = kind.create(policies, model, np.random.default_rng(int(seed)), float(forgetting))
    selector.name = text      # what the reports call it: the name it was asked by
    return selector
