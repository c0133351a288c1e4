"""POMDPX: variables, factored tables flattened exactly, observability, safe XML, every error."""
import importlib.util
import time
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from ros_hrc.errors import ModelFormatError
from ros_hrc.pomdp import pomdpx
from ros_hrc.pomdp.io import differences

ROOT = Path(__file__).resolve().parents[3]


def read(text: str):
    return pomdpx.loads(text, source="test.pomdpx")


def error_of(text: str) -> ModelFormatError:
    with pytest.raises(ModelFormatError) as info:
        read(text)
    return info.value


def doc(variables: str, functions: str, discount: str = "0.9") -> str:
    return (f"<?xml version='1.0'?>\n<pomdpx version='1.0'>\n<Discount>{discount}</Discount>\n"
            f"<Variable>\n{variables}\n</Variable>\n{functions}\n</pomdpx>\n")


def cond(var: str, parents: str, *entries) -> str:
    body = "".join(f"<Entry><Instance>{i}</Instance><ProbTable>{p}</ProbTable></Entry>"
                   for i, p in entries)
    return (f"<CondProb><Var>{var}</Var><Parent>{parents}</Parent>"
            f"<Parameter type='TBL'>{body}</Parameter></CondProb>")


def func(parents: str, *entries, var: str = "r") -> str:
    body = "".join(f"<Entry><Instance>{i}</Instance><ValueTable>{v}</ValueTable></Entry>"
                   for i, v in entries)
    return f"<Func><Var>{var}</Var><Parent>{parents}</Parent><Parameter>{body}</Parameter></Func>"


# A two-variable POMDP: a hidden 2-valued x, a fully observable 3-valued y, one observation var.
VARS = """<StateVar vnamePrev='x0' vnameCurr='x1' fullyObs='false'><ValueEnum>lo hi</ValueEnum></StateVar>
<StateVar vnamePrev='y0' vnameCurr='y1' fullyObs='true'><NumValues>3</NumValues></StateVar>
<ObsVar vname='z'><ValueEnum>quiet loud</ValueEnum></ObsVar>
<ActionVar vname='act'><ValueEnum>wait push</ValueEnum></ActionVar>
<RewardVar vname='r'/>"""
INIT = ("<InitialStateBelief>" + cond("x0", "null", ("-", "0.25 0.75"))
        + cond("y0", "null", ("-", "1 0 0")) + "</InitialStateBelief>")
TRANS = ("<StateTransitionFunction>"
         + cond("x1", "act x0", ("* - -", "identity"), ("push lo -", "0.4 0.6"))
         + cond("y1", "act y0", ("wait - -", "identity"), ("push - -", "0 1 0 0 0 1 0 0 1"))
         + "</StateTransitionFunction>")
OBS = ("<ObsFunction>" + cond("z", "act x1", ("* lo -", "0.9 0.1"), ("* hi -", "0.2 0.8"),
                              ("wait * -", "uniform")) + "</ObsFunction>")
REWARDS = ("<RewardFunction>" + func("act x0", ("push hi", "5"), ("* lo", "-1"))
           + func("y1", ("s2", "10")) + "</RewardFunction>")


def momdp():
    return read(doc(VARS, INIT + TRANS + OBS + REWARDS))


# -- flattening -------------------------------------------------------------------------------------
def test_states_are_the_product_of_variables_first_most_significant():
    m = momdp()
    assert m.states == ["lo_s0", "lo_s1", "lo_s2", "hi_s0", "hi_s1", "hi_s2"]
    assert m.actions == ["wait", "push"]
    assert np.allclose(m.initial_belief, [0.25, 0, 0, 0.75, 0, 0])


def test_transitions_are_the_product_of_the_variables_tables():
    m = momdp()
    assert np.array_equal(m.dense_T[0], np.eye(6))                  # wait: nothing moves
    px = np.array([[0.4, 0.6], [0.0, 1.0]])                          # push: x
    py = np.array([[0, 1, 0], [0, 0, 1], [0, 0, 1]])                 # push: y
    expected = np.einsum("ik,jl->ijkl", px, py).reshape(6, 6)        # rows of x, then of y
    assert np.allclose(m.dense_T[1], expected)
    assert all(sp.issparse(t) for t in m.T)


def test_mixed_observability_puts_the_fully_observable_variable_in_the_observation():
    m = momdp()
    assert not m.fully_observable
    assert m.observations == ["s0_quiet", "s0_loud", "s1_quiet", "s1_loud", "s2_quiet", "s2_loud"]
    # push, next state (hi, s1): y is seen as s1, z is loud with 0.8
    o = m.dense_O[1][m.states.index("hi_s1")]
    assert np.allclose(o, [0, 0, 0.2, 0.8, 0, 0])
    # wait: z is uniform whatever x (the later '*' entry overrides)
    assert np.allclose(m.dense_O[0][m.states.index("lo_s2")], [0, 0, 0, 0, 0.5, 0.5])
    assert m.meta["pomdpx"]["state_variables"][1]["fully_observable"] is True


def test_several_reward_functions_are_summed_over_previous_and_next_variables():
    m = momdp()
    hi_s1, hi_s2, lo_s0 = (m.states.index(n) for n in ("hi_s1", "hi_s2", "lo_s0"))
    assert m.R[1][hi_s1, hi_s2] == 5 + 10          # push from hi, next y = s2
    assert m.R[0][lo_s0, lo_s0] == -1
    assert m.R[1][hi_s1, m.states.index("lo_s0")] == 5   # kept even where T is 0 (small model)


def test_an_all_fully_observable_model_is_an_mdp():
    text = doc("<StateVar vnamePrev='s0' vnameCurr='s1' fullyObs='true'><ValueEnum>a b</ValueEnum>"
               "</StateVar><ActionVar vname='act'><NumValues>2</NumValues></ActionVar><RewardVar vname='r'/>",
               "<InitialStateBelief>" + cond("s0", "null", ("-", "uniform")) + "</InitialStateBelief>"
               "<StateTransitionFunction>" + cond("s1", "act s0", ("a0 - -", "identity"),
                                                  ("a1 * -", "0 1")) + "</StateTransitionFunction>"
               "<RewardFunction>" + func("act s1", ("a1 b", "1")) + "</RewardFunction>")
    m = read(text)
    assert m.fully_observable and m.observations == ["a", "b"] and m.actions == ["a0", "a1"]
    assert np.array_equal(m.dense_O[0], np.eye(2))
    assert np.array_equal(m.dense_T[1], [[0, 1], [0, 1]])
    assert m.R[1][0, 1] == 1 and m.R[1][1, 1] == 1


def test_without_any_observation_a_pomdp_sees_none():
    text = doc("<StateVar vnamePrev='s0' vnameCurr='s1'><NumValues>2</NumValues></StateVar>"
               "<ActionVar vname='act'><ValueEnum>go</ValueEnum></ActionVar>",
               "<InitialStateBelief>" + cond("s0", "null", ("-", "0.5 0.5")) + "</InitialStateBelief>"
               "<StateTransitionFunction>" + cond("s1", "act s0", ("* - -", "identity"))
               + "</StateTransitionFunction>")
    m = read(text)
    assert m.observations == ["none"] and m.states == ["s0", "s1"]
    assert np.array_equal(m.dense_O[0], [[1], [1]])
    assert m.R[0].nnz == 0


def test_star_repeats_dash_enumerates_and_later_entries_override():
    text = doc("<StateVar vnamePrev='s0' vnameCurr='s1'><ValueEnum>a b c</ValueEnum></StateVar>"
               "<ActionVar vname='act'><ValueEnum>go</ValueEnum></ActionVar>",
               "<InitialStateBelief>" + cond("s0", "null", ("a", "1")) + "</InitialStateBelief>"
               "<StateTransitionFunction>" + cond("s1", "act s0",
                                                  ("go * -", "0.2 0.3 0.5"),   # every row
                                                  ("go - c", "0.5 0.1 0.5"),   # column c, by row
                                                  ("* b -", "uniform"),        # row b again
                                                  ("go 0 -", "0.9 0 0.1"))     # row a, by index
               + "</StateTransitionFunction>", discount="0.5")
    m = read(text)
    assert np.allclose(m.dense_T[0], [[0.9, 0, 0.1], [1 / 3] * 3, [0.2, 0.3, 0.5]])
    assert np.array_equal(m.initial_belief, [1, 0, 0])


def test_rowwise_kron_matches_dense_products():
    A = sp.random(5, 3, density=0.5, random_state=1, format="csr")
    B = sp.random(5, 4, density=0.5, random_state=2, format="csr")
    C = pomdpx.rowwise_kron(A, B).toarray()
    for s in range(5):
        assert np.allclose(C[s], np.kron(A[s].toarray().ravel(), B[s].toarray().ravel()))


def test_the_seed_header_and_latin1_bytes_are_read():
    text = doc(VARS, INIT + TRANS + OBS + REWARDS).replace(
        "<?xml version='1.0'?>", "<?xml version='1.0' encoding='ISO-8859-1'?>").replace(
        "<Discount>", "<Description>caf\u00e9 mod\u00e8le</Description><Discount>")
    m = pomdpx.loads(text.encode("latin-1"), source="x.pomdpx")
    assert m.n_states == 6


# -- RockSample_7_8 -----------------------------------------------------------------------------------
def _generator():
    spec = importlib.util.spec_from_file_location("make_rocksample_pomdpx",
                                                  ROOT / "bench" / "make_rocksample_pomdpx.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_rocksample_7_8_parses_in_seconds_with_sparse_tables(tmp_path):
    path = tmp_path / "RockSample_7_8.pomdpx"
    path.write_text(_generator().rocksample_pomdpx(7, 8))
    start = time.perf_counter()
    m = pomdpx.load(path)
    seconds = time.perf_counter() - start
    assert seconds < 15, f"parsing took {seconds:.1f} s"
    assert (m.n_states, m.n_actions, m.n_observations) == (50 * 256, 13, 50 * 3)
    assert all(t.nnz == m.n_states for t in m.T)           # deterministic moves: one per row
    assert all(abs(t.sum(axis=1) - 1).max() < 1e-9 for t in m.T)
    assert sum(r.nnz for r in m.R) < 10_000
    good0 = m.states.index("s20_good_" + "_".join(["bad"] * 7))      # rover on rock 0 (2, 0)
    assert m.R_sa[m.actions.index("as"), good0] == 10
    assert m.states[m.T[m.actions.index("as")][good0].indices[0]] == "s20_" + "_".join(["bad"] * 8)
    east = m.states.index("s63_" + "_".join(["bad"] * 8))
    assert m.R_sa[m.actions.index("ame"), east] == 10
    # checking rock 0 from (0, 0), 2 cells away: right with (1 + 2^(-2/20)) / 2
    o = m.O[m.actions.index("ac0")][m.states.index("s00_good_" + "_".join(["bad"] * 7))].toarray()
    assert o[0, m.observations.index("s00_ogood")] == pytest.approx((1 + 2 ** -0.1) / 2)
    assert np.count_nonzero(m.initial_belief) == 256


# -- errors ------------------------------------------------------------------------------------------
GOOD = doc(VARS, INIT + TRANS + OBS + REWARDS)


@pytest.mark.parametrize("old, new, words", [
    ("0.4 0.6", "0.4 -0.6", "negative probability"),
    ("0.4 0.6", "0.4 0.5", "sums to 0.9"),
    ("0.4 0.6", "0.4 0.6 0", "has 3 number(s)"),
    ("0.4 0.6", "0.4 six", "expected numbers, found 'six'"),
    ("push lo -", "push lo", "has 2 item(s)"),
    ("push lo -", "push middle -", "'middle' is not a value of x0"),
    ("act x0", "act xx", "unknown parent variable 'xx'"),
    ("<Var>x1</Var>", "<Var>q1</Var>", "unknown variable 'q1'"),
    ("<Discount>0.9", "<Discount>1.5", "outside [0, 1)"),
    ("<Discount>0.9", "<Discount>nine", "not a number"),
    ("type='TBL'", "type='DD'", "not supported"),
    ("* - -</Instance><ProbTable>identity", "* - *</Instance><ProbTable>identity", "identity"),
    ("vnameCurr='y1'", "vnameCurr='x1'", "used twice"),
    ("fullyObs='true'", "fullyObs='yes'", "fullyObs must be"),
    ("act x1", "act x0", "cannot be a parent"),
    ("<RewardVar vname='r'/>", "<RewardVar vname='r'/><Bogus/>", "unknown element <Bogus>"),
])
def test_each_error_names_the_file_line_and_problem(old, new, words):
    assert old in GOOD
    text = GOOD.replace(old, new, 1)
    err = error_of(text)
    assert err.path == "test.pomdpx"
    assert err.where and err.where.isdigit(), str(err)
    assert words in err.what, str(err)


def test_errors_point_at_the_line_of_the_offending_element():
    text = GOOD.replace("<ProbTable>0.4 0.6", "\n\n<ProbTable>0.4 -0.6", 1)
    line = next(i for i, l in enumerate(text.splitlines(), 1) if "0.4 -0.6" in l)
    assert error_of(text).where == str(line)
    # a table that does not sum to one is reported at its <CondProb>
    text = GOOD.replace("<CondProb><Var>x1", "\n<CondProb><Var>x1").replace("0.4 0.6", "0.4 0.5")
    line = next(i for i, l in enumerate(text.splitlines(), 1) if "<Var>x1" in l)
    err = error_of(text)
    assert err.where == str(line) and "P(x1 | act=push, x0=lo) sums to 0.9" in err.what


def test_a_missing_table_is_reported():
    err = error_of(GOOD.replace(cond("y1", "act y0", ("wait - -", "identity"),
                                     ("push - -", "0 1 0 0 0 1 0 0 1")), ""))
    assert "no transition table for state variable y0/y1" in err.what
    err = error_of(GOOD.replace(OBS, ""))
    assert "no <ObsFunction>" in err.what


def test_malformed_xml_names_the_line():
    err = error_of("<?xml version='1.0'?>\n<pomdpx>\n<Discount>0.9</Discount>\n</pomdp>\n")
    assert err.where == "4" and "malformed XML" in err.what
    assert "not <pomdpx>" in error_of("<pomdp/>").what


def test_an_entity_bomb_is_refused_without_expanding_it():
    bomb = ("<?xml version='1.0'?>\n<!DOCTYPE pomdpx [\n<!ENTITY a 'aaaaaaaaaa'>\n"
            + "".join(f"<!ENTITY {chr(98 + i)} '{('&' + chr(97 + i) + ';') * 10}'>\n" for i in range(8))
            + "]>\n<pomdpx><Description>&i;</Description></pomdpx>\n")
    start = time.perf_counter()
    err = error_of(bomb)
    assert time.perf_counter() - start < 1.0
    assert "unsafe XML refused" in err.what and err.where == "3"


def test_an_external_entity_is_refused():
    text = ("<?xml version='1.0'?>\n<!DOCTYPE pomdpx [<!ENTITY ext SYSTEM 'file:///etc/passwd'>]>\n"
            "<pomdpx><Description>&ext;</Description></pomdpx>\n")
    assert "unsafe XML refused" in error_of(text).what


def test_a_file_that_cannot_be_read_is_a_format_error(tmp_path):
    with pytest.raises(ModelFormatError) as info:
        pomdpx.load(tmp_path / "missing.pomdpx")
    assert "cannot read" in info.value.what


# -- writing ------------------------------------------------------------------------------------------
def test_a_factored_model_written_flat_reads_back_to_identical_tables():
    m = momdp()
    back = read(pomdpx.dump(m))
    assert differences(m, back) == []
    assert len(back.meta["pomdpx"]["state_variables"]) == 1


def test_an_mdp_is_written_with_a_fully_observable_variable_and_no_observation():
    text = pomdpx.dump(read(GOOD.replace("fullyObs='false'", "fullyObs='true'")))
    assert 'fullyObs="true"' in text and "<ObsVar" not in text and "<ObsFunction>" not in text
    assert read(text).fully_observable


def test_a_cost_model_keeps_its_flag_through_pomdpx():
    m = momdp()
    m.minimise = True
    text = pomdpx.dump(m)
    assert "[values: cost]" in text
    assert read(text).minimise


def test_names_that_would_break_the_xml_are_refused():
    m = momdp()
    m.actions[0] = "a<b"
    with pytest.raises(ModelFormatError):
        pomdpx.dump(m)


def test_the_seeds_printed_figures_read_and_say_what_is_missing():
    # Figures 3.5-3.8 print only graspAttempt's transitions: the reader parses the seed's own
    # text and names the first table row that is missing (models/human completes them).
    with pytest.raises(ModelFormatError) as info:
        pomdpx.load(ROOT / "test" / "fixtures" / "seed_figures_3_5_to_3_8.pomdpx")
    err = info.value
    assert err.where == "51"
    assert "P(state_1 | action_agent=lookAround, state_0=task_assigned) sums to 0" in err.what
    assert "32 such row(s)" in err.what            # lookAround, idle, walkAway, warnRobot
