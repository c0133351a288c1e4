"""Fitting T and O to labelled experience with a model as a Dirichlet prior (``hrc_fit``'s core).

Recovery tolerance, derived: a row sampled n times estimates each probability by a frequency
whose standard deviation is sqrt(p(1-p)/n) <= 0.5/sqrt(n). Every row here gets at least
N_MIN = 10,000 samples (asserted), so sd <= 0.005 and 5 sd = 0.025; the weak prior (uniform,
strength 1) moves a row by at most 1/(N_MIN + 1) = 0.0001 more. TOLERANCE = 0.03 on
max |fitted - true| over every cell of T and O is thus beyond 5 sd for each of the (at most 36)
estimated rows; and the seed is fixed, so the test is deterministic anyway.
"""
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from solver_models import build_chain, build_tiger, make_model
from ros_hrc.errors import ModelError
from ros_hrc.pomdp import cassandra
from ros_hrc.pomdp.fit import (ExperienceCounts, fit_header, fit_model, fitted_text, row_support,
                               sample_experience, support_lines, uniform_policy, write_fitted)
from ros_hrc.pomdp.io import differences, load_model

ROOT = Path(__file__).resolve().parents[3]

N_MIN = 10_000
TOLERANCE = 0.03
EPISODES, STEPS = 400, 250            # 100,000 steps


def random_model(seed: int = 7, S: int = 3, A: int = 2, Z: int = 3):
    """A random POMDP with full rows (Dirichlet(8) rows of T keep every state often visited)."""
    rng = np.random.default_rng(seed)
    T = rng.dirichlet(np.full(S, 8.0), size=(A, S))
    O = rng.dirichlet(np.full(Z, 3.0), size=(A, S))
    R = rng.normal(size=(A, S, S)).round(3)
    return make_model(T, O, R, 0.9, rng.dirichlet(np.ones(S)), name="random")


def uniform_like(model):
    """A model with ``model``'s names and rewards and uniform T and O: a prior knowing nothing."""
    A, S, Z = model.n_actions, model.n_states, model.n_observations
    R = np.stack([r.toarray() for r in model.R])
    return make_model(np.full((A, S, S), 1.0 / S), np.full((A, S, Z), 1.0 / Z), R,
                      model.discount, model.initial_belief, states=model.states,
                      actions=model.actions, observations=model.observations, name="uniform")


_SAMPLES = {}


def sampled(which: str):
    """The true model and 100,000 steps of uniform exploration in it (computed once)."""
    if which not in _SAMPLES:
        true = random_model() if which == "random" else build_tiger()
        counts = sample_experience(true, uniform_policy(true.n_actions), EPISODES, STEPS, seed=11)
        _SAMPLES[which] = (true, counts)
    return _SAMPLES[which]


def max_errors(fitted, true):
    return (float(np.abs(fitted.dense_T - true.dense_T).max()),
            float(np.abs(fitted.dense_O - true.dense_O).max()))


# -- recovery ----------------------------------------------------------------------------------
@pytest.mark.parametrize("which", ["random", "tiger"])
def test_fitting_recovers_the_true_t_and_o_within_the_stated_tolerance(which):
    true, counts = sampled(which)
    assert counts.n_transitions == counts.n_observations_counted == EPISODES * STEPS
    assert row_support(counts).weakest() >= N_MIN
    fitted = fit_model(uniform_like(true), counts, strength=1.0)
    t_err, o_err = max_errors(fitted, true)
    assert t_err <= TOLERANCE and o_err <= TOLERANCE, (t_err, o_err)
    # and the uniform prior was far from the truth, so the data did the work
    prior_t, prior_o = max_errors(uniform_like(true), true)
    assert max(prior_t, prior_o) > 3 * TOLERANCE


def test_sampling_is_deterministic_given_the_seed():
    true = random_model()
    policy = uniform_policy(true.n_actions)
    a = sample_experience(true, policy, 20, 50, seed=5)
    b = sample_experience(true, policy, 20, 50, seed=5)
    c = sample_experience(true, policy, 20, 50, seed=6)
    assert a == b and a != c
    assert a.n_transitions == 1000
    fa, fb = fit_model(true, a, 2.0), fit_model(true, b, 2.0)
    assert differences(fa, fb) == []


def test_sampling_counts_every_step_and_reports_progress():
    true = random_model()
    seen = []
    counts = sample_experience(true, uniform_policy(2), 3, 7, seed=0, progress=seen.append)
    assert seen == [1, 2, 3]
    assert counts.n_transitions == counts.n_observations_counted == 21
    # the observation counts of (a, s') equal the transitions into s' by a
    assert np.array_equal(counts.observations.sum(axis=2), counts.transitions.sum(axis=1))
    assert sample_experience(true, uniform_policy(2), 0, 7, seed=0).n_transitions == 0


def test_sampling_follows_the_policy():
    true = random_model()
    counts = sample_experience(true, lambda rng, step: 1, 5, 10, seed=0)
    assert counts.transitions[0].sum() == 0 and counts.transitions[1].sum() == 50


@pytest.mark.parametrize("bad", [2, -1, 1.0, "a0", None])
def test_a_policy_choosing_no_action_index_is_refused(bad):
    with pytest.raises(ModelError, match="not an action index"):
        sample_experience(random_model(), lambda rng, step: bad, 1, 3, seed=0)


# -- the posterior -----------------------------------------------------------------------------
def test_the_posterior_mean_by_hand():
    prior = build_tiger()                         # T[open-left] rows are (0.5, 0.5)
    counts = ExperienceCounts.for_model(prior)
    counts.transitions[1, 0] = [3, 1]
    counts.observations[0, 1] = [0, 4]            # O[listen][tiger-right] is (0.15, 0.85)
    fitted = fit_model(prior, counts, strength=2.0)
    assert fitted.dense_T[1, 0] == pytest.approx([(1 + 3) / 6, (1 + 1) / 6], abs=1e-15)
    assert fitted.dense_O[0, 1] == pytest.approx([0.3 / 6, (1.7 + 4) / 6], abs=1e-15)


def test_a_large_strength_keeps_the_prior():
    true, counts = sampled("random")
    prior = uniform_like(true)
    fitted = fit_model(prior, counts, strength=1e12)
    t_err, o_err = max_errors(fitted, prior)
    assert t_err < 1e-6 and o_err < 1e-6


def test_strength_zero_gives_the_frequencies_exactly():
    true, counts = sampled("random")
    fitted = fit_model(uniform_like(true), counts, strength=0)
    n_t, n_o = counts.transitions.astype(float), counts.observations.astype(float)
    assert np.array_equal(fitted.dense_T, n_t / n_t.sum(axis=2, keepdims=True))
    assert np.array_equal(fitted.dense_O, n_o / n_o.sum(axis=2, keepdims=True))


@pytest.mark.parametrize("strength", [0, 1, 50])
def test_rows_without_counts_keep_the_prior_exactly(strength):
    prior = random_model(seed=3)
    counts = ExperienceCounts.for_model(prior)
    counts.add_step(0, 1, 2, 0)                   # only T[a1][s0] and O[a1][s2] have counts
    fitted = fit_model(prior, counts, strength)
    for a in range(2):
        for s in range(3):
            t_same = np.array_equal(fitted.dense_T[a, s], prior.dense_T[a, s])
            o_same = np.array_equal(fitted.dense_O[a, s], prior.dense_O[a, s])
            assert t_same == ((a, s) != (1, 0))
            assert o_same == ((a, s) != (1, 2))


def test_no_counts_at_all_give_back_the_prior_bit_for_bit():
    for path in (ROOT / "test/fixtures/tiger.95.pomdp", ROOT / "models/human/beginner.pomdpx"):
        prior = load_model(path)
        fitted = fit_model(prior, ExperienceCounts.for_model(prior), strength=0)
        assert differences(fitted, prior) == []


def test_rewards_and_everything_but_t_and_o_are_the_priors():
    true, counts = sampled("random")
    prior = uniform_like(true)
    prior.minimise = True
    before = [r.copy() for r in prior.T]
    fitted = fit_model(prior, counts, strength=1.0, name="mine")
    assert fitted.name == "mine"
    assert fit_model(prior, counts, 1.0).name == "uniform-fitted"
    assert (fitted.states, fitted.actions, fitted.observations) == \
        (prior.states, prior.actions, prior.observations)
    assert fitted.discount == prior.discount and fitted.minimise
    assert np.array_equal(fitted.initial_belief, prior.initial_belief)
    for a in range(prior.n_actions):
        assert (fitted.R[a] != prior.R[a]).nnz == 0
        assert (prior.T[a] != before[a]).nnz == 0          # the prior is not modified
    assert fitted.meta["fit"] == {"prior": "uniform", "strength": 1.0,
                                  "transitions": 100_000, "observations": 100_000}
    fitted.validate(tolerance=1e-12)                       # rows are exact distributions


def test_a_fully_observable_prior_stays_so_while_o_keeps_its_support():
    chain = build_chain()
    counts = ExperienceCounts.for_model(chain)
    counts.add_step(0, 1, 1, 1)                            # o = s': the identity again
    kept = fit_model(chain, counts, 1.0)
    assert kept.fully_observable and np.array_equal(kept.observed_key, np.arange(4))
    counts.add_observation(1, 1, 2)                        # o != s'
    lost = fit_model(chain, counts, 0.0)
    assert not lost.fully_observable and lost.observed_key is None


def test_a_human_model_fitted_to_its_own_kind_of_experience_stays_an_mdp():
    human = load_model(ROOT / "models/human/beginner.pomdpx")
    assert human.fully_observable
    counts = sample_experience(human, uniform_policy(human.n_actions), 20, 30, seed=2)
    fitted = fit_model(human, counts, strength=5.0)
    assert fitted.fully_observable
    assert np.array_equal(fitted.observed_key, human.observed_key)
    assert np.array_equal(fitted.dense_O, human.dense_O)


# -- refusals ----------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [-1, -1e-9, float("nan"), float("inf"), "strong", None])
def test_a_bad_strength_is_refused(bad):
    prior = build_tiger()
    with pytest.raises(ValueError, match="strength"):
        fit_model(prior, ExperienceCounts.for_model(prior), bad)
    with pytest.raises(ValueError, match="strength"):
        fit_header(bad, ExperienceCounts.for_model(prior))


def test_counts_of_other_sizes_are_refused():
    with pytest.raises(ModelError, match="counts are for 3 actions, 2 states and 2 observations"):
        fit_model(random_model(), ExperienceCounts.for_model(build_tiger()), 1.0)


@pytest.mark.parametrize("transitions, observations, message", [
    (np.zeros((2, 3, 4)), np.zeros((2, 3, 3)), "shape"),
    (np.zeros((2, 3, 3)), np.zeros((2, 4, 3)), "shape"),
    (np.full((2, 3, 3), -1), np.zeros((2, 3, 3)), "negative"),
    (np.full((2, 3, 3), np.nan), np.zeros((2, 3, 3)), "NaN"),
    (np.zeros((2, 3, 3)), np.full((2, 3, 3), 0.5), "whole"),
])
def test_malformed_counts_are_refused(transitions, observations, message):
    with pytest.raises(ModelError, match=message):
        ExperienceCounts(transitions, observations)


# -- counting ----------------------------------------------------------------------------------
def test_counts_by_index_and_by_name_and_merging():
    tiger = build_tiger()
    a = ExperienceCounts.for_model(tiger)
    assert a.shape == (3, 2, 2) and a.transitions.dtype == np.int64
    a.add_transition(0, 0, 0)
    a.add_observation("listen", "tiger-left", "tiger-right", model=tiger)
    b = ExperienceCounts.from_steps(tiger, [("tiger-left", "open-left", "tiger-right",
                                             "tiger-left"), (1, 2, 0, 0)])
    assert b.transitions[1, 0, 1] == 1 and b.observations[1, 1, 0] == 1
    assert b.transitions[2, 1, 0] == 1 and b.observations[2, 0, 0] == 1
    total = a + b
    assert total.n_transitions == 3 and total.n_observations_counted == 3
    assert a.n_transitions == 1                            # + makes a new object
    a += b
    assert a == total
    with pytest.raises(ModelError, match="cannot merge"):
        a += ExperienceCounts.for_model(random_model())


@pytest.mark.parametrize("call, message", [
    (lambda c, m: c.add_transition(2, 0, 0), "outside"),
    (lambda c, m: c.add_transition(-1, 0, 0), "outside"),
    (lambda c, m: c.add_observation(0, 0, 2), "outside"),
    (lambda c, m: c.add_transition("tiger-left", 0, 0), "pass the model"),
    (lambda c, m: c.add_transition("tiger-middle", 0, 0, model=m), "unknown state"),
    (lambda c, m: c.add_observation(0, 0, 0.0), "neither an index nor a name"),
])
def test_bad_labels_are_refused(call, message):
    tiger = build_tiger()
    counts = ExperienceCounts.for_model(tiger)
    with pytest.raises(ModelError, match=message):
        call(counts, tiger)
    assert counts.n_transitions == counts.n_observations_counted == 0


def test_row_support_and_the_report():
    tiger = build_tiger()
    counts = ExperienceCounts.for_model(tiger)
    for _ in range(5):
        counts.add_step("tiger-left", "listen", "tiger-left", "tiger-left", model=tiger)
    support = row_support(counts)
    assert support.transitions.tolist() == [[5, 0], [0, 0], [0, 0]]
    assert support.observations.tolist() == [[5, 0], [0, 0], [0, 0]]
    assert support.weakest() == 0
    lines = support_lines(tiger, counts, minimum=3)
    assert lines[0].startswith("5 transitions, 5 observations; rows with fewer than 3")
    assert "  T: listen : tiger-right  0 sample(s)" in lines
    assert not any("T: listen : tiger-left " in line for line in lines)
    assert len(lines) == 1 + 5 + 5
    assert support_lines(tiger, counts, minimum=0) == [
        "5 transitions, 5 observations; every row has at least 0 samples"]


# -- the written file --------------------------------------------------------------------------
def test_the_written_file_starts_with_the_header_and_reads_back_equal(tmp_path):
    true, counts = sampled("random")
    fitted = fit_model(uniform_like(true), counts, strength=1.0)
    header = fit_header(1.0, counts, prior="uniform.pomdp", models=["expert", "tired"],
                        episodes=EPISODES, seed=11)
    path = tmp_path / "fitted.pomdp"
    write_fitted(fitted, path, header)
    text = path.read_text()
    assert text.splitlines()[:len(header)] == [f"# {line}" for line in header]
    assert "# models: expert tired" in text and "# seed: 11" in text
    assert "# strength: 1 pseudo-counts per row" in text
    assert "# counts: 100000 transitions, 100000 observations" in text
    back = cassandra.load(path)
    for label in ("T", "O", "R"):
        for a in range(fitted.n_actions):
            delta = abs(getattr(back, label)[a] - getattr(fitted, label)[a])
            assert delta.max() <= 1e-6 if delta.nnz else True
    assert differences(back, fitted) == []                 # in fact bit for bit
    assert [p.name for p in tmp_path.iterdir()] == ["fitted.pomdp"]   # no temporary left


def test_header_lines_of_several_lines_stay_comments():
    tiger = build_tiger()
    text = fitted_text(tiger, ["made by hand", "two\nlines", ""])
    assert text.startswith("# made by hand\n# two\n# lines\n#\n# tiger: written by ros_hrc")
    assert differences(cassandra.loads(text), tiger) == []
    assert fitted_text(tiger, []) == cassandra.dump(tiger)
