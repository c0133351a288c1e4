"""Simulation of many runs at once (issue #24) and the expected-reward estimator."""
import json
import re
from pathlib import Path

import numpy as np
import pytest

from solver_models import TIGER_OPTIMUM, build_chain, build_tiger, make_model
from ros_hrc.errors import SolverError
from ros_hrc.pomdp import offline
from ros_hrc.commands.pomdp import run
from ros_hrc.commands.pomdp_simulate import duration
from ros_hrc.pomdp.planner import MdpPlanner, PolicyPlanner
from ros_hrc.pomdp.simulate import (policy_chooser, q_chooser, simulate, simulate_batch)

TIGER = str(Path(__file__).resolve().parents[2] / "fixtures" / "tiger.95.pomdp")


def coin(discount: float = 0.9):
    """One action; the next state is a fair coin; entering s1 pays 10, s0 nothing. The expected
    reward of every step is 5, whatever the state."""
    T = np.full((1, 2, 2), 0.5)
    O = np.ones((1, 2, 1))
    R = np.zeros((1, 2, 2))
    R[0, :, 1] = 10.0
    return make_model(T, O, R, discount, [1.0, 0.0], name="coin")


@pytest.fixture(scope="module")
def tiger_and_policy():
    tiger = build_tiger()
    return tiger, offline.solve(tiger, timeout=60, precision=0.01)


def test_a_deterministic_chain_gives_its_exact_total_all_runs_at_once():
    chain = build_chain(4, discount=0.9)
    result = simulate_batch(chain, q_chooser(MdpPlanner(chain).Q), sim_len=10, sim_num=5, seed=1)
    expected = sum(0.9 ** t for t in range(2, 10))
    assert result.mean == pytest.approx(expected)
    assert (result.ci95_low, result.ci95_high) == (pytest.approx(expected),) * 2
    assert result.undiscounted_mean == pytest.approx(8)
    assert result.runs == 5 and result.steps == 50 and result.batched


def test_the_optimal_tiger_policy_scores_the_optimum_all_runs_at_once(tiger_and_policy):
    tiger, policy = tiger_and_policy
    seen = []
    result = simulate_batch(tiger, policy_chooser(tiger, policy), sim_len=100, sim_num=1000,
                            seed=0, progress=lambda n, m: seen.append(n))
    assert result.ci95_low - 0.2 <= TIGER_OPTIMUM <= result.ci95_high + 0.2
    assert seen[-1] == 1000


def test_runs_at_once_are_reproducible_from_the_seed(tiger_and_policy):
    tiger, policy = tiger_and_policy
    def returns(seed):
        return simulate_batch(tiger, policy_chooser(tiger, policy), 30, 50, seed).returns
    assert np.array_equal(returns(4), returns(4))
    assert not np.array_equal(returns(4), returns(5))


def test_the_batched_lookahead_chooses_as_the_planner_does(tiger_and_policy):
    tiger, policy = tiger_and_policy
    beliefs = np.random.default_rng(0).dirichlet([1.0, 1.0], size=40)
    chosen = policy_chooser(tiger, policy, lookahead=True)(beliefs)
    planner = PolicyPlanner(tiger, policy, 0, lookahead=True)
    for b, a in zip(beliefs, chosen):
        planner.reset(b)
        assert planner.act() == a


def test_the_expected_reward_estimator_has_the_same_mean_and_no_noise_of_s_prime():
    model = coin()
    exact = 5.0 * sum(0.9 ** t for t in range(20))
    policy = offline.solve(model, timeout=60, precision=0.01)
    for sim in (lambda est: simulate(model, lambda s: PolicyPlanner(model, policy, s), 20, 200,
                                     3, estimator=est),
                lambda est: simulate_batch(model, policy_chooser(model, policy), 20, 200, 3,
                                           estimator=est)):
        realised, expected = sim("realised"), sim("expected")
        assert realised.estimator == "realised" and expected.estimator == "expected"
        assert expected.mean == pytest.approx(exact) and expected.std == pytest.approx(0.0)
        assert realised.ci95_low <= exact <= realised.ci95_high
        assert realised.ci95_high - realised.ci95_low > 1.0


def test_an_unknown_estimator_is_refused():
    with pytest.raises(SolverError, match="estimator"):
        simulate_batch(coin(), q_chooser(np.zeros((1, 2))), 1, 1, estimator="mean")


def test_the_command_names_its_estimator_and_runs_a_policy_all_at_once(capsys, tmp_path):
    policy = tmp_path / "tiger.policy"
    assert run(["solve", TIGER, "--precision", "0.1", "-o", str(policy)]) == 0
    capsys.readouterr()
    argv = ["simulate", TIGER, "--policy", str(policy), "--sim-len", "20", "--sim-num", "40"]
    assert run(argv + ["--estimator", "expected", "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert facts["estimator"] == "expected" and facts["batched"] is True
    assert run(argv) == 0
    out = capsys.readouterr().out
    assert "estimator      realised" in out and "R(s,a,s')" in out


def test_a_saved_policys_time_per_step_is_shown_in_a_unit_that_shows_it(capsys, tmp_path):
    """A saved policy chooses in microseconds: "time per step 0.000 ms" said nothing."""
    policy = tmp_path / "tiger.policy"
    assert run(["solve", TIGER, "--precision", "0.1", "-o", str(policy)]) == 0
    capsys.readouterr()
    assert run(["simulate", TIGER, "--policy", str(policy), "--sim-len", "20",
                "--sim-num", "400"]) == 0
    line = next(line for line in capsys.readouterr().out.splitlines()
                if "time per step" in line)
    assert "0.000" not in line
    shown = re.findall(r"([0-9.]+) (s|ms|µs|ns)\b", line)
    assert len(shown) == 3 and all(float(value) > 0 for value, _unit in shown), line
    assert "the runs step together" in line


@pytest.mark.parametrize("ms, text", [(0.0, "0 ms"), (12.34, "12.3 ms"), (0.845, "845 µs"),
                                      (2e-5, "20 ns"), (1500.0, "1.5 s")])
def test_durations_take_the_unit_that_shows_three_digits(ms, text):
    assert duration(ms) == text
