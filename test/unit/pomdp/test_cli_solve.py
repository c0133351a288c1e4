"""``hrc_pomdp solve`` and ``hrc_pomdp simulate``."""
import json
from pathlib import Path

import pytest

from ros_hrc.commands.pomdp import run

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
TIGER = str(FIXTURES / "tiger.95.pomdp")
COST_MODEL = """\
discount: 0.9
values: cost
states: 2
actions: 2
observations: 2
start: uniform
T: * identity
O: * uniform
R: 0 : * : * : * 1.0
R: 1 : * : * : * 2.0
"""


def _json(capsys, argv):
    assert run(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_solve_tiger_prints_bounds_that_bracket_the_optimum(capsys, tmp_path):
    policy = tmp_path / "tiger.policy"
    facts = _json(capsys, ["solve", TIGER, "--precision", "0.01", "-o", str(policy), "--json"])
    assert facts["lower"] <= 19.375 and facts["upper"] >= 19.365
    assert facts["upper"] - facts["lower"] <= 0.01 and facts["converged"]
    assert facts["seconds"] >= 0 and facts["solver"] == "hsvi2"
    assert policy.exists()


def test_solve_text_output_names_the_bounds_and_time(capsys):
    assert run(["solve", TIGER, "--precision", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "lower bound" in out and "upper bound" in out and " s " in out


def test_simulate_a_saved_policy_reports_mean_and_interval(capsys, tmp_path):
    policy = tmp_path / "tiger.policy"
    assert run(["solve", TIGER, "--precision", "0.1", "-o", str(policy)]) == 0
    capsys.readouterr()
    facts = _json(capsys, ["simulate", TIGER, "--policy", str(policy), "--sim-len", "50",
                           "--sim-num", "30", "--seed", "3", "--json"])
    assert facts["ci95_low"] <= facts["mean"] <= facts["ci95_high"]
    assert facts["runs"] == 30 and facts["ms_per_step"] >= 0
    again = _json(capsys, ["simulate", TIGER, "--policy", str(policy), "--sim-len", "50",
                           "--sim-num", "30", "--seed", "3", "--json"])
    assert again["mean"] == facts["mean"]


def test_simulate_with_despot_under_a_trial_cap(capsys):
    facts = _json(capsys, ["simulate", TIGER, "--planner", "despot", "--max-trials", "5",
                           "--scenarios", "100", "--time-per-step", "5", "--sim-len", "5",
                           "--sim-num", "2", "--json"])
    assert facts["steps"] == 10 and "DESPOT" in facts["planner"]


def test_a_cost_model_reports_costs(capsys, tmp_path):
    model = tmp_path / "cost.pomdp"
    model.write_text(COST_MODEL)
    facts = _json(capsys, ["solve", str(model), "--json"])
    assert facts["values"] == "cost"
    assert facts["lower"] == pytest.approx(10.0, abs=1e-3)      # 1 per step, 1 / (1 - 0.9)
    assert facts["lower"] <= facts["upper"]


@pytest.mark.parametrize("argv", [
    ["simulate", TIGER, "--policy", "/nonexistent/x.policy", "--sim-len", "1", "--sim-num", "1"],
    ["simulate", TIGER, "--planner", "mdp", "--sim-len", "1", "--sim-num", "1"],
    ["simulate", TIGER, "--planner", "despot", "--sim-len", "0", "--sim-num", "1"],
    ["solve", TIGER, "--precision", "-1"],
])
def test_errors_are_one_line_and_exit_2(capsys, argv):
    assert run(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.strip()


def test_a_file_that_is_not_a_policy_is_refused_in_one_line(capsys, tmp_path):
    bad = tmp_path / "bad.policy"
    bad.write_text("garbage\n")
    assert run(["simulate", TIGER, "--policy", str(bad), "--sim-len", "1", "--sim-num", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0]
