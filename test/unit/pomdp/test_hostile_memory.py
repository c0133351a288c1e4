"""A large model meets a memory budget and a timeout (hostile input, failure 1).

Memory must be bounded by the model's non-zeros: no S x S (or S x S x Z) array on the way
through info, solve, simulate or convert. Models too large for ``--memory-limit`` are refused in
one line before anything large is allocated, and ``--timeout`` counts from the start, the
building of the solver's tables included. The 50,000-state model is a factored POMDPX of a few
kilobytes (large_models.py); its CLI runs are child processes under RLIMIT_AS (cli_process.py),
so a regression that makes a dense 50,000 x 50,000 array (20 GB) fails instead of swapping.
"""
import json
import time
import tracemalloc

import numpy as np
import pytest
import scipy.sparse as sp

from ros_hrc.pomdp import cassandra, mdp
from ros_hrc.commands.pomdp import run
from ros_hrc.pomdp.model import Model

from cli_process import GiB, run_hrc_pomdp
from large_models import torus_pomdpx

#: 250 x 200 cells: 50,000 states, 250,000 non-zeros in T.
NX, NY = 250, 200


@pytest.fixture(scope="module")
def torus(tmp_path_factory):
    path = tmp_path_factory.mktemp("large") / "torus.pomdpx"
    path.write_text(torus_pomdpx(NX, NY))
    return path


def _one_json(result):
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    facts = json.loads(result.stdout)
    assert np.isfinite(facts["lower"]) and np.isfinite(facts["upper"])
    assert facts["lower"] <= facts["upper"]
    return facts


def test_solve_on_50000_states_makes_no_state_by_state_array(torus):
    # In a process that may not map more than 1 GiB in all (the interpreter, numpy and scipy
    # map about 250 MB before any model is read); an identity matrix of 50,000 states is 20 GB.
    facts = _one_json(run_hrc_pomdp(["solve", str(torus), "--timeout", "3", "--json"],
                                    address_space=1 * GiB))
    assert facts["stats"]["backups"] > 0                 # it did solve, not just start


def test_solve_stops_at_its_memory_limit_and_still_reports_its_bounds(torus):
    from ros_hrc.pomdp import hsvi, io
    model = io.load_model(torus)
    # The solver's tables and working arrays, and room for about 100 stored vectors.
    limit_mib = (hsvi.memory_needed(model) + 100 * 8 * model.n_states) // (1 << 20) + 1
    facts = _one_json(run_hrc_pomdp(["solve", str(torus), "--timeout", "30",
                                     "--memory-limit", f"{limit_mib}M", "--json"],
                                    address_space=1 * GiB))
    assert facts["stats"]["memory_limit_reached"] and not facts["converged"]


def test_a_timeout_of_zero_still_reports_valid_bounds_of_a_large_model(torus):
    # The clock starts with the command: the tables and MDP bounds are cut short (one
    # iteration each), no trial runs, and the bounds are reported as at any timeout.
    result = run_hrc_pomdp(["solve", str(torus), "--timeout", "0", "--json"],
                           address_space=1 * GiB)
    facts = _one_json(result)
    assert facts["stats"]["trials"] == 0 and facts["stats"]["sweeps"] == 0
    assert not facts["converged"]


def test_the_mdp_bounds_stop_at_a_deadline_after_one_iteration(tiger):
    past = time.perf_counter()
    solution = mdp.value_iteration(tiger, epsilon=1e-12, deadline=past)
    assert solution.iterations == 1 and np.isfinite(solution.error_bound)
    full = mdp.blind_lower_bound(tiger)
    cut = mdp.blind_lower_bound(tiger, deadline=past)
    assert np.all(cut <= full + 1e-12) and not np.allclose(cut, full)
    assert np.all(mdp.fast_informed_bound(tiger, deadline=past)
                  >= mdp.fast_informed_bound(tiger) - 1e-9)


def test_a_model_too_large_for_the_memory_limit_is_refused_in_one_line(torus, capsys):
    assert run(["solve", str(torus), "--memory-limit", "64M"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"hrc_pomdp: {torus}: ") and "needs about" in err
    assert "--memory-limit" in err and "64 MiB" in err


def test_uniform_transitions_on_50000_states_are_refused_before_allocation(tmp_path):
    # T: * uniform is 2.5e9 non-zeros per action: refused from the statements alone.
    path = tmp_path / "dense.pomdp"
    path.write_text("discount: 0.95\nstates: 50000\nactions: 2\nobservations: 2\n"
                    "T: * uniform\nO: * uniform\nR: * : * : * : * 1\n")
    result = run_hrc_pomdp(["info", str(path)], address_space=1 * GiB)
    assert result.returncode == 1, result.stderr
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert f"hrc_pomdp: {path}: building T, O and R" in result.stderr
    assert "GiB" in result.stderr and "--memory-limit" in result.stderr


def test_a_state_count_too_large_to_name_is_refused_at_its_line(tmp_path):
    path = tmp_path / "many.pomdp"
    path.write_text("discount: 0.9\nstates: 99999999999\nactions: 1\nobservations: 1\n")
    result = run_hrc_pomdp(["info", str(path)], address_space=1 * GiB)
    assert result.returncode == 1, result.stderr
    assert result.stderr.startswith(f"hrc_pomdp: {path}:2: 99999999999 states needs about")


def test_observation_dependent_rewards_on_a_large_model_fold_without_a_dense_grid():
    # 5000 states x 5000 x 3 observations would be a 600 MB grid per action.
    text = ("discount: 0.9\nstates: 5000\nactions: 2\nobservations: 3\nT: * identity\n"
            "O: * uniform\nR: * : * : * : o0 3\nR: a1 : * : * : o2 -6\n")
    tracemalloc.start()
    try:
        model = cassandra.loads(text)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 64 << 20
    assert np.allclose(model.R[0].diagonal(), 1.0)         # 3 x 1/3
    assert np.allclose(model.R[1].diagonal(), -1.0)        # (3 + 0 - 6) x 1/3
    assert model.R[0].nnz == 5000                           # on T's pattern only


def test_many_actions_on_few_states_use_the_sparse_tables():
    # 300 states but 60 actions: a dense (A, S, S) copy is 43 MB, past the dense fast path.
    S, A = 300, 60
    eye = sp.identity(S, format="csr")
    model = Model(states=[f"s{i}" for i in range(S)], actions=[f"a{i}" for i in range(A)],
                  observations=["o"], discount=0.9, initial_belief=np.full(S, 1.0 / S),
                  T=[eye] * A, O=[sp.csr_matrix(np.ones((S, 1)))] * A,
                  R=[sp.csr_matrix(eye * float(a)) for a in range(A)])
    model.validate()
    assert not model.dense_tables_fit
    solution = mdp.value_iteration(model)
    assert solution.V == pytest.approx(np.full(S, (A - 1) / 0.1))
    from ros_hrc.pomdp import belief
    b, _ = belief.update(model, model.initial_belief, 3, 0)
    assert b == pytest.approx(model.initial_belief)
    assert "dense_T" not in model.__dict__ and "dense_O" not in model.__dict__


def test_despot_too_large_for_the_memory_limit_is_refused_in_one_line(torus, capsys):
    argv = ["simulate", str(torus), "--planner", "despot", "--scenarios", "1000000",
            "--depth", "100000", "--sim-len", "1", "--sim-num", "1"]
    assert run(argv + ["--memory-limit", "4G"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "simulating with DESPOT" in err and "--memory-limit" in err


def test_despot_on_50000_states_stays_within_its_memory_limit(torus):
    result = run_hrc_pomdp(["simulate", str(torus), "--planner", "despot", "--max-trials", "20",
                            "--time-per-step", "5", "--sim-len", "2", "--sim-num", "1",
                            "--memory-limit", "384M", "--json"],
                           address_space=1 * GiB)
    assert result.returncode == 0, result.stderr
    facts = json.loads(result.stdout)
    assert facts["steps"] == 2 and np.isfinite(facts["mean"])
