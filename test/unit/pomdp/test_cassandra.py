"""Cassandra .pomdp: every form of the grammar, every error, and exact round trips."""
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from ros_hrc.errors import ModelFormatError
from ros_hrc.pomdp import cassandra
from ros_hrc.pomdp.io import differences

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"

HEADER = """discount: 0.9
values: reward
states: a b c
actions: x y
observations: o p
"""

# A complete body most tests extend: T identity, O uniform, no rewards.
BODY = """T: * identity
O: * uniform
"""


def read(text: str):
    return cassandra.loads(text, source="test.pomdp")


def error_of(text: str) -> ModelFormatError:
    with pytest.raises(ModelFormatError) as info:
        read(text)
    return info.value


# -- the Tiger fixture -------------------------------------------------------------------------
def test_tiger_reads_as_the_classic_problem():
    m = cassandra.load(FIXTURES / "tiger.95.pomdp")
    assert m.states == ["tiger-left", "tiger-right"]
    assert m.actions == ["listen", "open-left", "open-right"]
    assert m.discount == 0.95 and not m.minimise and not m.fully_observable
    assert np.array_equal(m.initial_belief, [0.5, 0.5])
    assert np.array_equal(m.dense_T[0], np.eye(2))
    assert np.array_equal(m.dense_T[1], np.full((2, 2), 0.5))
    assert np.array_equal(m.dense_O[0], [[0.85, 0.15], [0.15, 0.85]])
    assert np.array_equal(m.R_sa, [[-1, -1], [-100, 10], [10, -100]])
    assert m.source.endswith("tiger.95.pomdp") and m.name == "tiger.95"


# -- preamble -----------------------------------------------------------------------------------
def test_counts_name_states_actions_and_observations_and_indices_refer_to_them():
    m = read("discount: 0.5\nstates: 3\nactions: 2\nobservations: 2\n"
             "T: * identity\nT: 1 : 0 : 0 0\nT: 1 : 0 : 2 1\nO: * uniform\nR: 1 : 0 : * : * 4\n")
    assert m.states == ["s0", "s1", "s2"] and m.actions == ["a0", "a1"]
    assert m.observations == ["o0", "o1"]
    assert m.T[1][0, 2] == 1.0 and m.T[1][0, 0] == 0.0
    assert m.R[1][0, 2] == 4.0


def test_names_win_over_indices():
    # State "1" is index 0: a token that is a name is read as that name.
    m = read("discount: 0.5\nstates: 1 0\nactions: go\nobservations: z\n"
             "T: go : 1 : 0 1\nT: go : 0 : 0 1\nO: go uniform\n")
    assert m.T[0][0, 1] == 1.0 and m.T[0][1, 1] == 1.0


def test_values_cost_stores_rewards_as_negative_costs_and_sets_minimise():
    m = read(HEADER.replace("reward", "cost") + BODY + "R: x : * : * : * 3\n")
    assert m.minimise
    assert m.R[0][0, 0] == -3.0
    back = read(cassandra.dump(m))
    assert back.minimise and differences(m, back) == []
    assert "values: cost" in cassandra.dump(m) and "R: x : a : a : * 3" in cassandra.dump(m)


def test_comments_and_numbers_running_across_lines():
    m = read(HEADER + "# a comment line\nT: x   # comment after a header\n"
             "1 0 0  0 1\n0 0 0 # a row split anywhere\n1\nT: y identity\nO: * uniform\n")
    assert np.array_equal(m.dense_T[0], np.eye(3))


@pytest.mark.parametrize("start, expected", [
    ("start: 0.2 0.3 0.5", [0.2, 0.3, 0.5]),
    ("start: uniform", [1 / 3] * 3),
    ("start: b", [0, 1, 0]),
    ("start: 2", [0, 0, 1]),
    ("start include: a c", [0.5, 0, 0.5]),
    ("start include: 0", [1, 0, 0]),
    ("start exclude: a", [0, 0.5, 0.5]),
    ("", [1 / 3] * 3),                       # no start: uniform, as pomdp-solve
])
def test_every_form_of_start(start, expected):
    m = read(HEADER + start + "\n" + BODY)
    assert np.allclose(m.initial_belief, expected)


# -- T and O in every form ---------------------------------------------------------------------------
def test_transition_single_entries_rows_and_matrices():
    m = read(HEADER + "T: x\n0 1 0\n0 0 1\n1 0 0\n"
             "T: y : a\n0.5 0.5 0\nT: y : b uniform\nT: y : c : c 1\nO: * uniform\n")
    assert np.array_equal(m.dense_T[0], [[0, 1, 0], [0, 0, 1], [1, 0, 0]])
    assert np.allclose(m.dense_T[1], [[0.5, 0.5, 0], [1 / 3] * 3, [0, 0, 1]])


def test_wildcards_in_every_position_of_t():
    m = read(HEADER + "T: * : * : * 0\nT: * : * : b 1\nO: * uniform\n")
    assert np.array_equal(m.dense_T[0][:, 1], [1, 1, 1])
    m = read(HEADER + "T: * identity\nT: x : * : c 1\nT: x : * : a 0\nT: x : * : b 0\n"
             "T: x : * : c 1\nT: y : a : *  0\nT: y : a : c 1\nO: * uniform\n")
    assert np.array_equal(m.dense_T[0], [[0, 0, 1]] * 3)
    assert np.array_equal(m.dense_T[1][0], [0, 0, 1])


def test_later_entries_override_earlier_ones_cell_by_cell():
    m = read(HEADER + "T: * uniform\nT: x identity\nT: x : a : a 0\nT: x : a : b 1\n"
             "T: x : * : c 0.5\nT: x : * : a 0\nT: x : * : b 0\nT: x : * : c 1\n"
             "T: x : c\n0 0.5 0.5\nO: * uniform\n")
    assert np.array_equal(m.dense_T[0], [[0, 0, 1], [0, 0, 1], [0, 0.5, 0.5]])
    assert np.allclose(m.dense_T[1], 1 / 3)


def test_observation_forms_and_identity_when_square():
    m = read(HEADER + "T: * identity\nO: x\n1 0\n0 1\n0.5 0.5\nO: y : a\n0.2 0.8\n"
             "O: y : b uniform\nO: y : c : o 1\nO: y : c : p 0\n")
    assert np.array_equal(m.dense_O[0], [[1, 0], [0, 1], [0.5, 0.5]])
    assert np.allclose(m.dense_O[1], [[0.2, 0.8], [0.5, 0.5], [1, 0]])
    square = read(HEADER.replace("observations: o p", "observations: a b c") +
                  "T: * identity\nO: * identity\n")
    assert square.fully_observable          # observations are the states, O the identity


def test_fully_observable_needs_the_same_names():
    m = read(HEADER.replace("observations: o p", "observations: u v w") +
             "T: * identity\nO: * identity\n")
    assert not m.fully_observable


# -- rewards -----------------------------------------------------------------------------------
def test_reward_forms_and_overrides():
    m = read(HEADER + BODY + "R: * : * : * : * -1\nR: x : a : * : * 5\nR: y : b : c : * 7\n"
             "R: y : c : c\n2 2\nR: y : a\n1 1\n2 2\n3 3\n")
    assert np.array_equal(m.R[0].toarray(), [[5, 5, 5], [-1, -1, -1], [-1, -1, -1]])
    assert np.array_equal(m.R[1].toarray(), [[1, 2, 3], [-1, -1, 7], [-1, -1, 2]])


def test_observation_dependent_rewards_are_folded_by_expectation():
    m = read(HEADER + "T: * identity\nO: * : *\n0.25 0.75\n"
             "R: x : * : * : o 4\nR: x : * : * : p 8\nR: y : a : a\n0 4\n")
    assert np.allclose(m.R[0].toarray(), 0.25 * 4 + 0.75 * 8)
    assert m.R[1][0, 0] == pytest.approx(3.0) and m.R[1][1, 1] == 0


def test_rewards_are_kept_where_the_transition_is_impossible_on_small_models():
    # A person typing an unlikely next state still gets the file's reward.
    m = read(HEADER + BODY + "R: x : a : b : * 9\n")
    assert m.T[0][0, 1] == 0 and m.R[0][0, 1] == 9


def test_keyword_names_in_headers_still_read():
    m = read("discount: 0.5\nstates: T R\nactions: O\nobservations: start\n"
             "T: O : T : R 1\nT: O : R : R 1\nO: O : * : start 1\nR: O : T : R : * 2\n")
    assert m.T[0][0, 1] == 1 and m.R[0][0, 1] == 2


# -- errors: each names the file and the line --------------------------------------------------------
@pytest.mark.parametrize("text, line, words", [
    (HEADER + "T: x : a\n0.5 -0.5 1\n", 7, "negative probability"),
    (HEADER + "T: * identity\nT: x : b\n0.5 0.4 0\nO: * uniform\n", 7, "sums to 0.9"),
    (HEADER.replace("0.9", "1.0") + BODY, 1, "outside [0, 1)"),
    (HEADER.replace("0.9", "-0.1") + BODY, 1, "outside [0, 1)"),
    (HEADER + "T: x : nowhere : a 1\n", 6, "unknown state 'nowhere'"),
    (HEADER + "T: zz identity\n", 6, "unknown action 'zz'"),
    (HEADER + BODY + "O: x : a : q 1\n", 8, "unknown observation 'q'"),
    (HEADER + "T: x : 7 : a 1\n", 6, "unknown state '7'"),
    (HEADER + "T: x : a\n0.5 0.5\nT: y identity\n", 6, "needs 3 numbers"),
    (HEADER + "T: x\n1 0 0\n0 1 0\n", 6, "needs 9 numbers"),
    (HEADER + BODY + "R: x : a\n1 2 3\n", 8, "needs 6 numbers"),
    (HEADER + "T: x : a\n0.5 0.5 zero\n", 7, "expected a number, found 'zero'"),
    (HEADER + "T: x : a : b 1.5\n", 6, "above 1"),
    (HEADER + "start: 0.5 0.6 0\n" + BODY, 6, "sum to 1.1"),
    (HEADER + "start: 0.5 0.5\n" + BODY, 6, "expects 3 probabilities"),
    (HEADER + "start exclude: a b c\n" + BODY, 6, "excludes every state"),
    ("discount: 0.9\nvalues: profit\n", 2, "'reward' or 'cost'"),
    ("discount: 0.9\nstates: a b a\n", 2, "appears twice"),
    ("discount: 0.9\ndiscount: 0.8\n", 2, "given twice"),
    ("hello world\ndiscount: 0.9\n", 1, "expected a statement"),
    ("discount: 0.9 0.8\n", 1, "expects one number, found 2"),
    ("discount: 0.9\nT: x identity\nstates: 2\n", 2, "before 'states:'"),
    (HEADER + "T: x : a : b : c 1\n", 6, "unexpected ':'"),
    (HEADER + "R: x\n1 2 3 4 5 6\n", 6, "at least an action and a start state"),
    (HEADER + "O: x identity\n", 6, "square table"),
    (HEADER + "T: x : a inf\n", 6, "non-finite"),
])
def test_each_error_names_the_file_line_and_problem(text, line, words):
    err = error_of(text)
    assert err.path == "test.pomdp"
    assert err.where == str(line), str(err)
    assert words in err.what, str(err)
    assert str(err).startswith(f"test.pomdp:{line}: ")


def test_a_row_never_given_is_reported_without_a_line():
    err = error_of(HEADER + "T: x identity\nO: * uniform\n")
    assert "T: y : a is never given" in err.what and err.where is None


def test_missing_declarations_are_reported():
    assert "no 'discount:' line" in error_of("states: 2\nactions: 1\nobservations: 1\n").what
    assert "no 'observations:' line" in error_of("discount: 0.5\nstates: 2\nactions: 1\n").what
    assert "empty" in error_of("# only a comment\n").what


def test_tolerance_is_1e_4_per_row():
    near = HEADER + "T: * identity\nT: x : a\n0.99995 0 0\nO: * uniform\n"
    assert read(near).T[0][0, 0] == 0.99995
    far = HEADER + "T: * identity\nT: x : a\n0.9998 0 0\nO: * uniform\n"
    assert "tolerance 0.0001" in error_of(far).what


def test_a_file_that_cannot_be_read_is_a_format_error(tmp_path):
    with pytest.raises(ModelFormatError) as info:
        cassandra.load(tmp_path / "missing.pomdp")
    assert "cannot read" in info.value.what


# -- writing ------------------------------------------------------------------------------------
def test_tiger_round_trips_exactly():
    m = cassandra.load(FIXTURES / "tiger.95.pomdp")
    back = read(cassandra.dump(m))
    assert differences(m, back) == []


def test_a_large_sparse_model_round_trips_entry_by_entry(tmp_path):
    rng = np.random.default_rng(3)
    S, A, Z = 40, 3, 5
    lines = [f"discount: 0.95\nstates: {S}\nactions: {A}\nobservations: {Z}\nstart: 0\n"]
    for a in range(A):
        for s in range(S):
            targets = rng.choice(S, 3, replace=False)
            p = rng.dirichlet(np.ones(3))
            p[-1] = 1 - p[:-1].sum()
            lines += [f"T: {a} : {s} : {t} {float(q)!r}" for t, q in zip(targets, p)]
            lines.append(f"O: {a} : {s}\n" + " ".join(repr(float(x)) for x in rng.dirichlet(np.ones(Z))))
            lines.append(f"R: {a} : {s} : * : * {float(rng.normal())!r}")
    m = read("\n".join(lines))
    text = cassandra.dump(m)
    assert "T: a0 : s0 : " in text            # too large for matrices: entries
    back = read(text)
    assert differences(m, back) == []
    cassandra.save(m, tmp_path / "big.pomdp")
    assert differences(m, cassandra.load(tmp_path / "big.pomdp")) == []


def test_start_is_written_in_its_shortest_exact_form():
    m = read(HEADER + "start include: a c\n" + BODY)
    assert "start include: a c" in cassandra.dump(m)
    m = read(HEADER + "start: 0.2 0.3 0.5\n" + BODY)
    text = cassandra.dump(m)
    assert "0.2 0.3 0.5" in text and np.array_equal(read(text).initial_belief, m.initial_belief)


def test_names_that_cannot_be_written_are_refused():
    m = read(HEADER + BODY)
    m.states[0] = "bad:name"
    with pytest.raises(ModelFormatError):
        cassandra.dump(m)


def test_layers_never_expand_identity_on_a_large_model():
    S = 3000
    m = read(f"discount: 0.9\nstates: {S}\nactions: 1\nobservations: 1\nT: * identity\n"
             "O: * uniform\nR: * : * : * : * -1\n")
    assert sp.issparse(m.T[0]) and m.T[0].nnz == S
    assert m.R[0].nnz == S                 # above 2000 states R is kept where T > 0
