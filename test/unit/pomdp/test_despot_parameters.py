"""DESPOT's parameters have one definition (ros_hrc.pomdp.despot_parameters): the launch
arguments, ``hrc_pomdp simulate``'s options and DespotConfig take the same values and refuse
the first one past a limit in one line that says the limit."""
import math
from pathlib import Path

import pytest

from ros_hrc import settings
from ros_hrc.commands.pomdp import run
from ros_hrc.errors import SolverError
from ros_hrc.pomdp.despot import DespotConfig
from ros_hrc.pomdp.despot_parameters import (DESPOT_PARAMETERS, SETTING_NAMES, config_value,
                                             parameter)
from ros_hrc.settings import SettingError

TIGER = str(Path(__file__).resolve().parents[2] / "fixtures" / "tiger.95.pomdp")
SIMULATE = ["simulate", TIGER, "--planner", "despot", "--max-trials", "1", "--sim-len", "1",
            "--sim-num", "1"]

NUMBERS = [p for p in DESPOT_PARAMETERS if not p.choices]


def _over(p):
    """The first value past the parameter's upper limit, as typed."""
    return str(p.high + 1) if p.kind is int else f"{p.high * 1.001:g}"


def _simulate(capsys, option, value):
    code = run(SIMULATE + [option, value, "--memory-limit", "1G", "--json"])
    return code, capsys.readouterr()


@pytest.mark.parametrize("name", SETTING_NAMES)
def test_a_launch_argument_is_its_definition(name):
    p, s = parameter(name), settings.SETTINGS[name]
    assert (s.default, s.minimum, s.maximum) == (p.default, p.low, p.high)
    assert s.kind == ("int" if p.kind is int else "float") and s.doc == p.doc
    assert s.requirement() == p.requirement()


@pytest.mark.parametrize("p", NUMBERS, ids=lambda p: p.name)
def test_the_largest_value_passes_every_door(p, capsys):
    top = str(int(p.high)) if p.kind is int else f"{p.high:g}"
    assert p.parse(top) == p.high
    if p.name in SETTING_NAMES:
        assert settings.parse(p.name, top) == p.high
    config = DespotConfig(max_trials=5)
    setattr(config, p.field, config_value(p.name, p.kind(p.high)))
    config.validate()


@pytest.mark.parametrize("p", NUMBERS, ids=lambda p: p.name)
def test_one_past_the_limit_is_refused_in_one_line_that_says_it(p, capsys):
    over, limit = _over(p), p.requirement()
    assert f"to {int(p.high) if float(p.high).is_integer() else p.high}" in limit
    # hrc_pomdp simulate: argparse's line
    code, out = _simulate(capsys, p.option, over)
    assert code == 2 and out.out == ""
    assert out.err.strip().splitlines()[-1] == (
        f"hrc_pomdp simulate: error: argument {p.option}: {limit}, got {over!r}")
    # the launch argument
    if p.name in SETTING_NAMES:
        with pytest.raises(SettingError) as refused:
            settings.parse(p.name, over)
        assert str(refused.value) == f"{p.name}:={over}: {limit}"
    # the toolkit's config
    config = DespotConfig(max_trials=5)
    setattr(config, p.field, p.kind(float(over)))
    with pytest.raises(SolverError) as refused:
        config.validate()
    assert str(refused.value) == f"DESPOT's {p.name} {limit}, got {p.kind(float(over))!r}"


def test_zero_is_the_off_value_of_the_time_budget_and_the_trial_cap():
    assert config_value("time_per_step", 0.0) == math.inf
    assert config_value("max_trials", 0) is None
    assert config_value("depth", 5) == 5


def test_simulate_without_a_time_budget_plays_on_its_trials(capsys):
    code, out = _simulate(capsys, "--time-per-step", "0")
    assert code == 0, out.err
    assert '"planner": "DESPOT (no time budget, K=500, D=90, lambda=0.1, at most 1 trials)"' \
        in out.out


def test_simulate_without_a_time_budget_or_a_trial_cap_is_one_line(capsys):
    code = run(["simulate"] + SIMULATE[1:4] + ["--sim-len", "1", "--sim-num", "1",
                                               "--time-per-step", "0"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.strip() == ("hrc_pomdp: DESPOT without a time budget (time_per_step 0) needs "
                           "max_trials")
