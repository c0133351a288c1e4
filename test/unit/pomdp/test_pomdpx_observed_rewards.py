"""POMDPX rewards conditioned on observation variables (the expectation over the observation,
as SARSOP reads them) and parse errors that say, in words, what is wrong and on which line."""
import numpy as np
import pytest

from ros_hrc.pomdp import offline, pomdpx

from test_pomdpx import error_of, read


def cond(var: str, parents: str, *entries) -> str:
    body = "".join(f"<Entry><Instance>{i}</Instance><ProbTable>{p}</ProbTable></Entry>"
                   for i, p in entries)
    return (f"<CondProb><Var>{var}</Var><Parent>{parents}</Parent>"
            f"<Parameter type='TBL'>{body}</Parameter></CondProb>")


def func(parents: str, *entries) -> str:
    body = "".join(f"<Entry><Instance>{i}</Instance><ValueTable>{v}</ValueTable></Entry>"
                   for i, v in entries)
    return f"<Func><Var>r</Var><Parent>{parents}</Parent><Parameter>{body}</Parameter></Func>"


# A hidden x that never changes (lo with 0.25, hi with 0.75); z is heard after each action:
# quiet with 0.9 when x is lo, loud with 0.8 when x is hi. 'wait' pays 10 when z is loud.
VARS = """<Variable>
<StateVar vnamePrev='x0' vnameCurr='x1'><ValueEnum>lo hi</ValueEnum></StateVar>
<ObsVar vname='z'><ValueEnum>quiet loud</ValueEnum></ObsVar>
<ActionVar vname='act'><ValueEnum>wait push</ValueEnum></ActionVar>
<RewardVar vname='r'/>
</Variable>"""
INIT = "<InitialStateBelief>" + cond("x0", "null", ("-", "0.25 0.75")) + "</InitialStateBelief>"
TRANS = ("<StateTransitionFunction>" + cond("x1", "act x0", ("* - -", "identity"))
         + "</StateTransitionFunction>")
OBS = ("<ObsFunction>" + cond("z", "act x1", ("* lo -", "0.9 0.1"), ("* hi -", "0.2 0.8"))
       + "</ObsFunction>")


def model_text(rewards: str, discount: str = "0.9") -> str:
    return (f"<?xml version='1.0'?>\n<pomdpx version='1.0'>\n<Discount>{discount}</Discount>\n"
            f"{VARS}\n{INIT}\n{TRANS}\n{OBS}\n<RewardFunction>{rewards}</RewardFunction>\n"
            "</pomdpx>\n")


OBSERVED_REWARD = func("act z", ("wait loud", "10"), ("wait quiet", "0"), ("push *", "0"))


def test_a_reward_on_an_observation_is_its_expectation_given_the_next_state():
    m = read(model_text(OBSERVED_REWARD))
    wait = m.R[m.actions.index("wait")].toarray()
    # R(s, wait, s') = 10 * P(loud | s'): 10 * 0.1 into lo, 10 * 0.8 into hi, from any s.
    assert np.allclose(wait, [[1.0, 8.0], [1.0, 8.0]])
    assert np.allclose(m.R[m.actions.index("push")].toarray(), 0.0)
    # With x fixed, waiting forever earns 0.25 * 1 + 0.75 * 8 = 6.25 a step: 62.5 at 0.9.
    assert np.allclose(m.R_sa[m.actions.index("wait")], [1.0, 8.0])


def test_the_solver_values_an_observation_conditioned_reward_as_computed_by_hand():
    policy = offline.solve(read(model_text(OBSERVED_REWARD)), timeout=60.0, precision=1e-3)
    assert policy.lower - 1e-9 <= 62.5 <= policy.upper + 1e-9
    assert policy.upper - policy.lower <= 1e-3


def test_rewards_on_states_and_observations_together_are_summed_in_expectation():
    # A second <Func> on (act, x0, z): 'push' from hi pays 4 when z is quiet (0.2 into hi).
    extra = func("act x0 z", ("* * *", "0"), ("push hi quiet", "4"))
    m = read(model_text(OBSERVED_REWARD + extra))
    push = m.R[m.actions.index("push")].toarray()
    assert np.allclose(push, [[0.0, 0.0], [4 * 0.9, 4 * 0.2]])


def test_a_reward_on_an_observation_needs_observations():
    text = model_text(OBSERVED_REWARD).replace("<StateVar vnamePrev='x0' vnameCurr='x1'>",
                                               "<StateVar vnamePrev='x0' vnameCurr='x1' "
                                               "fullyObs='true'>")
    err = error_of(text)
    assert err.where and "fully observable" in err.what and "'z'" in err.what


# -- parse errors in words -----------------------------------------------------------------------
def test_a_nested_comment_is_named_as_such_at_the_inner_comment():
    text = model_text(OBSERVED_REWARD).replace(
        "<Variable>", "<!-- the variables\n  <!-- an inner note -->\n-->\n<Variable>", 1)
    err = error_of(text)
    inner = next(i for i, l in enumerate(text.splitlines(), 1) if "inner note" in l)
    outer = inner - 1
    assert err.where == str(inner)
    assert "comment is opened inside another comment" in err.what
    assert f"line {outer}" in err.what and "do not nest" in err.what


def test_two_hyphens_inside_a_comment_are_named():
    text = model_text(OBSERVED_REWARD).replace("<Variable>", "<!-- a -- b -->\n<Variable>", 1)
    err = error_of(text)
    assert "'--' inside a comment" in err.what and err.where.isdigit()


def test_a_non_number_is_reported_at_its_own_line_not_the_tables():
    numbers = "0.9\n0.1\n0.2\n0.8x\n"
    text = model_text(OBSERVED_REWARD).replace(
        cond("z", "act x1", ("* lo -", "0.9 0.1"), ("* hi -", "0.2 0.8")),
        cond("z", "act x1 ", ("* - -", numbers)))
    err = error_of(text)
    bad = next(i for i, l in enumerate(text.splitlines(), 1) if l == "0.8x")
    tag = next(i for i, l in enumerate(text.splitlines(), 1) if "<ProbTable>0.9" in l)
    assert bad != tag
    assert err.where == str(bad), str(err)
    assert "'0.8x', which is not a number" in err.what


def test_a_non_finite_number_is_reported_at_its_own_line():
    text = model_text(OBSERVED_REWARD).replace(("wait loud</Instance><ValueTable>10"),
                                               "wait loud</Instance><ValueTable>\n\ninf")
    err = error_of(text)
    bad = next(i for i, l in enumerate(text.splitlines(), 1) if l.startswith("inf<"))
    assert err.where == str(bad) and "non-finite" in err.what
