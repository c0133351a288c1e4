"""A large model meets a memory budget and a timeout through ``hrc_pomdp`` in a child process
(hostile input, failure 1): each run is capped by RLIMIT_AS (cli_process.py), so a regression
that makes a dense 50,000 x 50,000 array (20 GB) fails instead of swapping. The in-process
checks of the same budget are test/unit/pomdp/test_hostile_memory.py's.
"""
import json

import numpy as np

from cli_process import GiB, run_hrc_pomdp
from large_models import torus  # noqa: F401  (the 50,000-state model, a fixture)


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
    # The clock starts with the command, reading the model included (about a second alone,
    # several under a loaded machine's two busy cores): 10 s leaves room for backups then.
    facts = _one_json(run_hrc_pomdp(["solve", str(torus), "--timeout", "10", "--json"],
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


def test_despot_on_50000_states_stays_within_its_memory_limit(torus):
    result = run_hrc_pomdp(["simulate", str(torus), "--planner", "despot", "--max-trials", "20",
                            "--time-per-step", "5", "--sim-len", "2", "--sim-num", "1",
                            "--memory-limit", "384M", "--json"],
                           address_space=1 * GiB)
    assert result.returncode == 0, result.stderr
    facts = json.loads(result.stdout)
    assert facts["steps"] == 2 and np.isfinite(facts["mean"])
