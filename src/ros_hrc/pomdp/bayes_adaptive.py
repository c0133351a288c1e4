"""A POMDP whose dynamics are learnt while it is used: Dirichlet posteriors over T (and O).

The ROS-free core of a Bayes-adaptive robot (Ross, Chaib-draa and Pineau, JMLR 2011; root
sampling as in BAMCP, Guez, Silver and Dayan, NeurIPS 2012): a prior model's rows, each a
Dirichlet of ``strength`` pseudo-counts (``alpha = strength * prior row``), plus the counts
that experience added. The experience of a task is its actions and observations only (the
true state is never read): :func:`expected_counts` runs forward-backward over them under a
model (the posterior mean) and returns the expected number of times each transition and each
observation happened, which :meth:`DirichletPosterior.learn` adds.

With prior row ``p``, strength ``k`` and a row's counts ``n``, the posterior mean row is
``(k p + n) / sum(k p + n)`` (:func:`ros_hrc.pomdp.fit.posterior_table`, the same rule as
``hrc_fit``'s labelled fit), and a row drawn from the posterior is a Dirichlet draw on the
prior row's support (:meth:`DirichletPosterior.sample`). :meth:`DirichletPosterior.forget`
moves the counts towards the prior (``n <- (1 - rate) n``), so that a human who changed is
learnt again.

Planning on the posterior (:func:`planning_model`): its mean (certainty equivalence), or a
model that plans for what learning is worth, made by root sampling (BAMCP's idea, as
BA-POMCP applies it to POMDPs): ``draws`` models drawn from the posterior, composed
(:func:`ros_hrc.pomdp.typed.compose`) into one POMDP whose hidden state is (draw, state) with a
uniform prior over the draws. A planner's scenarios then each start in one draw's dynamics,
and its belief update weighs the draws by how well each explains what the task shows, so a
tree search values an action also for what it reveals of this human. The draws are names
``d0``, ``d1``, ... and mean nothing beyond the task.

A task's ending is evidence too (:data:`End`): one more transition under the robot's last
action, into the states the ending allows. What an action would teach for the tasks after
this one is priced by :class:`LookBonus`, on a decision's first step only (the models a
planner gets keep the prior's rewards).

Steps are ``(action, observation)`` pairs by index: ``action`` is the one taken before
``observation`` was made (the robot's previous action; for a task's first step its idle
action), as the robot's belief update takes them. No task is known here.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import ModelError
from ros_hrc.pomdp.fit import posterior_table
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.typed import compose

__all__ = ["End", "expected_counts", "DirichletPosterior", "check_strength", "check_forgetting",
           "check_draws", "check_bonus", "planning_model", "reach_probability", "LookBonus",
           "PLANNING"]

#: How a robot plans on its posterior: ``sampled`` (root sampling over ``draws`` models drawn
#: from it) or ``mean`` (the posterior mean alone).
PLANNING = ("sampled", "mean")

Step = Tuple[int, int]


#: How a task ended, as evidence of its last transition: the robot's last ``action`` (chosen
#: after the last observation, never followed by one) and, per state, whether the task could
#: have ended in it (``states``: 1 where it could, 0 where not). A success is the success
#: state and nothing else; a task that ran out is any state but it.
End = Tuple[int, np.ndarray]


def expected_counts(model: Model, steps: Sequence[Step],
                    belief: Optional[np.ndarray] = None,
                    end: Optional[End] = None) -> Tuple[np.ndarray, np.ndarray]:
    """The expected counts of a task's hidden transitions and observations under ``model``,
    given its ``steps`` (``(action, observation)`` indices), the belief it started from
    (``belief``; the model's initial belief when None) and, with ``end``, how it ended (one
    more transition, under the robot's last action, into a state the end allows; no
    observation): ``(transitions[a, s, s'], observations[a, s', o])``, float arrays whose
    entries for each step sum to 1.

    The end is what ``hrc_fit`` counts as a success's last transition, and what tells a
    learner that a human it left alone after a failure went on to succeed: without it the
    task's last and most telling transition is never counted.

    Forward-backward (scaled): an observation the model gives probability 0 after the
    prediction is left out of that step (the belief keeps the prediction, as the robot's
    belief update does), so that one surprise does not void the task; so is an end the model
    cannot reach."""
    T, O = model.dense_T, model.dense_O
    A, S, _ = T.shape
    n_obs = O.shape[2]
    b = np.asarray(model.initial_belief if belief is None else belief, dtype=float)
    if b.shape != (S,) or not np.isfinite(b).all() or b.min() < 0 or b.sum() <= 0:
        raise ModelError(f"the starting belief must be {S} non-negative numbers, not {b!r}")
    for a, o in steps:
        if not (0 <= a < A and 0 <= o < n_obs):
            raise ModelError(f"step ({a}, {o}) is outside the model's {A} actions and "
                             f"{n_obs} observations")
    # Each transition: its action and the likelihood of what followed it, per next state.
    chain = [(a, O[a][:, o]) for a, o in steps]
    if end is not None:
        end_action, allowed = end
        allowed = np.asarray(allowed, dtype=float)
        if not 0 <= end_action < A or allowed.shape != (S,) or allowed.min() < 0:
            raise ModelError(f"a task's end must be an action of the model's {A} and {S} "
                             f"non-negative weights, not ({end_action!r}, {allowed!r})")
        chain.append((end_action, allowed))
    transitions = np.zeros((A, S, S))
    observations = np.zeros((A, S, n_obs))
    if not chain:
        return transitions, observations
    # Forward: alpha[t] is P(s_t | what followed the first t transitions).
    alphas, likelihoods = [b / b.sum()], []
    for a, likelihood in chain:
        predicted = alphas[-1] @ T[a]
        if not (predicted @ likelihood) > 0:
            likelihood = np.ones(S)      # an impossible observation: the prediction stands
        posterior = predicted * likelihood
        alphas.append(posterior / posterior.sum())
        likelihoods.append(likelihood)
    # Backward: beta[t] (scaled) with alpha[t] * beta[t] = P(s_t | all the evidence).
    beta = np.ones(S)
    for t in range(len(chain), 0, -1):
        a = chain[t - 1][0]
        weighted = likelihoods[t - 1] * beta                      # over s_t
        joint = alphas[t - 1][:, None] * T[a] * weighted[None, :]  # (s_{t-1}, s_t)
        total = joint.sum()
        joint /= total
        transitions[a] += joint
        if t <= len(steps):                                       # the end saw nothing
            observations[a][:, steps[t - 1][1]] += joint.sum(axis=0)
        beta = (T[a] @ weighted) / total
    return transitions, observations


def _checked(value, what: str, rule: str, holds) -> float:
    """``value`` as a float when it is a finite number for which ``holds`` is true; else a
    one-line ValueError saying what it must be."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a number, not {value!r}") from None
    if not (math.isfinite(x) and holds(x)):
        raise ValueError(f"{what} must be {rule}, not {value!r}")
    return x


def check_strength(strength: float) -> float:
    """The prior's strength ``kappa`` (pseudo-counts per row): a finite number > 0."""
    return _checked(strength, "the prior's strength", "a finite number > 0", lambda k: k > 0)


def check_forgetting(rate: float) -> float:
    """A forgetting rate: from 0 (keep everything) to 1 (back to the prior)."""
    return _checked(rate, "the forgetting rate", "from 0 to 1", lambda r: 0.0 <= r <= 1.0)


def check_bonus(bonus: float) -> float:
    """The exploration bonus (reward units of the prior): a finite number >= 0."""
    return _checked(bonus, "the exploration bonus", "a finite number >= 0", lambda b: b >= 0)


def check_draws(draws: int) -> int:
    """Root sampling's number of models drawn: a whole number from 1 to 64 (each adds the
    prior's states once more to the model the planner plans on)."""
    if isinstance(draws, bool) or not isinstance(draws, (int, np.integer)) \
            or not 1 <= int(draws) <= 64:
        raise ValueError(f"the number of posterior draws must be a whole number from 1 to 64, "
                         f"not {draws!r}")
    return int(draws)


def reach_probability(transitions: np.ndarray, start: int, target: int, steps: int) -> float:
    """P(the state is ``target`` after at most ``steps`` steps from ``start``) under one
    action's transition table ``transitions[s, s']`` (dense), ``target`` made absorbing
    (reaching it is what counts)."""
    T = np.array(transitions, dtype=float, copy=True)
    T[target] = 0.0
    T[target, target] = 1.0
    p = np.zeros(T.shape[0])
    p[start] = 1.0
    for _ in range(steps):
        p = p @ T
    return float(p[target])


def _dirichlet_rows(p: np.ndarray, counts: np.ndarray, k: float,
                    rng: np.random.Generator) -> np.ndarray:
    """A Dirichlet draw of every row at once (normalised Gamma draws) on the support of the
    prior rows ``p``, with parameters ``k p + counts``."""
    support = p > 0
    gammas = np.zeros_like(p)
    gammas[support] = rng.standard_gamma(k * p[support] + counts[support])
    totals = gammas.sum(axis=1, keepdims=True)
    # A row whose every Gamma draw underflowed to 0 (tiny parameters) keeps its mean.
    empty = totals[:, 0] <= 0
    if empty.any():
        gammas[empty] = (k * p[empty] + counts[empty]) * support[empty]
        totals = gammas.sum(axis=1, keepdims=True)
    return gammas / totals


@dataclass
class DirichletPosterior:
    """A prior model's T (and, with ``learn_observations``, O) as Dirichlet posteriors: each
    row ``strength * prior row`` plus the expected counts learnt so far (``transitions``,
    ``observations``, float arrays). Rewards, discount, initial belief and names stay the
    prior's."""

    prior: Model
    strength: float
    learn_observations: bool = False
    transitions: Optional[np.ndarray] = None      # (A, S, S') counts learnt
    observations: Optional[np.ndarray] = None     # (A, S', O) counts learnt

    def __post_init__(self) -> None:
        self.strength = check_strength(self.strength)
        self.prior.validate()
        A, S, n_obs = self.prior.n_actions, self.prior.n_states, self.prior.n_observations
        if self.transitions is None:
            self.transitions = np.zeros((A, S, S))
        if self.observations is None:
            self.observations = np.zeros((A, S, n_obs))
        if self.transitions.shape != (A, S, S) or self.observations.shape != (A, S, n_obs):
            raise ModelError(f"the counts are not sized for the prior's {A} actions, {S} "
                             f"states and {n_obs} observations")

    def learn(self, steps: Sequence[Step], belief: Optional[np.ndarray] = None,
              forget_first: float = 0.0, end: Optional[End] = None) -> None:
        """Add a task's expected counts (with ``end``, its ending too: :func:`expected_counts`),
        computed under the posterior mean; with ``forget_first``, the counts so far are moved
        towards the prior by that rate (:meth:`forget`) after the task's were computed and
        before they are added."""
        transitions, observations = expected_counts(self.mean(), steps, belief, end)
        if forget_first:
            self.forget(forget_first)
        self.transitions += transitions
        if self.learn_observations:
            self.observations += observations

    def forget(self, rate: float) -> None:
        """Move the counts towards the prior: ``n <- (1 - rate) n`` (0 keeps them, 1 is the
        prior again)."""
        keep = 1.0 - check_forgetting(rate)
        self.transitions *= keep
        self.observations *= keep

    def times_seen(self, action: int) -> np.ndarray:
        """``n(s)``: the times ``action`` was taken in each state ``s`` by the counts learnt
        (expected counts, forgetting applied)."""
        return self.transitions[action].sum(axis=1)

    def _model(self, T, O, name: str) -> Model:
        prior = self.prior
        model = dataclasses.replace(
            prior, T=T, O=O, R=[sp.csr_matrix(r, copy=True) for r in prior.R],
            initial_belief=np.array(prior.initial_belief, dtype=float, copy=True),
            fully_observable=prior.fully_observable and not self.learn_observations,
            observed_key=(np.array(prior.observed_key, copy=True)
                          if prior.observed_key is not None and not self.learn_observations
                          else None),
            name=name, source=None, meta=dict(prior.meta))
        return model

    def mean(self) -> Model:
        """The posterior mean model (certainty equivalence)."""
        k, prior = self.strength, self.prior
        T = [posterior_table(prior.T[a], self.transitions[a], k) for a in range(prior.n_actions)]
        O = [posterior_table(prior.O[a], self.observations[a], k)
             for a in range(prior.n_actions)] if self.learn_observations else \
            [sp.csr_matrix(o, copy=True) for o in prior.O]
        return self._model(T, O, f"{prior.name or 'model'}-posterior-mean")

    def mean_transitions(self, action: int) -> np.ndarray:
        """The posterior mean of one action's T, dense ``[s, s']``."""
        return posterior_table(self.prior.T[action], self.transitions[action],
                               self.strength).toarray()

    def sample_transitions(self, action: int, rng: np.random.Generator) -> np.ndarray:
        """One action's T drawn from the posterior, dense ``[s, s']`` (as :meth:`sample`
        draws every table)."""
        return _dirichlet_rows(sp.csr_matrix(self.prior.T[action]).toarray().astype(float),
                               self.transitions[action], self.strength, rng)

    def sample(self, rng: np.random.Generator) -> Model:
        """A model drawn from the posterior: every row a Dirichlet draw on the prior row's
        support (a transition the prior rules out stays ruled out), as a scenario of root
        sampling draws its model."""
        k, prior = self.strength, self.prior

        def draw(table: sp.csr_matrix, counts: np.ndarray) -> sp.csr_matrix:
            drawn = sp.csr_matrix(_dirichlet_rows(sp.csr_matrix(table).toarray().astype(float),
                                                  counts, k, rng))
            drawn.eliminate_zeros()
            return drawn

        T = [draw(prior.T[a], self.transitions[a]) for a in range(prior.n_actions)]
        O = [draw(prior.O[a], self.observations[a]) for a in range(prior.n_actions)] \
            if self.learn_observations else [sp.csr_matrix(o, copy=True) for o in prior.O]
        return self._model(T, O, f"{prior.name or 'model'}-posterior-draw")


def planning_model(posterior: DirichletPosterior, planning: str, draws: int,
                   rng: np.random.Generator) -> Model:
    """The model a planner plans the next task on (see the module docstring): the posterior
    mean (``planning="mean"``), or ``draws`` posterior draws composed by root sampling
    (``"sampled"``), their states ``<state>__d<i>``."""
    if planning == "mean":
        return posterior.mean()
    if planning != "sampled":
        raise ValueError(f"planning must be one of {', '.join(PLANNING)}, not {planning!r}")
    models = {f"d{i}": posterior.sample(rng) for i in range(check_draws(draws))}
    return compose(models, name=f"{posterior.prior.name or 'model'}-posterior-draws")


class LookBonus:
    """An exploration bonus for one task, paid on a decision's first step only: taking
    ``action`` in state ``s`` is worth ``scale / (1 + n(s) + m(s))`` more there, ``n(s)`` the
    times the posterior has seen it (:meth:`DirichletPosterior.times_seen`, at the task's
    start) and ``m(s)`` the looks this task has taken so far (:meth:`looked`: the belief in
    ``s`` at each decision that took it).

    Why (BEB: Kolter and Ng, ICML 2009): DESPOT plans one task, so what an action would teach
    for the tasks after it is worth nothing to it, and root sampling alone does not explore
    (docs/study/learning.md). Why on the first step only, and falling with this task's looks:
    a bonus in the model's rewards is paid on every step the planner imagines and only fades
    between tasks, so a robot can stare at a human who never recovers until the task runs
    out, and its search never closes its bounds (every decision ran all its trials,
    docs/performance.md). Here the tree plans on the posterior's own rewards; only the
    decision now is weighed by what it would show, and each look makes the next worth less.
    """

    def __init__(self, scale: float, action: int, times_seen: np.ndarray) -> None:
        self.scale = check_bonus(scale)
        self.action = action
        self.times_seen = np.asarray(times_seen, dtype=float)
        self.looks = np.zeros_like(self.times_seen)

    def per_state(self) -> np.ndarray:
        """The bonus on ``action`` at the next decision, per state."""
        return self.scale / (1.0 + self.times_seen + self.looks)

    def looked(self, belief: np.ndarray) -> None:
        """A decision took ``action`` while believing ``belief`` (over the states)."""
        self.looks += np.asarray(belief, dtype=float)
