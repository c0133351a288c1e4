"""Mixed observability (MOMDP, as SARSOP reads POMDPX): the fully observed state variables are
known at every step, the first included, in simulate, in every planner and in the solvers.

Tiger with the tiger's side seen (``fullyObs="true"``) is an MDP: open the other door every step
for +10, worth 10 / (1 - 0.95) = 200 forever and 200·(1 - 0.95^100) = 198.8159 over 100 steps.
SARSOP says 198.8 (simulated) and 200 (solved); a simulator that hides the start state at t = 0
makes the agent listen once and scores 187.8.
"""
import dataclasses
import json
import math

import numpy as np
import pytest

from ros_hrc.errors import ModelError
from ros_hrc.pomdp import cassandra, hsvi, offline, pomdpx
from ros_hrc.commands.pomdp import run
from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner, DespotTables
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.planner import MdpPlanner, PolicyPlanner
from ros_hrc.pomdp.simulate import simulate

LISTEN, OPEN_LEFT, OPEN_RIGHT = 0, 1, 2

#: The exact 100-step value of the seen Tiger (every step +10), and its infinite-horizon value.
SEEN_TIGER_100_STEPS = 200.0 * (1.0 - 0.95 ** 100)
SEEN_TIGER_VALUE = 200.0

#: A small trial-capped DESPOT: the same trees on every machine, quick enough for 100-step runs.
SMALL_DESPOT = DespotConfig(scenarios=50, time_per_step=30.0, max_trials=5)

_TIGER_TABLES = """
  <StateTransitionFunction>
    {round_transition}
    <CondProb><Var>tiger_1</Var><Parent>action tiger_0</Parent>
      <Parameter type="TBL">
        <Entry><Instance>listen - -</Instance><ProbTable>identity</ProbTable></Entry>
        <Entry><Instance>open-left * -</Instance><ProbTable>uniform</ProbTable></Entry>
        <Entry><Instance>open-right * -</Instance><ProbTable>uniform</ProbTable></Entry>
      </Parameter>
    </CondProb>
  </StateTransitionFunction>
  <ObsFunction>
    <CondProb><Var>heard</Var><Parent>action tiger_1</Parent>
      <Parameter type="TBL">
        <Entry><Instance>listen - -</Instance><ProbTable>0.85 0.15 0.15 0.85</ProbTable></Entry>
        <Entry><Instance>open-left * -</Instance><ProbTable>uniform</ProbTable></Entry>
        <Entry><Instance>open-right * -</Instance><ProbTable>uniform</ProbTable></Entry>
      </Parameter>
    </CondProb>
  </ObsFunction>
  <RewardFunction>
    <Func><Var>reward</Var><Parent>action tiger_0</Parent>
      <Parameter type="TBL">
        <Entry><Instance>listen *</Instance><ValueTable>-1</ValueTable></Entry>
        <Entry><Instance>open-left -</Instance><ValueTable>-100 10</ValueTable></Entry>
        <Entry><Instance>open-right -</Instance><ValueTable>10 -100</ValueTable></Entry>
      </Parameter>
    </Func>
  </RewardFunction>
</pomdpx>
"""

_TIGER_VAR = """<StateVar vnamePrev="tiger_0" vnameCurr="tiger_1" fullyObs="{seen}">
      <ValueEnum>tiger-left tiger-right</ValueEnum>
    </StateVar>"""
_ROUND_VAR = """<StateVar vnamePrev="round_0" vnameCurr="round_1" fullyObs="true">
      <ValueEnum>calm alert</ValueEnum>
    </StateVar>"""
_OTHER_VARS = """<ObsVar vname="heard"><ValueEnum>hear-left hear-right</ValueEnum></ObsVar>
    <ActionVar vname="action"><ValueEnum>listen open-left open-right</ValueEnum></ActionVar>
    <RewardVar vname="reward"/>"""

#: Tiger (Kaelbling, Littman and Cassandra 1998) with the tiger's side seen. The listening
#: observation is kept: with every state variable fully observable it is ignored (an MDP).
TIGER_SEEN = ("""<?xml version="1.0"?>
<pomdpx version="1.0">
  <Description>Tiger with the tiger's side seen</Description>
  <Discount>0.95</Discount>
  <Variable>
    """ + _TIGER_VAR.format(seen="true") + "\n    " + _OTHER_VARS + """
  </Variable>
  <InitialStateBelief>
    <CondProb><Var>tiger_0</Var><Parent>null</Parent>
      <Parameter type="TBL"><Entry><Instance>-</Instance><ProbTable>uniform</ProbTable></Entry>
      </Parameter>
    </CondProb>
  </InitialStateBelief>""" + _TIGER_TABLES.format(round_transition=""))

_ROUND_TABLES = """
  <InitialStateBelief>
    <CondProb><Var>round_0</Var><Parent>null</Parent>
      <Parameter type="TBL"><Entry><Instance>-</Instance><ProbTable>0.6 0.4</ProbTable></Entry>
      </Parameter>
    </CondProb>
    <CondProb><Var>tiger_0</Var><Parent>round_0</Parent>
      <Parameter type="TBL">
        <Entry><Instance>calm -</Instance><ProbTable>uniform</ProbTable></Entry>
        <Entry><Instance>alert -</Instance><ProbTable>0.98 0.02</ProbTable></Entry>
      </Parameter>
    </CondProb>
  </InitialStateBelief>"""

_ROUND_TRANSITION = """<CondProb><Var>round_1</Var><Parent>action round_0</Parent>
      <Parameter type="TBL">
        <Entry><Instance>listen - -</Instance><ProbTable>identity</ProbTable></Entry>
        <Entry><Instance>open-left * -</Instance><ProbTable>1 0</ProbTable></Entry>
        <Entry><Instance>open-right * -</Instance><ProbTable>1 0</ProbTable></Entry>
      </Parameter>
    </CondProb>"""


def tiger_rounds(round_first: bool = True) -> str:
    """Tiger with a fully observed round next to the hidden tiger: a round starts calm (0.6,
    tiger uniform) or alert (0.4, the tiger left with 0.98); opening a door starts a calm one.
    Seeing the round at the start matters: alert, open right at once; calm, listen."""
    tiger = _TIGER_VAR.format(seen="false")
    variables = [_ROUND_VAR, tiger] if round_first else [tiger, _ROUND_VAR]
    return ("""<?xml version="1.0"?>
<pomdpx version="1.0">
  <Discount>0.95</Discount>
  <Variable>
    """ + "\n    ".join(variables + [_OTHER_VARS]) + """
  </Variable>""" + _ROUND_TABLES + _TIGER_TABLES.format(round_transition=_ROUND_TRANSITION))


#: The seen Tiger in Cassandra's format: observations are the states, O the identity.
TIGER_SEEN_CASSANDRA = """\
discount: 0.95
values: reward
states: tiger-left tiger-right
actions: listen open-left open-right
observations: tiger-left tiger-right
start: uniform
T: listen
identity
T: open-left
uniform
T: open-right
uniform
O: * identity
R: listen : * : * : * -1
R: open-left : tiger-left : * : * -100
R: open-left : tiger-right : * : * 10
R: open-right : tiger-left : * : * 10
R: open-right : tiger-right : * : * -100
"""


@pytest.fixture(scope="module")
def seen_tiger() -> Model:
    return pomdpx.loads(TIGER_SEEN, source="tiger_seen.pomdpx")


@pytest.fixture(scope="module")
def rounds() -> Model:
    return pomdpx.loads(tiger_rounds(), source="tiger_rounds.pomdpx")


@pytest.fixture(scope="module")
def rounds_policy(rounds):
    return offline.solve(rounds, timeout=30, precision=1e-3)


def assert_scores_the_seen_tiger(result, runs: int) -> None:
    """198.8 like SARSOP: the interval holds the exact 100-step value, the mean within 0.5."""
    assert result.runs == runs
    assert abs(result.mean - SEEN_TIGER_100_STEPS) <= 0.5
    # Every run opens the right door at every step, so the interval may be a point.
    assert result.ci95_low - 1e-9 <= SEEN_TIGER_100_STEPS <= result.ci95_high + 1e-9


# -- the model: keys, start beliefs ----------------------------------------------------------------
def test_a_fully_observable_pomdpx_is_an_mdp_whose_states_are_their_own_keys(seen_tiger):
    m = seen_tiger
    assert m.fully_observable and m.observations == m.states == ["tiger-left", "tiger-right"]
    assert np.array_equal(m.observed_key, [0, 1])
    assert np.array_equal(m.start_belief(0), [1, 0])
    assert np.array_equal(m.start_belief(1), [0, 1])
    split = m.start_split()
    assert [w for w, _ in split] == [0.5, 0.5]
    assert [b.tolist() for _, b in split] == [[1, 0], [0, 1]]


def test_observed_key_numbers_the_fully_observed_values_whatever_their_place(rounds):
    assert rounds.states == ["calm_tiger-left", "calm_tiger-right",
                             "alert_tiger-left", "alert_tiger-right"]
    assert np.array_equal(rounds.observed_key, [0, 0, 1, 1])
    assert not rounds.fully_observable
    later = pomdpx.loads(tiger_rounds(round_first=False))
    assert later.states == ["tiger-left_calm", "tiger-left_alert",
                            "tiger-right_calm", "tiger-right_alert"]
    assert np.array_equal(later.observed_key, [0, 1, 0, 1])


def test_start_belief_conditions_the_initial_belief_on_the_seen_round(rounds):
    assert np.allclose(rounds.initial_belief, [0.3, 0.3, 0.392, 0.008])
    calm, alert = [0.5, 0.5, 0, 0], [0, 0, 0.98, 0.02]
    for state, expected in ((0, calm), (1, calm), (2, alert), (3, alert)):
        assert rounds.start_belief(state) == pytest.approx(expected, abs=1e-12)
    split = rounds.start_split()
    assert [w for w, _ in split] == pytest.approx([0.6, 0.4], abs=1e-12)
    assert split[0][1] == pytest.approx(calm, abs=1e-12)
    assert split[1][1] == pytest.approx(alert, abs=1e-12)
    # The weighted beliefs add up to the initial belief.
    total = sum(w * b for w, b in split)
    assert total == pytest.approx(rounds.initial_belief, abs=1e-12)


def test_without_a_fully_observed_variable_the_start_is_the_initial_belief(tiger):
    assert tiger.observed_key is None
    for state in range(tiger.n_states):
        b = tiger.start_belief(state)
        assert np.array_equal(b, tiger.initial_belief) and b is not tiger.initial_belief
    [(weight, b)] = tiger.start_split()
    assert weight == 1.0 and np.array_equal(b, tiger.initial_belief)
    # One key with all the initial probability (RockSample's rover) changes nothing either.
    one_key = dataclasses.replace(tiger, observed_key=np.zeros(2, dtype=np.int64))
    assert np.array_equal(one_key.start_belief(1), tiger.initial_belief)
    assert one_key.start_split()[0][0] == 1.0


def test_a_cassandra_mdp_is_its_own_key_and_a_pomdp_has_none():
    mdp = cassandra.loads(TIGER_SEEN_CASSANDRA)
    assert mdp.fully_observable and np.array_equal(mdp.observed_key, [0, 1])
    assert np.array_equal(mdp.start_belief(1), [0, 1])
    pomdp = cassandra.loads(TIGER_SEEN_CASSANDRA.replace("O: * identity", "O: * uniform"))
    assert not pomdp.fully_observable and pomdp.observed_key is None


def test_the_model_constructor_keeps_its_old_arguments_and_checks_a_given_key(tiger):
    fields = {f.name: getattr(tiger, f.name) for f in dataclasses.fields(tiger)
              if f.name != "observed_key"}
    assert Model(**fields).observed_key is None
    bad = dataclasses.replace(tiger, observed_key=np.zeros(3, dtype=np.int64))
    with pytest.raises(ModelError, match="observed_key"):
        bad.validate()
    left_only = dataclasses.replace(tiger, observed_key=np.array([0, 1]),
                                    initial_belief=np.array([1.0, 0.0]))
    with pytest.raises(ModelError, match="probability zero"):
        left_only.start_belief(1)


# -- the seen Tiger: simulate, solve, every planner, the command line ------------------------------
def test_simulate_reveals_the_seen_tiger_at_the_start_like_sarsop(seen_tiger):
    solution = MdpPlanner(seen_tiger).solution         # what 'simulate --planner mdp' uses
    result = simulate(seen_tiger, lambda s: MdpPlanner(seen_tiger, solution, s),
                      sim_len=100, sim_num=200, seed=0)
    assert_scores_the_seen_tiger(result, 200)


def test_solve_gives_200_like_sarsop(seen_tiger):
    policy = offline.solve(seen_tiger, precision=1e-3)
    assert policy.kind == "mdp"
    assert policy.lower - 1e-9 <= SEEN_TIGER_VALUE <= policy.upper + 1e-9
    assert policy.upper - policy.lower <= 1e-3


def test_a_policy_planner_scores_the_seen_tiger_like_sarsop(seen_tiger):
    policy = offline.solve(seen_tiger, precision=1e-3)    # its vectors are the MDP's Q rows
    for lookahead in (False, True):
        result = simulate(seen_tiger, lambda s: PolicyPlanner(seen_tiger, policy, s, lookahead),
                          sim_len=100, sim_num=200, seed=1)
        assert_scores_the_seen_tiger(result, 200)


@pytest.mark.parametrize("particles", [None, 100])
def test_despot_scores_the_seen_tiger_like_sarsop(seen_tiger, particles):
    config = dataclasses.replace(SMALL_DESPOT, particles=particles)
    tables = DespotTables(seen_tiger, config.upper, config.lower)
    result = simulate(seen_tiger, lambda s: DespotPlanner(seen_tiger, config, s, tables=tables),
                      sim_len=100, sim_num=5, seed=2)
    assert_scores_the_seen_tiger(result, 5)


def test_hrc_pomdp_solve_and_simulate_agree_with_sarsop(tmp_path, capsys):
    path = tmp_path / "tiger_seen.pomdpx"
    path.write_text(TIGER_SEEN)
    policy = tmp_path / "tiger_seen.policy"

    def facts(*argv):
        assert run(list(argv) + ["--json"]) == 0
        return json.loads(capsys.readouterr().out)

    solved = facts("solve", str(path), "--precision", "0.001", "-o", str(policy))
    assert solved["kind"] == "MDP" and solved["converged"]
    assert solved["lower"] - 1e-9 <= SEEN_TIGER_VALUE <= solved["upper"] + 1e-9
    runs = ["--sim-len", "100", "--sim-num", "200", "--seed", "0"]
    for how in (["--policy", str(policy)], ["--planner", "mdp"]):
        simulated = facts("simulate", str(path), *how, *runs)
        assert abs(simulated["mean"] - SEEN_TIGER_100_STEPS) <= 0.5
        assert simulated["ci95_low"] - 1e-9 <= SEEN_TIGER_100_STEPS <= simulated["ci95_high"] + 1e-9
    despot = facts("simulate", str(path), "--planner", "despot", "--scenarios", "50",
                   "--max-trials", "5", "--time-per-step", "30", "--sim-len", "100",
                   "--sim-num", "3")
    assert abs(despot["mean"] - SEEN_TIGER_100_STEPS) <= 0.5


def test_a_cassandra_mdp_simulates_from_its_start_state_too(tmp_path, capsys):
    path = tmp_path / "tiger_seen.pomdp"
    path.write_text(TIGER_SEEN_CASSANDRA)
    assert run(["simulate", str(path), "--planner", "mdp", "--sim-len", "100",
                "--sim-num", "50", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["mean"] == pytest.approx(SEEN_TIGER_100_STEPS)


# -- Tiger with a seen round: genuinely mixed ------------------------------------------------------
def test_hsvi_bounds_are_the_weighted_sum_of_the_values_given_each_round(rounds, rounds_policy):
    precision = 1e-3
    solver = hsvi.HsviSolver(rounds)
    lower, upper = solver.run(timeout=30, precision=precision)
    assert upper - lower <= precision
    split = rounds.start_split()
    # bounds() at the start is the weighted sum of the bounds at the roots.
    at_roots = np.array([solver.bounds(b) for _, b in split])
    weights = np.array([w for w, _ in split])
    assert (lower, upper) == pytest.approx(tuple(weights @ at_roots), abs=1e-12)
    assert (rounds_policy.lower, rounds_policy.upper) == pytest.approx((lower, upper),
                                                                      abs=precision)
    # Solving each conditioned problem on its own gives the same weighted sum.
    alone = [offline.solve(dataclasses.replace(rounds, initial_belief=b), precision=precision)
             for _, b in split]
    assert [p.upper - p.lower for p in alone] == [pytest.approx(0, abs=precision)] * 2
    assert alone[0].lower == pytest.approx(19.37, abs=0.01)          # calm: plain Tiger
    weighted_lower = sum(w * p.lower for w, p in zip(weights, alone))
    weighted_upper = sum(w * p.upper for w, p in zip(weights, alone))
    assert lower <= weighted_upper + 1e-9 and weighted_lower <= upper + 1e-9
    assert (lower + upper) / 2 == pytest.approx((weighted_lower + weighted_upper) / 2,
                                                abs=precision)


def test_seeing_the_round_at_the_start_is_worth_something(rounds, rounds_policy):
    hidden_at_start = offline.solve(dataclasses.replace(rounds, observed_key=None), precision=1e-3)
    assert hidden_at_start.upper + 0.3 < rounds_policy.lower       # 21.52 against 22.10
    calm, alert = (b for _, b in rounds.start_split())
    assert rounds_policy.action(calm) == LISTEN
    assert rounds_policy.action(alert) == OPEN_RIGHT
    assert rounds_policy.action(rounds.initial_belief) == LISTEN


def test_a_trial_starts_at_the_root_with_the_largest_weighted_excess_gap(rounds):
    precision = 1e-3
    solver = hsvi.HsviSolver(rounds)
    roots = [b for _, b in rounds.start_split()]
    before = np.array([solver.bounds(b) for b in roots])
    weights = np.array([w for w, _ in rounds.start_split()])
    chosen = int(np.argmax(weights * (before[:, 1] - before[:, 0] - precision)))
    solver._trial(precision, math.inf)
    after = np.array([solver.bounds(b) for b in roots])
    # The rounds' beliefs have disjoint supports: only the chosen root's upper bound moves.
    assert after[chosen, 1] < before[chosen, 1]
    assert after[1 - chosen, 1] == before[1 - chosen, 1]
    assert np.all(after[:, 0] >= before[:, 0])


def test_simulate_starts_every_run_from_the_start_states_conditioned_belief(rounds,
                                                                            rounds_policy):
    starts = []

    class Recording(PolicyPlanner):
        def reset(self, belief=None):
            super().reset(belief)
            starts.append(self.belief.copy())

    simulate(rounds, lambda s: Recording(rounds, rounds_policy, s), sim_len=3, sim_num=40, seed=0)
    calm, alert = (b for _, b in rounds.start_split())
    assert len(starts) == 40
    kinds = [0 if np.allclose(b, calm) else 1 if np.allclose(b, alert) else -1 for b in starts]
    assert -1 not in kinds and 0 in kinds and 1 in kinds


def test_despot_searches_from_the_conditioned_start_belief(rounds):
    config = DespotConfig(scenarios=100, time_per_step=30.0, max_trials=20)
    for seed in range(3):
        planner = DespotPlanner(rounds, config, seed=seed)
        planner.reset(rounds.start_belief(2))
        assert planner.act() == OPEN_RIGHT
        planner.reset(rounds.start_belief(0))
        assert planner.act() == LISTEN
        planner.reset()                               # the round unseen: 0.69 left, listen
        assert planner.act() == LISTEN


def test_despot_draws_its_particles_from_the_conditioned_start_belief(rounds):
    config = DespotConfig(scenarios=100, time_per_step=30.0, max_trials=20, particles=200)
    planner = DespotPlanner(rounds, config, seed=0)
    planner.reset(rounds.start_belief(2))
    assert planner.belief[[2, 3]].sum() == pytest.approx(1.0)          # alert states only
    planner.act()
    planner.reset(rounds.start_belief(1))
    assert planner.belief[[0, 1]].sum() == pytest.approx(1.0)          # calm states only


def test_planners_start_from_a_given_belief(rounds, rounds_policy):
    alert = rounds.start_belief(3)
    for planner in (PolicyPlanner(rounds, rounds_policy, seed=0),
                    MdpPlanner(rounds, seed=0)):
        planner.reset(alert)
        assert np.array_equal(planner.belief, alert)
        assert planner.act() == OPEN_RIGHT
