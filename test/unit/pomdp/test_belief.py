"""Exact and particle beliefs, and the generative sampler they share."""
import numpy as np
import pytest

from solver_models import build_chain
from ros_hrc.errors import SolverError, ZeroProbabilityObservation
from ros_hrc.pomdp import belief
from ros_hrc.pomdp.belief import ExactBelief, ParticleBelief
from ros_hrc.pomdp.sampling import ModelSampler

LISTEN, OPEN_LEFT = 0, 1
HEAR_LEFT, HEAR_RIGHT = 0, 1


def test_listening_once_follows_bayes_rule(tiger):
    b, p_o = belief.update(tiger, np.array([0.5, 0.5]), LISTEN, HEAR_LEFT)
    assert np.allclose(b, [0.85, 0.15])
    assert p_o == pytest.approx(0.5)


def test_two_consistent_listens_give_the_textbook_belief(tiger):
    b, _ = belief.update(tiger, np.array([0.5, 0.5]), LISTEN, HEAR_LEFT)
    b, p_o = belief.update(tiger, b, LISTEN, HEAR_LEFT)
    assert b[0] == pytest.approx(0.85 ** 2 / (0.85 ** 2 + 0.15 ** 2))
    assert p_o == pytest.approx(0.85 * 0.85 + 0.15 * 0.15)


def test_opening_a_door_resets_the_belief(tiger):
    b, p_o = belief.update(tiger, np.array([0.97, 0.03]), OPEN_LEFT, HEAR_RIGHT)
    assert np.allclose(b, [0.5, 0.5]) and p_o == pytest.approx(0.5)


def test_zero_probability_observation_raises_the_specific_error():
    chain = build_chain(4)
    with pytest.raises(ZeroProbabilityObservation) as err:
        belief.update(chain, np.array([1.0, 0, 0, 0]), 0, 3)   # stay in s0, "see" s3
    assert isinstance(err.value, SolverError)
    assert err.value.action == 0 and err.value.observation == 3


def test_exact_belief_is_unchanged_by_an_impossible_observation_and_can_predict():
    chain = build_chain(4)
    b = ExactBelief(chain)
    with pytest.raises(ZeroProbabilityObservation):
        b.update(1, 3)
    assert np.allclose(b.probabilities(), [1, 0, 0, 0])
    b.predict(1)                                   # the fallback: through T only
    assert np.allclose(b.probabilities(), [0, 1, 0, 0])


def test_out_of_range_indices_and_bad_beliefs_are_refused(tiger):
    with pytest.raises(SolverError):
        belief.update(tiger, np.array([0.5, 0.5]), 7, 0)
    with pytest.raises(SolverError):
        ExactBelief(tiger, np.array([-1.0, 2.0]))
    with pytest.raises(SolverError):
        ExactBelief(tiger, np.array([1.0, 0.0, 0.0]))


def test_particle_belief_tracks_the_exact_belief(tiger):
    rng = np.random.default_rng(3)
    particles = ParticleBelief(tiger, 20000, rng)
    exact = ExactBelief(tiger)
    for o in (HEAR_LEFT, HEAR_LEFT, HEAR_RIGHT, HEAR_LEFT):
        particles.update(LISTEN, o)
        exact.update(LISTEN, o)
    assert np.allclose(particles.probabilities(), exact.probabilities(), atol=0.02)
    assert particles.probabilities().sum() == pytest.approx(1.0)


def test_particle_belief_is_reproducible_from_its_seed(tiger):
    def run(seed):
        b = ParticleBelief(tiger, 500, np.random.default_rng(seed))
        for o in (HEAR_LEFT, HEAR_RIGHT, HEAR_LEFT):
            b.update(LISTEN, o)
        return b.probabilities()
    assert np.array_equal(run(11), run(11))


def test_particle_belief_resamples_when_weights_degenerate(tiger):
    b = ParticleBelief(tiger, 1000, np.random.default_rng(0))
    for _ in range(6):
        b.update(LISTEN, HEAR_LEFT)
    # Listening moves no particle: only resampling can make the particles themselves (not just
    # their weights) concentrate on tiger-left.
    assert np.mean(b.states == 0) > 0.9
    assert b.probabilities()[0] > 0.99


def test_particle_belief_raises_when_no_particle_explains_the_observation():
    chain = build_chain(4)
    b = ParticleBelief(chain, 100, np.random.default_rng(0))
    with pytest.raises(ZeroProbabilityObservation):
        b.update(0, 2)
    b.predict(1)
    assert np.all(b.states == 1)


def test_sampler_draws_transitions_with_the_model_frequencies(tiger):
    sampler = ModelSampler(tiger)
    rng = np.random.default_rng(5)
    n = 40000
    states = np.zeros(n, dtype=np.int64)               # tiger-left
    nxt, obs, rew = sampler.step(states, LISTEN, rng.random(n), rng.random(n))
    assert np.all(nxt == 0) and np.all(rew == -1.0)
    assert np.mean(obs == HEAR_LEFT) == pytest.approx(0.85, abs=0.01)
    nxt, obs, rew = sampler.step(states, OPEN_LEFT, rng.random(n), rng.random(n))
    assert np.mean(nxt == 0) == pytest.approx(0.5, abs=0.01)
    assert np.all(rew == -100.0)


def test_sampler_scalar_and_vector_steps_agree(tiger):
    sampler = ModelSampler(tiger)
    rng = np.random.default_rng(9)
    for _ in range(200):
        s, a, u1, u2 = int(rng.integers(2)), int(rng.integers(3)), rng.random(), rng.random()
        nxt, obs, rew = sampler.step(np.array([s]), a, np.array([u1]), np.array([u2]))
        assert (int(nxt[0]), int(obs[0]), float(rew[0])) == sampler.step1(s, a, u1, u2)


def test_sampler_same_uniforms_give_the_same_outcome(tiger):
    sampler = ModelSampler(tiger)
    u = np.random.default_rng(1).random((2, 50))
    s = np.zeros(50, dtype=np.int64)
    first = sampler.step(s, OPEN_LEFT, u[0], u[1])
    second = sampler.step(s, OPEN_LEFT, u[0], u[1])
    assert all(np.array_equal(x, y) for x, y in zip(first, second))
