"""Numbers that are not finite, or so large that values overflow (hostile input, failure 2).

Both parsers refuse ``inf``, ``nan`` and ``1e999`` with the file and the line, and a reward with
|R| / (1 - discount) above ``MAX_VALUE`` (1e150); every ``--json`` output is strict JSON, and a
non-finite result that still arises is an error, never printed.
"""
import json
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from ros_hrc.errors import ModelError
from ros_hrc.commands.pomdp import run
from ros_hrc.pomdp.model import Model

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
TIGER = str(FIXTURES / "tiger.95.pomdp")

CASSANDRA = """\
discount: 0.95
states: 2
actions: 2
observations: 2
start: uniform
T: * identity
O: * uniform
R: 0 : * : * : * {reward}
R: 1 : * : * : * -1
"""

POMDPX = """\
<?xml version="1.0" encoding="UTF-8"?>
<pomdpx version="1.0" id="two">
<Discount>0.95</Discount>
<Variable>
  <StateVar vnamePrev="s_0" vnameCurr="s_1"><ValueEnum>a b</ValueEnum></StateVar>
  <ObsVar vname="o"><ValueEnum>x y</ValueEnum></ObsVar>
  <ActionVar vname="act"><ValueEnum>left right</ValueEnum></ActionVar>
  <RewardVar vname="r"/>
</Variable>
<InitialStateBelief><CondProb><Var>s_0</Var><Parent>null</Parent><Parameter type="TBL">
  <Entry><Instance>-</Instance><ProbTable>uniform</ProbTable></Entry></Parameter></CondProb>
</InitialStateBelief>
<StateTransitionFunction><CondProb><Var>s_1</Var><Parent>act s_0</Parent><Parameter type="TBL">
  <Entry><Instance>* - -</Instance><ProbTable>identity</ProbTable></Entry></Parameter></CondProb>
</StateTransitionFunction>
<ObsFunction><CondProb><Var>o</Var><Parent>act s_1</Parent><Parameter type="TBL">
  <Entry><Instance>* * -</Instance><ProbTable>uniform</ProbTable></Entry></Parameter></CondProb>
</ObsFunction>
<RewardFunction>
  <Func><Var>r</Var><Parent>act s_0</Parent><Parameter type="TBL">
    <Entry><Instance>left *</Instance><ValueTable>{reward}</ValueTable></Entry>
  </Parameter></Func>
  <Func><Var>r</Var><Parent>act</Parent><Parameter type="TBL">
    <Entry><Instance>left</Instance><ValueTable>{second}</ValueTable></Entry>
  </Parameter></Func>
</RewardFunction>
</pomdpx>
"""
#: The lines of the first <ValueTable> in POMDPX above, and of <RewardFunction>.
POMDPX_REWARD_LINE = POMDPX.splitlines().index("    <Entry><Instance>left *</Instance>"
                                               "<ValueTable>{reward}</ValueTable></Entry>") + 1
POMDPX_REWARD_FUNCTION_LINE = POMDPX.splitlines().index("<RewardFunction>") + 1


def _refused(capsys, path, line, *words):
    assert run(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"hrc_pomdp: {path}:{line}: "), err
    for word in words:
        assert word in err, err


@pytest.mark.parametrize("reward", ["1e308", "-1e308", "6e148"])      # 1e150 x 0.05 = 5e148
def test_a_reward_whose_values_overflow_is_refused_with_the_line_cassandra(capsys, tmp_path,
                                                                          reward):
    path = tmp_path / "big.pomdp"
    path.write_text(CASSANDRA.format(reward=reward))
    _refused(capsys, path, 8, "too large", "1e+150")


@pytest.mark.parametrize("literal", ["inf", "-inf", "nan", "1e999", "Infinity"])
def test_non_finite_literals_are_refused_with_the_line_in_both_formats(capsys, tmp_path,
                                                                       literal):
    path = tmp_path / "bad.pomdp"
    path.write_text(CASSANDRA.format(reward=literal))
    _refused(capsys, path, 8, "non-finite", repr(literal))
    path = tmp_path / "bad.pomdpx"
    path.write_text(POMDPX.format(reward=literal, second=0))
    _refused(capsys, path, POMDPX_REWARD_LINE, "non-finite", repr(literal))


def test_a_reward_whose_values_overflow_is_refused_with_the_line_pomdpx(capsys, tmp_path):
    path = tmp_path / "big.pomdpx"
    path.write_text(POMDPX.format(reward="1e308", second=0))
    _refused(capsys, path, POMDPX_REWARD_LINE, "too large")


def test_rewards_that_overflow_only_when_summed_are_refused_pomdpx(capsys, tmp_path):
    # Each <Func> is within 1e150 x (1 - 0.95) = 5e148; their sum is not.
    path = tmp_path / "sum.pomdpx"
    path.write_text(POMDPX.format(reward="4e148", second="4e148"))
    _refused(capsys, path, POMDPX_REWARD_FUNCTION_LINE, "summed rewards", "too large")


def test_the_largest_allowed_reward_still_solves_to_finite_bounds(capsys, tmp_path):
    path = tmp_path / "edge.pomdp"
    path.write_text(CASSANDRA.format(reward="4.9e148"))
    assert run(["solve", str(path), "--timeout", "5", "--precision", "1e140", "--json"]) == 0
    facts = json.loads(capsys.readouterr().out, parse_constant=_no_constants)
    assert np.isfinite(facts["lower"]) and np.isfinite(facts["upper"])
    assert facts["lower"] == pytest.approx(facts["upper"], rel=1e-9)       # 4.9e148 / 0.05


def test_a_model_built_in_code_with_a_non_finite_number_is_invalid():
    eye = sp.identity(2, format="csr")
    kwargs = dict(states=["a", "b"], actions=["x"], observations=["o"], discount=0.9,
                  initial_belief=np.array([0.5, 0.5]), O=[sp.csr_matrix(np.ones((2, 1)))])
    with pytest.raises(ModelError, match="non-finite"):
        Model(T=[sp.csr_matrix([[np.nan, 1.0], [0.0, 1.0]])], R=[eye], **kwargs).validate()
    with pytest.raises(ModelError, match="non-finite"):
        Model(T=[eye], R=[sp.csr_matrix(eye * np.inf)], **kwargs).validate()
    with pytest.raises(ModelError, match="too large"):
        Model(T=[eye], R=[sp.csr_matrix(eye * 1e300)], **kwargs).validate()


def _no_constants(name):
    raise AssertionError(f"not strict JSON: {name}")


@pytest.mark.parametrize("argv", [
    ["info", TIGER, "--json"],
    ["solve", TIGER, "--precision", "0.5", "--json"],
    ["simulate", TIGER, "--planner", "despot", "--max-trials", "3", "--time-per-step", "5",
     "--sim-len", "3", "--sim-num", "2", "--json"],
])
def test_every_json_output_is_strict_json(capsys, argv):
    assert run(argv) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1
    json.loads(out, parse_constant=_no_constants)


def test_a_non_finite_result_is_an_error_and_is_not_printed(capsys, monkeypatch, tmp_path):
    from ros_hrc.pomdp import offline

    real = offline.solve

    def broken(*args, **kwargs):
        policy = real(*args, **kwargs)
        policy.upper = float("nan")
        return policy

    monkeypatch.setattr(offline, "solve", broken)
    written = tmp_path / "p.policy"
    for extra in (["--json"], []):
        assert run(["solve", TIGER, "--precision", "0.5", "-o", str(written)] + extra) == 1
        captured = capsys.readouterr()
        assert captured.out == "" and not written.exists()
        assert captured.err.count("\n") == 1 and "not a finite number" in captured.err
