"""A large model meets a memory budget and a timeout (hostile input, failure 1).

Memory must be bounded by the model's non-zeros: no S x S (or S x S x Z) array on the way
through info, solve, simulate or convert. Models too large for ``--memory-limit`` are refused in
one line before anything large is allocated, and ``--timeout`` counts from the start, the
building of the solver's tables included. The 50,000-state model is a factored POMDPX of a few
kilobytes (large_models.py). Its runs of ``hrc_pomdp`` in a child process under RLIMIT_AS are
test/integration/pomdp/test_hostile_memory_cli.py's.
"""
import time
import tracemalloc

import numpy as np
import pytest
import scipy.sparse as sp

from ros_hrc.pomdp import cassandra, mdp
from ros_hrc.commands.pomdp import run
from ros_hrc.pomdp.model import Model

from large_models import torus  # noqa: F401  (the 50,000-state model, a fixture)


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
    argv = ["simulate", str(torus), "--planner", "despot", "--scenarios", "100000",
            "--depth", "1000", "--sim-len", "1", "--sim-num", "1"]
    assert run(argv + ["--memory-limit", "1G"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "simulating with DESPOT" in err and "--memory-limit" in err
