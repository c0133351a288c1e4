"""DESPOT: online POMDP planning with regularization (Ye, Somani, Hsu and Lee, JAIR 2017).

At every step the planner samples K *scenarios* from the current belief: a start state and a
stream of random numbers, one pair per depth. Simulating a scenario under an action sequence
with those numbers is deterministic, so the scenarios induce a sparse tree (a DESPOT) whose
belief nodes hold the scenarios consistent with their action-observation history. The tree is
built anytime, by trials, within a time budget (and an optional trial cap):

* every belief node b keeps, weighted by |Φ_b|/K·γ^Δ(b) (its share of scenarios, discounted):
  ℓ0(b) the default policy's value, U(b) an upper bound on its value, and the bounds
  ℓ(b) <= ν*(b) <= μ(b) on the best *regularized* value, where each policy node costs λ;
* a trial descends from the root along the action with the largest μ and the observation whose
  child has the largest weighted excess uncertainty E(b') = ε(b') − ξ·|Φ_b'|/K·ε(root),
  ε = μ − ℓ; it stops at depth D (the node gets its default value), when E <= 0, or when the
  node is *blocked*: some ancestor b' cannot repay the regularization of the path to it,
  |Φ_b'|/K·γ^Δ(b')·(U(b') − ℓ0(b')) <= λ·(Δ(b) − Δ(b')), in which case the blocked nodes get
  their default values;
* the path is then backed up (ρ(b,a) = Σ_φ γ^Δ R / K − λ):
  μ(b) = max(ℓ0(b), max_a ρ(b,a) + Σ μ(b')),  ℓ(b) likewise,  U(b) = max_a ρ(b,a) + λ + Σ U(b'),
* the action returned is the one with the best lower bound ℓ(b0, a) (or the default action when
  no expanded action beats it). Those values are what ``last_stats.action_values`` reports
  per action (why the robot acted: the value it chose by, against the others'); they are the
  lower bounds, not the upper bounds μ the trials descend by, because the choice compares
  them (and μ of an action the trials never entered is only its heuristic bound).

Bounds: the upper bound is the fully observable MDP's value ("mdp", default), the fast informed
bound max_a of the scenarios' mean Q_FIB(s, a) ("fib", small models), or the trivial
max R/(1−γ) ("trivial"). The default policy is the best fixed action, valued exactly for each
scenario's state by the blind-policy values ("blind", default: as if the rollout went on
forever, at the cost of a table lookup), or simulated along the scenario's own random stream
down to depth D ("rollout", as in the paper; slower), or the best of the fixed actions and the
conditional plans of an offline policy's alpha vectors ("policy": pass ``default_policy``, or
for a small model one is solved in about a second).

Speed: each scenario's random numbers for one depth are drawn once, as a (K, 2) block, the first
time any node of that depth needs them, so the same (scenario, depth) always gets the same numbers
within a search. Expanding a node steps all its scenarios under all actions with two
``np.searchsorted`` on ``ModelSampler``'s flat cumulative tables (read through tables aligned
with T's and O's entries that give the next observation row and the child's (action,
observation) key directly), groups them by key with one sort, and sums the children's bound and
default-plan values in one ``np.add.reduceat``. Children are not objects until a trial enters
them: one ``_Kids`` per expansion holds their ranges and bounds as parallel lists, which makes
an expansion and freeing the tree cheaper (most children are never entered). Every sum keeps the
order it always had, so a trial-bounded search builds the same tree to the last bit.

Beliefs are exact for small models (scenarios are drawn from the exact belief) and particle
filters for large ones (``DespotConfig.particles``).

Memory: the tables are O(non-zeros of T and O + A·S); a search adds its scenarios' random numbers
(2·K·(D+1) at most) and its tree, which ``DespotConfig.max_nodes`` caps (``hrc_pomdp`` sets it
from ``--memory-limit``; :func:`memory_needed` estimates the rest).

Time: ``time_per_step`` bounds all of act(), and the belief updates since the previous act(), not
only the trials: the garbage collector is paused during act() (the tree has no reference cycles
and is freed before act() returns), and the search stops before an expansion predicted to end
too late to free the tree in time. Under ``max_trials`` with a generous budget none of this
changes a trial or a random draw; with ``time_per_step`` infinite (no time budget, which needs
``max_trials``) the search is bounded by work alone: no clock reading changes it, so the same
seed gives the same decision on any machine and under any load (what experiments run).
"""
from __future__ import annotations

import gc
import math
import time
from bisect import bisect_left
from functools import reduce
from itertools import accumulate
from operator import add
from dataclasses import dataclass
from typing import Any, Dict, List, Mapping, Optional, Tuple

import numpy as np

from ros_hrc.errors import SolverError
from ros_hrc.pomdp import mdp, sampling
from ros_hrc.pomdp.despot_parameters import (DESPOT_PARAMETERS, EXACT_BELIEF_MAX_STATES,
                                             SETTING_NAMES, config_value, parameter)
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.planner import BeliefPlanner, PlannerStats
from ros_hrc.pomdp.policy import Policy
from ros_hrc.pomdp.sampling import U_MAX, ModelSampler

#: Particle count of the default particle belief.
DEFAULT_PARTICLES = 2000

#: First guess of the seconds it takes to free one node of a finished tree (measured on every
#: search afterwards); the search stops early enough to free its tree within the budget.
FREE_SECONDS_PER_NODE = 1e-6

#: Safety factor on that estimate, the fewest nodes a measurement is taken from, and the most
#: a measurement may say (a stall while freeing must not starve the next searches).
FREE_MARGIN = 1.5
#: Relative difference below which two actions' values are a tie (see _best_action).
TIE_TOLERANCE = 1e-6
FREE_MIN_NODES = 100
FREE_MAX_PER_NODE = 1e-5

#: Weight of the newest expansion in the running means that predict the next one's duration.
EXPAND_WEIGHT = 0.1

#: What one node of a tree costs, its share of the scenario arrays included: measured 420-530
#: bytes on Tiger and the robot model, 1.4 KB on RockSample_7_8 (13 actions), rounded up.
BYTES_PER_NODE = 2048

def _default(name: str):
    return parameter(name).default


@dataclass
class DespotConfig:
    """DESPOT's parameters (the paper's names in brackets). Their defaults, limits and docs
    are :mod:`ros_hrc.pomdp.despot_parameters`'; here ``time_per_step`` inf is no time budget
    and ``max_trials`` None no cap (a command line's 0 for both: ``config_value``)."""

    scenarios: int = _default("scenarios")          # [K] scenarios sampled per search
    depth: int = _default("depth")                  # [D] maximum depth of the tree
    pruning: float = _default("lambda")             # [λ] regularization: one policy node's cost
    xi: float = _default("xi")                      # [ξ] target gap fraction of the excess
    time_per_step: float = _default("time_per_step")   # seconds of search per act(); inf: none
    max_trials: Optional[int] = None   # stop after this many trials too (reproducible runs)
    upper: str = _default("upper")                  # "mdp" | "fib" | "trivial"
    lower: str = _default("lower")                  # "blind" | "policy" | "rollout"
    particles: Optional[int] = None    # particle belief of this size; None: exact when small
    gap_tolerance: float = 1e-6        # [ε0] stop early once the root gap is this small
    max_nodes: Optional[int] = None    # stop a search once its tree has this many nodes

    def validate(self) -> None:
        """SolverError, one line naming the parameter and its limits, when one is out of
        range."""
        for p in DESPOT_PARAMETERS:
            value = getattr(self, p.field)
            none = (p.name == "time_per_step" and value == math.inf) or (
                value is None and (p.name in ("max_trials", "particles")))
            if not none and not p.accepts(value):
                raise SolverError(p.refusal(value))
        if math.isinf(self.time_per_step) and self.max_trials is None:
            # Work-bounded search (experiments): the trials alone end it, so they must.
            raise SolverError("DESPOT without a time budget (time_per_step 0) needs "
                              "max_trials")
        if self.max_nodes is not None and self.max_nodes < 1:
            raise SolverError(f"max_nodes must be at least 1, got {self.max_nodes}")


def memory_needed(model: Model, config: DespotConfig) -> int:
    """Bytes DESPOT needs besides its tree: the model's sampler and bounds (an upper estimate
    from the sizes and non-zeros), one belief and one search's scenarios and expansions."""
    A, S, Z = model.n_actions, model.n_states, model.n_observations
    nnz_t = sum(t.nnz for t in model.T)
    nnz_o = sum(o.nnz for o in model.O)
    tables = sampling.memory_needed(model) + 8 * (2 * nnz_t + 2 * nnz_o)  # + aligned rows, keys
    bounds = 8 * 12 * A * S                     # value iteration, blind policies, bound rows
    if config.upper == "fib" and mdp.fib_is_dense(model):
        bounds += 8 * (2 * A * Z * S * S + A * A * Z * S)
    particles = config.particles
    if particles is None and S > EXACT_BELIEF_MAX_STATES:
        particles = DEFAULT_PARTICLES
    belief = 8 * 4 * S + (48 * particles if particles else 0)
    K = config.scenarios
    search = 16 * K * (config.depth + 2) + 8 * 8 * A * K + 8 * A * Z
    return tables + bounds + belief + search


class DespotTables:
    """What DESPOT precomputes for a model; build once and share between planners.

    ``plans``/``plan_actions`` are the default policy's candidate plans as value vectors: the
    blind policies (one per action) and, for ``lower="policy"``, the alpha vectors of an offline
    policy (each the value of a conditional plan that starts with its action).
    """

    def __init__(self, model: Model, upper: str = "mdp", lower: str = "blind",
                 default_policy: Optional[Policy] = None, policy_seconds: float = 1.0) -> None:
        self.model = model
        self.key = (upper, lower)
        self.sampler = ModelSampler(model)
        gamma = float(model.discount)
        R = np.asarray(model.R_sa, dtype=float)
        self.blind = mdp.blind_lower_bound(model)                    # (A, S)
        self.plans = self.blind
        self.plan_actions = np.arange(model.n_actions)
        if lower == "policy":
            if default_policy is None:
                if model.fully_observable or model.n_states > mdp.DENSE_STATE_LIMIT:
                    raise SolverError('lower="policy" needs a default policy for this model')
                from ros_hrc.pomdp import offline   # only this option needs the offline solver
                default_policy = offline.solve(model, timeout=policy_seconds, precision=1e-2)
            default_policy.check(model)
            self.plans = np.vstack([self.blind, default_policy.alphas])
            self.plan_actions = np.concatenate([self.plan_actions, default_policy.actions])
        self.q_upper: Optional[np.ndarray] = None                    # (A, S) for "fib"
        if upper == "fib" and model.n_states > mdp.DENSE_STATE_LIMIT:
            upper = "mdp"                                             # FIB is for small models
        if upper == "fib":
            self.q_upper = mdp.fast_informed_bound(model)
            self.v_upper = self.q_upper.max(axis=0)
        elif upper == "mdp":
            sol = mdp.value_iteration(model, epsilon=1e-4)
            self.v_upper = sol.V + sol.error_bound                    # (S,)
        else:
            # Largest reward of any transition, every step forever.
            rmax = max(float(r.data.max()) if r.nnz else 0.0 for r in model.R)
            rmax = max(rmax, float(R.max()))
            if any(r.nnz < r.shape[0] * r.shape[1] for r in model.R):
                rmax = max(rmax, 0.0)                                 # implicit zero rewards
            self.v_upper = np.full(model.n_states, rmax / (1.0 - gamma))
        # For expanding a node: T's entries with their next state's observation row
        # (action * S + s'), O's entries with their child's key (action * Z + o), and the
        # per-state rows a node's bounds sum: the upper bound (or FIB's A rows), then the plans.
        S, Z = model.n_states, model.n_observations
        trans, obs = self.sampler.trans, self.sampler.obs
        t_row = np.repeat(np.arange(trans.n_rows), np.diff(trans.indptr))
        o_row = np.repeat(np.arange(obs.n_rows), np.diff(obs.indptr))
        self.t_cum, self.t_cols, self.t_vals = trans.cum, trans.cols, trans.values
        self.t_orow = (t_row // S) * S + trans.cols
        self.o_cum = obs.cum
        self.o_key = (o_row // S) * Z + obs.cols
        up_rows = self.q_upper if self.q_upper is not None else self.v_upper[None, :]
        self.n_up = up_rows.shape[0]
        self.state_rows = np.ascontiguousarray(np.vstack([up_rows, self.plans]), dtype=float)


class _VNode:
    """A belief node: the scenarios that reach it and their current states.

    Those are ``block[0][lo:hi]`` and ``block[1][lo:hi]``: the arrays of all the siblings'
    scenarios and states, shared, sliced only when the node is expanded (most never are), which
    saves two array views per node in making and in freeing the tree. A node is made only when a
    trial first enters it; until then its bounds live in its parent's ``_Kids`` lists.
    """

    __slots__ = ("depth", "block", "lo", "hi", "frac", "lower0", "lower", "upper", "uupper",
                 "children", "is_default")

    def __init__(self, depth: int, block: tuple, lo: int, hi: int, frac: float,
                 lower0: float, lower: float, upper: float, uupper: float) -> None:
        self.depth = depth
        self.block = block                 # (scenario indices, states) of the sibling group
        self.lo = lo
        self.hi = hi
        self.frac = frac                   # |Φ_b| / K
        self.lower0 = lower0               # weighted default-policy value ℓ0
        self.lower = lower                 # ℓ
        self.upper = upper                 # μ (at first max(U0, ℓ0))
        self.uupper = uupper               # U (weighted, not regularized)
        self.children: Optional[List[_QNode]] = None
        self.is_default = False


class _Kids:
    """The children of one expanded belief node, all actions', in (action, observation) order,
    as parallel lists: each child's scenario range in ``block``, share |Φ|/K, ℓ0 and current
    bounds ℓ, μ, U, and its ``_VNode`` once a trial has entered it (None before). A child's
    bounds change only in a trial through it, which writes them back here as it backs up."""

    __slots__ = ("depth", "block", "lo", "size", "frac", "lower0", "lower", "upper", "uupper",
                 "nodes")

    def __init__(self, depth: int, block: tuple, lo: list, size: list, frac: list,
                 lower0: list, upper: list) -> None:
        self.depth = depth
        self.block = block
        self.lo = lo
        self.size = size
        self.frac = frac
        self.lower0 = lower0
        self.lower = lower0[:]
        self.upper = upper
        self.uupper = upper[:]
        self.nodes: List[Optional[_VNode]] = [None] * len(lo)

    def node(self, i: int) -> _VNode:
        """Child ``i``'s belief node, made on first use."""
        v = self.nodes[i]
        if v is None:
            lo = self.lo[i]
            v = self.nodes[i] = _VNode(self.depth, self.block, lo, lo + self.size[i],
                                       self.frac[i], self.lower0[i], self.lower[i],
                                       self.upper[i], self.uupper[i])
        return v


class _QNode:
    """An action node: the step reward of its scenarios; its children are ``kids``' entries
    ``c0`` to ``c1`` (one per observation).

    Nodes hold no pointer to their parent: the tree has no reference cycles, so a finished tree
    is freed by reference counting the moment it is dropped, never left to the cyclic garbage
    collector (whose full passes over dead trees cost up to ~190 ms inside a 0.1 s search).
    """

    __slots__ = ("action", "rho", "kids", "c0", "c1", "lower", "upper", "uupper")

    def __init__(self, action: int, rho: float, kids: _Kids, c0: int, c1: int) -> None:
        self.action = action
        self.rho = rho                     # weighted step reward minus λ
        self.kids = kids
        self.c0 = c0
        self.c1 = c1
        self.lower = self.upper = self.uupper = 0.0


class DespotPlanner(BeliefPlanner):
    """Online planner: ``reset``, then ``act`` / ``update`` in turn (see planner.Planner)."""

    plans_on_model = True
    #: The robot process's settings of its search: the launch arguments of DESPOT's
    #: parameters (``lambda`` is the config's ``pruning``).
    SETTINGS = SETTING_NAMES

    @classmethod
    def settings_used(cls, task: Any) -> Tuple[str, ...]:
        return cls.SETTINGS

    @classmethod
    def from_settings(cls, model: Model, task: Any, values: Mapping[str, Any]
                      ) -> "DespotPlanner":
        """DESPOT with the settings' budget and shape; ``time_per_step`` 0: no time budget,
        the trials alone bound the search (no clock read in a decision)."""
        if values["time_per_step"] == 0 and not values["max_trials"]:
            raise ValueError("--time-per-step 0 (no time budget) needs --max-trials > 0")
        config = DespotConfig(**{parameter(name).field: config_value(name, values[name])
                                 for name in cls.SETTINGS})
        return cls(model, config, seed=values.get("seed"))

    def __init__(self, model: Model, config: Optional[DespotConfig] = None,
                 seed: Optional[int] = None, tables: Optional[DespotTables] = None,
                 default_policy: Optional[Policy] = None) -> None:
        self.config = config if config is not None else DespotConfig()
        self.config.validate()
        particles = self.config.particles
        if particles is None and model.n_states > EXACT_BELIEF_MAX_STATES:
            particles = DEFAULT_PARTICLES
        cfg = self.config
        if tables is None or tables.model is not model or tables.key != (cfg.upper, cfg.lower):
            tables = DespotTables(model, cfg.upper, cfg.lower, default_policy)
        # The particle belief shares the tables' sampler (the same tables a sampler of its own
        # would build: the same draws, without another copy per planner).
        super().__init__(model, seed, particles, sampler=tables.sampler)
        self.tables = tables
        self.sampler = tables.sampler
        self._A = model.n_actions
        self._S = model.n_states
        self._Z = model.n_observations
        self._gamma = float(model.discount)
        self._blind = tables.blind
        self._plans = tables.plans
        self._plan_actions = tables.plan_actions
        self._v_upper = tables.v_upper
        self._q_upper = tables.q_upper
        self._action_rows = (np.arange(self._A) * self._S)[:, None]
        self._t_cum, self._t_cols, self._t_vals = tables.t_cum, tables.t_cols, tables.t_vals
        self._t_orow, self._o_cum, self._o_key = tables.t_orow, tables.o_cum, tables.o_key
        self._state_rows, self._n_up = tables.state_rows, tables.n_up
        self._lower_rollout = self.config.lower == "rollout"
        self._root_action = 0
        #: An exploration bonus on the root's first step only: (action, per-state reward
        #: added to that action's in each start state), or None. Set before act() (e.g.
        #: :class:`ros_hrc.pomdp.bayes_adaptive.LookBonus`); the tree below the root plans
        #: on the model's own rewards, so its bounds meet as they do without it.
        self.root_bonus: Optional[Tuple[int, np.ndarray]] = None
        self._obs_offsets = (np.arange(self._A) * self._Z)[:, None]
        self._u: List[np.ndarray] = []
        self._u_rows: List[tuple] = []                # each depth's uniforms, as two rows
        self._search_rng = np.random.default_rng(0)
        self._nodes = 0
        self._max_depth = 0
        self._deadline = math.inf
        self._trials = 0
        self._free_per_node = FREE_SECONDS_PER_NODE
        self._expand_seconds = 0.0
        self._expand_scenarios = 0.0
        self._update_seconds = 0.0

    # -- random streams ------------------------------------------------------------------------
    def _uniforms(self, depth: int) -> np.ndarray:
        """The (2, K) uniforms of every scenario at ``depth`` (drawn once per search, in order)."""
        while len(self._u) <= depth:
            block = self._search_rng.random((2, self.config.scenarios))
            self._u.append(np.minimum(block, U_MAX, out=block))
            self._u_rows.append((block[0], block[1]))
        return self._u[depth]

    # -- node bounds ---------------------------------------------------------------------------
    def _default_values(self, depth: int, scen_sorted: np.ndarray, states_sorted: np.ndarray,
                        starts: np.ndarray):
        """Weighted ℓ0, the default action and weighted U0 for groups of scenarios."""
        K = self.config.scenarios
        w = self._gamma ** depth / K
        if self._q_upper is not None:
            # max_a of the scenarios' mean Q[a]: a bound on the node's belief, not per scenario.
            up = np.add.reduceat(self._q_upper[:, states_sorted], starts, axis=1).max(axis=0) * w
        else:
            up = np.add.reduceat(self._v_upper[states_sorted], starts) * w
        if self.config.lower != "rollout":
            sums = np.add.reduceat(self._plans[:, states_sorted], starts, axis=1)   # (plans, C)
            best = sums.argmax(axis=0)
            low = sums[best, np.arange(starts.size)] * w
            acts = self._plan_actions[best]
        else:
            acts = np.add.reduceat(self._blind[:, states_sorted], starts, axis=1).argmax(axis=0)
            per = self._rollout(depth, scen_sorted, states_sorted,
                                np.repeat(acts, np.diff(np.append(starts, states_sorted.size))))
            low = np.add.reduceat(per, starts) * w
        return low, acts, up

    def _rollout(self, depth: int, scen: np.ndarray, states: np.ndarray,
                 actions: np.ndarray) -> np.ndarray:
        """Discounted return (from ``depth``) of each scenario repeating its action to depth D."""
        total = np.zeros(states.size)
        disc = 1.0
        rows0 = actions * self._S
        for d in range(depth, self.config.depth + 1):
            if time.perf_counter() > self._deadline:
                break               # out of time: the blind values stand in from here on
            u = self._uniforms(d)
            states, _, r = self.sampler.step_rows(rows0 + states, u[0, scen], u[1, scen])
            total += disc * r
            disc *= self._gamma
        # Beyond the horizon the blind values stand in for the rest of the rollout.
        total += disc * self._blind[actions, states]
        return total

    def _root(self, states: np.ndarray) -> _VNode:
        K = self.config.scenarios
        scen = np.arange(K)
        starts = np.zeros(1, dtype=np.int64)
        low, acts, up = self._default_values(0, scen, states, starts)
        self._nodes = 1
        self._max_depth = 0
        self._root_action = int(acts[0])          # the default action (only the root's is used)
        if self.config.lower != "rollout":
            # Ties among the plans' values at the root go to the model's first action, as in
            # _best_action (the plans' numerical slack must not choose the robot's action).
            means = self._plans[:, states].mean(axis=1)
            best = means.max()
            near = means >= best - TIE_TOLERANCE * max(1.0, abs(best))
            self._root_action = int(self._plan_actions[near].min())
        lower, upper = float(low[0]), float(up[0])
        if self.root_bonus is not None:
            # The bonus raises at most one action's first reward: U0 plus its mean stays an
            # upper bound (the backup only ever lowers the root's).
            upper += float(self.root_bonus[1][states].mean())
        upper = max(upper, lower)
        return _VNode(0, (scen, states), 0, K, 1.0, lower, lower, upper, upper)

    # -- tree ----------------------------------------------------------------------------------
    def _expand(self, v: _VNode) -> None:
        """Step every scenario of v under every action; one child per (action, observation)."""
        A, Z, K = self._A, self._Z, self.config.scenarios
        lo, hi = v.lo, v.hi
        n = hi - lo
        scen = v.block[0][lo:hi]
        if v.depth >= len(self._u):
            self._uniforms(v.depth)
        u_t, u_o = self._u_rows[v.depth]
        # ModelSampler.step_block for every action at once (the same two uniforms per scenario
        # for every action: that is the determinized scenario), reading the next state's
        # observation row and the child's key (action * Z + observation) from tables aligned
        # with T's and O's entries, and the next state only for the sorted scenarios.
        pos = self._t_cum.searchsorted((self._action_rows + v.block[1][lo:hi]) + u_t[scen],
                                       side="right")                  # (A, n)
        opos = self._o_cum.searchsorted(self._t_orow[pos] + u_o[scen], side="right")
        key = self._o_key[opos].ravel()
        order = key.argsort(kind="stable")
        counts = np.bincount(key, minlength=A * Z)
        keys = counts.nonzero()[0]                                    # the children's keys
        sizes_l = counts[keys].tolist()
        keys_l = keys.tolist()
        starts_l = list(accumulate(sizes_l, initial=0))
        del starts_l[-1]
        nxt_s = self._t_cols[pos.ravel()[order]]
        scen_s = scen[order % n]
        depth = v.depth + 1
        if self._lower_rollout:
            low, _, up = self._default_values(depth, scen_s, nxt_s, np.asarray(starts_l))
        else:
            # _default_values without the children's default actions (only the root's is used):
            # the bound rows and the plans summed in one reduceat.
            # Scaling by w > 0 before the maxima is exact: rounding is monotone.
            sums = np.add.reduceat(self._state_rows[:, nxt_s], starts_l, axis=1)
            sums *= self._gamma ** depth / K
            nu = self._n_up
            up = sums[0] if nu == 1 else sums[:nu].max(axis=0)
            low = sums[nu:].max(axis=0)
        lam = self.config.pruning
        wr = self._gamma ** v.depth / K
        rho = [r * wr - lam for r in self._t_vals[pos].sum(axis=1).tolist()]
        if v.depth == 0 and self.root_bonus is not None:
            action, per_state = self.root_bonus
            rho[action] += float(per_state[v.block[1][lo:hi]].sum()) * wr
        up = np.maximum(up, low)                                      # μ0 = max(U0, ℓ0)
        # Children of action a: keys in [a·Z, (a+1)·Z); the action nodes' initial bounds sum
        # them in order from 0 (as np.bincount), then add ρ.
        cut = [0] + [bisect_left(keys_l, a * Z) for a in range(1, A)] + [len(keys_l)]
        low_l = low.tolist()
        up_l = up.tolist()
        kids = _Kids(depth, (scen_s, nxt_s), starts_l, sizes_l, [m / K for m in sizes_l],
                     low_l, up_l)
        qnodes = []
        for a, r in enumerate(rho):
            c0, c1 = cut[a], cut[a + 1]
            q = _QNode(a, r, kids, c0, c1)
            q.lower = r + reduce(add, low_l[c0:c1], 0.0)
            q.upper = up_a = r + reduce(add, up_l[c0:c1], 0.0)
            q.uupper = up_a + lam
            qnodes.append(q)
        v.children = qnodes
        self._nodes += len(keys_l)
        if depth > self._max_depth:
            self._max_depth = depth

    @staticmethod
    def _make_default(v: _VNode) -> None:
        v.lower = v.upper = v.uupper = v.lower0
        v.is_default = True

    def _backup(self, path: List[_VNode], qpath: List[_QNode], index: List[int]) -> None:
        """Recompute the bounds on a trial's path, from its last node up to the root.

        ``path`` holds the belief nodes from the root down, ``qpath[i]`` the action node between
        ``path[i]`` and ``path[i + 1]``, which is child ``index[i]`` of its ``kids``.
        """
        lam = self.config.pruning
        for i in range(len(qpath) - 1, -1, -1):
            q = qpath[i]
            kids = q.kids
            c = path[i + 1]
            j = index[i]
            kl, ku, kuu = kids.lower, kids.upper, kids.uupper
            kl[j] = c.lower
            ku[j] = c.upper
            kuu[j] = c.uupper
            # Sums from ρ in the children's order (a left fold, like the loop it replaces).
            c0, c1 = q.c0, q.c1
            r = q.rho
            q.lower = reduce(add, kl[c0:c1], r)
            q.upper = reduce(add, ku[c0:c1], r)
            q.uupper = reduce(add, kuu[c0:c1], r) + lam
            v = path[i]
            if v.is_default:
                continue
            lower = upper = uupper = v.lower0
            for x in v.children:
                if x.lower > lower:
                    lower = x.lower
                if x.upper > upper:
                    upper = x.upper
                if x.uupper > uupper:
                    uupper = x.uupper
            # Monotone updates: the heuristic bounds need not be consistent between levels.
            if lower > v.lower:
                v.lower = lower
            if upper < v.upper:
                v.upper = upper
            if v.upper < v.lower:
                v.upper = v.lower
            if uupper < v.uupper:
                v.uupper = uupper

    def _trial(self, root: _VNode, deadline: float) -> bool:
        """One trial: descend, expanding leaves, until a stopping rule holds, then back up.

        The descent stops before an expansion that would end past ``deadline`` less the time to
        free the tree (the path is still backed up), so a deep trial does not overrun the step's
        budget; an expansion is predicted to take the recent expansions' mean time, scaled up
        when it has more scenarios than their mean. True when it stopped for time.
        """
        cfg = self.config
        lam, xi, D = cfg.pruning, cfg.xi, cfg.depth
        v = root
        path = [root]
        qpath: List[_QNode] = []
        index: List[int] = []
        # keys[i] = min over path[0..i] of weighted (U - ℓ0) + λ·depth: the blocking test for a
        # node at depth d is min over its ancestors of that key <= λ·d.
        keys = [root.uupper - root.lower0]
        # The root's bounds change only in the backup: its gap is fixed for the descent.
        root_gap = root.upper - root.lower
        target = xi * root_gap
        while True:
            if v.depth > D:
                self._make_default(v)
                break
            if v is not root and (v.upper - v.lower) - xi * v.frac * root_gap <= 0.0:
                break
            if len(path) > 1 and keys[-2] <= lam * v.depth:
                # Blocked: default values for it and every blocked node above it.
                for i in range(len(path) - 1, 0, -1):
                    x = path[i]
                    if keys[i - 1] <= lam * x.depth:
                        self._make_default(x)
                    else:
                        break
                break
            if v.children is None:
                n = v.hi - v.lo
                if v is not root and (self._out_of_time(deadline, n) or (
                        cfg.max_nodes is not None and self._nodes >= cfg.max_nodes)):
                    self._backup(path, qpath, index)
                    return True
                began = time.perf_counter()
                self._expand(v)
                # Recent expansions' mean size and duration (they predict the next one's).
                w = EXPAND_WEIGHT if self._expand_scenarios > 0.0 else 1.0
                self._expand_scenarios += w * (n - self._expand_scenarios)
                self._expand_seconds += w * (time.perf_counter() - began - self._expand_seconds)
            children = v.children
            q = children[0]                    # the first action node of the largest μ
            for x in children:
                if x.upper > q.upper:
                    q = x
            kids = q.kids
            up, lw, fr = kids.upper, kids.lower, kids.frac
            best = -1
            best_e = -math.inf
            for i in range(q.c0, q.c1):
                e = (up[i] - lw[i]) - target * fr[i]
                if e > best_e:
                    best_e, best = e, i
            v = kids.node(best)
            qpath.append(q)
            index.append(best)
            path.append(v)
            keys.append(min(keys[-1], v.uupper - v.lower0 + lam * v.depth))
        self._backup(path, qpath, index)
        return False

    def _out_of_time(self, deadline: float, scenarios: int = 0) -> bool:
        """Whether the search must stop now to free its tree (of ``_nodes``) by ``deadline``,
        after expanding a node of ``scenarios`` scenarios first when that is not 0."""
        reserve = FREE_MARGIN * self._free_per_node * self._nodes
        if scenarios and self._expand_scenarios > 0.0:
            reserve += self._expand_seconds * max(1.0, scenarios / self._expand_scenarios)
        return time.perf_counter() + reserve >= deadline

    # -- the Planner interface -----------------------------------------------------------------
    def reset(self, belief: Optional[np.ndarray] = None) -> None:
        """Start again from ``belief`` (e.g. ``model.start_belief(state)``) or the initial
        belief: every search draws its scenarios from the current belief, the particles of a
        particle belief are drawn from this one."""
        super().reset(belief)
        self._update_seconds = 0.0

    def update(self, action: int, observation: int) -> None:
        """The belief update; its duration comes out of the next act()'s budget."""
        start = time.perf_counter()
        super().update(action, observation)
        self._update_seconds += time.perf_counter() - start

    def act(self) -> int:
        """Build a DESPOT from the current belief within the budget and return its best action.

        ``time_per_step`` bounds the whole decision, what a caller waits for: the belief updates
        since the last act() (a decision loop updates, then acts), drawing the scenarios, the
        search, choosing the action and freeing the tree. The search stops early enough for the
        rest to fit (the time to free a tree is measured on each act). A search bounded by
        ``max_trials`` under a generous budget makes the same trials and random draws whatever
        the clock says. ``last_stats`` then holds the trials, the seconds act() took, the root's
        regularized bounds, the tree's size and depth, and each root action's value that the
        choice compared (:meth:`_root_values`).
        """
        start = time.perf_counter()
        budget = self.config.time_per_step - self._update_seconds
        self._update_seconds = 0.0
        # The cyclic garbage collector is paused for the call: the tree makes no reference
        # cycles and is freed by reference counting before act() returns, so nothing is left
        # for the collector, whose passes (triggered by the tree's allocations) walked the whole
        # heap and cost up to ~190 ms of a 0.1 s budget.
        paused = gc.isenabled()
        gc.disable()
        try:
            root = self._search(start + budget)
            values = self._root_values(root, self._root_action)
            action = self._best_action(values)
            stats = PlannerStats(trials=self._trials, lower=root.lower, upper=root.upper,
                                 nodes=self._nodes, depth=self._max_depth,
                                 action_values=values)
            freeing = time.thread_time()              # CPU time: immune to preemption
            del root                                  # the whole tree, by reference counting
            end = time.perf_counter()
            if stats.nodes >= FREE_MIN_NODES:
                per_node = min((time.thread_time() - freeing) / stats.nodes, FREE_MAX_PER_NODE)
                self._free_per_node = 0.5 * (self._free_per_node + per_node)
        finally:
            if paused:
                gc.enable()
        stats.seconds = end - start
        self.last_stats = stats
        return action

    def _search(self, deadline: float) -> _VNode:
        """The tree grown from the current belief by trials until ``deadline`` or a trial cap."""
        cfg = self.config
        self._deadline = deadline
        self._search_rng = np.random.default_rng(int(self.rng.integers(2**63)))
        self._u = []
        self._u_rows = []
        # Stratified start states: the scenarios' state mix matches the belief to within one
        # scenario per state, which removes most of the noise in comparing close actions.
        states = self._belief.sample_systematic(self._search_rng, cfg.scenarios)
        root = self._root(states)
        trials = 0
        while True:
            if cfg.max_trials is not None and trials >= cfg.max_trials:
                break
            if root.upper - root.lower <= cfg.gap_tolerance:
                break
            if trials > 0 and self._out_of_time(deadline):
                break
            if cfg.max_nodes is not None and self._nodes >= cfg.max_nodes:
                break
            trials += 1
            if self._trial(root, deadline):
                break
        self._trials = trials
        self._deadline = math.inf
        return root

    @staticmethod
    def _root_values(root: _VNode, default_action: int) -> Dict[int, float]:
        """The value of each root action that the choice compares: its action node's lower
        bound ℓ(b0, a) (regularized: the scenarios' mean discounted return of the best policy
        the tree holds under it, less λ per policy node), and for the default action the
        default policy's value ℓ0(b0) when that is larger. Only the default action has a value
        when the root was never expanded (no trial ran). In the model's reward units, from the
        belief the search started at."""
        values = {default_action: root.lower0}
        for q in root.children or ():
            if q.action not in values or q.lower > values[q.action]:
                values[q.action] = q.lower
        return values

    @staticmethod
    def _best_action(values: Dict[int, float]) -> int:
        """The action of the best value of :meth:`_root_values` (the root's best lower bound,
        or its default action).

        Values within :data:`TIE_TOLERANCE` (relative) of the best are ties, and a tie goes to
        the action the model lists first. The bounds carry numerical slack (the blind policies'
        convergence margin, a few 1e-7), so without this rule a robot that has nothing left
        to gain (the human holds the object: every action is worth 0) would pick whichever
        action's slack happens to be smallest, e.g. pointing; the model's first action, rIdle
        in the robot model, is the one that does nothing."""
        best = max(values.values())
        tolerance = TIE_TOLERANCE * max(1.0, abs(best))
        return int(min(a for a, value in values.items() if value >= best - tolerance))
