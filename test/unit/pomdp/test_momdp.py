"""HSVI by blocks of fully observed values (ros_hrc.pomdp.momdp, issue #24): the same values as
the plain solver, a policy that is a valid bound everywhere and acts on its own block's vectors."""
import dataclasses
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from ros_hrc.pomdp import hsvi, momdp, offline, pomdpx
from ros_hrc.pomdp.simulate import policy_chooser, simulate_batch

from solver_models import build_tiger
from test_mixed_observability import tiger_rounds

ROOT = Path(__file__).resolve().parents[3]
PRECISION = 1e-3


@pytest.fixture(scope="module")
def rocksample_3_2():
    """RockSample[3, 2]: 40 states in 10 blocks (the rover's cells and the end) of 4."""
    spec = importlib.util.spec_from_file_location("make_rocksample_pomdpx",
                                                  ROOT / "bench" / "make_rocksample_pomdpx.py")
    maker = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(maker)
    return pomdpx.loads(maker.rocksample_pomdpx(3, 2), source="RockSample_3_2.pomdpx")


@pytest.fixture(scope="module")
def rounds():
    """Tiger with a fully observed round, which starts in either of its two blocks."""
    return pomdpx.loads(tiger_rounds(), source="tiger_rounds.pomdpx")


def test_it_applies_where_observations_tell_the_fully_observed_values(rocksample_3_2, rounds):
    assert momdp.applies(rocksample_3_2) and momdp.applies(rounds)
    assert not momdp.applies(build_tiger())                 # nothing fully observed
    # A key that the observations do not tell (both tiger states a block of their own).
    tiger = build_tiger()
    assert not momdp.applies(dataclasses.replace(tiger, observed_key=np.array([0, 1])))


@pytest.mark.parametrize("name", ["rocksample_3_2", "rounds"])
def test_its_value_is_the_plain_solvers(name, request):
    model = request.getfixturevalue(name)
    by_blocks = offline.solve(model, timeout=120.0, precision=PRECISION)
    assert by_blocks.stats["solver"] == "hsvi2-momdp"
    plain = hsvi.HsviSolver(model)
    plain.run(timeout=120.0, precision=PRECISION)
    lower, upper = plain.bounds()
    # Both stop at the precision, and both brackets hold the same optimal value.
    assert by_blocks.upper - by_blocks.lower <= PRECISION and upper - lower <= PRECISION
    assert by_blocks.lower <= upper + 1e-9 and by_blocks.upper >= lower - 1e-9


def test_the_policys_value_at_the_start_is_its_lower_bound(rounds):
    policy = offline.solve(rounds, timeout=120.0, precision=PRECISION)
    split = rounds.start_split()
    value = sum(w * policy.value(b) for w, b in split)
    assert value == pytest.approx(policy.lower, abs=1e-9)


def test_at_a_belief_of_one_block_the_policy_uses_that_blocks_vectors(rocksample_3_2):
    """Another block's vector is worth less than any policy outside its block, so it never
    wins: the policy's value stays below the upper bound at every belief of every block."""
    model = rocksample_3_2
    solver = momdp.MomdpSolver(model)
    solver.run(timeout=120.0, precision=PRECISION)
    policy = solver.policy()
    for k, members in enumerate(solver.t.states):
        x = np.full(members.size, 1.0 / members.size)
        b = np.zeros(model.n_states)
        b[members] = x
        chosen = policy.alphas[policy.best(b)]
        outside = np.setdiff1d(np.arange(model.n_states), members)
        assert np.all(chosen[outside] < chosen[members].min()), f"block {k}"
        assert policy.value(b) <= float(solver.upper[k].values(x[None])[0]) + 1e-9


def test_the_policy_earns_its_lower_bound_in_simulation(rocksample_3_2):
    model = rocksample_3_2
    policy = offline.solve(model, timeout=120.0, precision=PRECISION)
    result = simulate_batch(model, policy_chooser(model, policy), sim_len=120, sim_num=2000,
                            seed=3, estimator="expected")
    # The runs' 120 steps leave out at most 0.95^120 x 10 < 0.03 of the value.
    assert result.ci95_high + 0.03 >= policy.lower


def test_a_memory_limit_counts_the_final_policy(rocksample_3_2):
    """The solver stops before its policy (alpha vectors x all states) would outgrow the limit."""
    model = rocksample_3_2
    room = 100 * model.n_states         # numbers left for vectors: fewer than it would use
    solver = momdp.MomdpSolver(model, memory_limit=momdp._memory_needed(model) + 8 * room)
    solver.run(timeout=120.0, precision=1e-9)
    assert solver.memory_limit_reached
    assert solver.policy().alphas.size <= room
