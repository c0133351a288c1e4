"""The Bayes-adaptive core (ros_hrc.pomdp.bayes_adaptive, issue #40): expected counts by
forward-backward from a task's actions and observations alone, the Dirichlet posterior they
feed, its mean, its draws and its forgetting."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from solver_models import make_model
from ros_hrc.errors import ModelError
from ros_hrc.pomdp.bayes_adaptive import DirichletPosterior, LookBonus, expected_counts


def three_state_model(noise: float = 0.0):
    """Three states in a ring (s0 -> s1 -> s2 -> s0 under a0, a1 stays put, each move
    succeeding with 0.8), observations naming the state up to ``noise``."""
    S = 3
    T = np.zeros((2, S, S))
    for s in range(S):
        T[0, s, (s + 1) % S], T[0, s, s] = 0.8, 0.2
        T[1, s, s] = 1.0
    O = np.full((2, S, S), noise / (S - 1)) + np.eye(S)[None] * (1.0 - noise - noise / (S - 1))
    return make_model(T, O, np.zeros((2, S, S)), 0.9, [1.0, 0.0, 0.0])


def test_seen_states_give_the_counts_one_counts_by_hand():
    """Observations that name the state leave nothing hidden: the expected counts are the
    transitions one counts by hand."""
    model = three_state_model()
    # From s0: a0 -> s1, a0 -> s1 (stayed), a1 -> s1, a0 -> s2.
    steps = [(0, 1), (0, 1), (1, 1), (0, 2)]
    transitions, observations = expected_counts(model, steps)
    by_hand = np.zeros((2, 3, 3))
    by_hand[0, 0, 1] = 1
    by_hand[0, 1, 1] = 1
    by_hand[1, 1, 1] = 1
    by_hand[0, 1, 2] = 1
    assert np.allclose(transitions, by_hand)
    assert np.allclose(observations[0][:, [1, 2]].sum(axis=0), [2, 1])
    assert observations.sum() == pytest.approx(len(steps))


def brute_force_counts(model, steps, belief, end=None):
    """Expected counts by summing over every hidden path s_0 .. s_T (with ``end``, one more
    state: the end's, weighted by whether the end allows it)."""
    T, O = model.dense_T, model.dense_O
    S = model.n_states
    transitions = np.zeros_like(T)
    observations = np.zeros_like(O)
    total = 0.0
    length = len(steps) + 1 + (end is not None)
    for path in itertools.product(range(S), repeat=length):
        weight = belief[path[0]]
        for t, (a, o) in enumerate(steps, 1):
            weight *= T[a, path[t - 1], path[t]] * O[a, path[t], o]
        if end is not None:
            weight *= T[end[0], path[-2], path[-1]] * end[1][path[-1]]
        total += weight
        for t, (a, o) in enumerate(steps, 1):
            transitions[a, path[t - 1], path[t]] += weight
            observations[a, path[t], o] += weight
        if end is not None:
            transitions[end[0], path[-2], path[-1]] += weight
    return transitions / total, observations / total


def test_forward_backward_matches_every_path_summed():
    rng = np.random.default_rng(3)
    S, A, Z = 3, 2, 3
    model = make_model(rng.dirichlet(np.ones(S), size=(A, S)),
                       rng.dirichlet(np.ones(Z), size=(A, S)), np.zeros((A, S, S)), 0.9,
                       rng.dirichlet(np.ones(S)))
    steps = [(0, 2), (1, 0), (1, 1), (0, 0), (0, 2)]
    belief = rng.dirichlet(np.ones(S))
    transitions, observations = expected_counts(model, steps, belief)
    want_t, want_o = brute_force_counts(model, steps, belief)
    assert np.allclose(transitions, want_t, atol=1e-12)
    assert np.allclose(observations, want_o, atol=1e-12)


def test_a_tasks_end_is_counted_as_every_path_through_it_summed():
    """A task's ending (the robot's last action, and the states it could have ended in) is
    one more transition with no observation: the counts are those of every path that ends
    where the end allows, summed."""
    rng = np.random.default_rng(5)
    S, A, Z = 3, 2, 3
    model = make_model(rng.dirichlet(np.ones(S), size=(A, S)),
                       rng.dirichlet(np.ones(Z), size=(A, S)), np.zeros((A, S, S)), 0.9,
                       rng.dirichlet(np.ones(S)))
    steps = [(0, 2), (1, 0), (1, 1), (0, 0)]
    belief = rng.dirichlet(np.ones(S))
    for end in ((1, np.array([0.0, 0.0, 1.0])), (0, np.array([1.0, 1.0, 0.0]))):
        transitions, observations = expected_counts(model, steps, belief, end)
        want_t, want_o = brute_force_counts(model, steps, belief, end)
        assert np.allclose(transitions, want_t, atol=1e-12)
        assert np.allclose(observations, want_o, atol=1e-12)
        assert transitions.sum() == pytest.approx(len(steps) + 1)
        assert observations.sum() == pytest.approx(len(steps))


def test_a_success_after_the_robot_idled_is_counted_where_it_happened():
    """By hand: states seen exactly, then the task ends in s2 after a1 (which stays put)
    from s1 is impossible, so the end stands as the prediction; after a0 it is s1 -> s2."""
    model = three_state_model()
    transitions, _ = expected_counts(model, [(0, 1)], end=(0, np.array([0.0, 0.0, 1.0])))
    by_hand = np.zeros((2, 3, 3))
    by_hand[0, 0, 1] = 1
    by_hand[0, 1, 2] = 1
    assert np.allclose(transitions, by_hand)
    with pytest.raises(ModelError, match="end"):
        expected_counts(model, [(0, 1)], end=(5, np.ones(3)))


def test_an_observation_the_model_rules_out_leaves_its_step_to_the_prediction():
    model = three_state_model()
    # s0 cannot be seen after a0 from s0 leads to s1 or stays: o2 is impossible.
    transitions, _ = expected_counts(model, [(0, 2)])
    assert np.allclose(transitions[0, 0], [0.2, 0.8, 0.0])


def sample_task(true, rng, steps: int = 12):
    """A task in the true model: a uniformly random action each step; its (action,
    observation) pairs (the states stay hidden)."""
    T, O = true.dense_T, true.dense_O
    state = rng.choice(true.n_states, p=true.initial_belief)
    out = []
    for _ in range(steps):
        a = int(rng.integers(true.n_actions))
        state = rng.choice(true.n_states, p=T[a, state])
        out.append((a, int(rng.choice(true.n_observations, p=O[a, state]))))
    return out


def test_the_posterior_mean_learns_a_human_it_did_not_know():
    """A synthetic human drawn from a known model: the posterior mean's
    transition rows are within 0.05 (L1) of the true ones after 1,000 tasks, from a prior
    0.6 off (the sampling error alone is about 0.02 then)."""
    true = three_state_model(noise=0.05)
    T_prior = true.dense_T.copy()
    for s in range(3):       # the prior thinks a move succeeds half the time
        T_prior[0, s, (s + 1) % 3], T_prior[0, s, s] = 0.5, 0.5
    prior = make_model(T_prior, true.dense_O, np.zeros((2, 3, 3)), 0.9, [1.0, 0.0, 0.0])
    posterior = DirichletPosterior(prior, strength=5.0)
    rng = np.random.default_rng(8)
    assert np.abs(posterior.mean().dense_T - true.dense_T).sum(axis=2).max() > 0.5
    for _ in range(1000):
        posterior.learn(sample_task(true, rng))
    error = np.abs(posterior.mean().dense_T - true.dense_T).sum(axis=2).max()
    assert error < 0.05, error


def test_forgetting_moves_the_posterior_back_to_the_prior():
    model = three_state_model(noise=0.1)
    posterior = DirichletPosterior(model, strength=2.0, learn_observations=True)
    posterior.learn([(0, 1), (0, 2), (0, 0)])
    learnt = posterior.mean()
    assert not np.allclose(learnt.dense_T, model.dense_T)
    half = DirichletPosterior(model, 2.0, True, posterior.transitions.copy(),
                              posterior.observations.copy())
    half.forget(0.5)
    assert np.allclose(half.transitions, posterior.transitions / 2)
    posterior.forget(0.0)
    assert np.allclose(posterior.mean().dense_T, learnt.dense_T)
    posterior.forget(1.0)
    assert np.allclose(posterior.mean().dense_T, model.dense_T)
    assert np.allclose(posterior.mean().dense_O, model.dense_O)


def test_a_draw_keeps_the_priors_support_and_its_mean_is_the_posterior_mean():
    model = three_state_model()
    posterior = DirichletPosterior(model, strength=4.0)
    posterior.learn([(0, 1), (0, 2)])
    rng = np.random.default_rng(1)
    draws = [posterior.sample(rng).dense_T for _ in range(2000)]
    assert all(np.all(d[model.dense_T == 0] == 0) for d in draws)
    assert np.allclose(np.mean(draws, axis=0), posterior.mean().dense_T, atol=0.02)


@pytest.mark.parametrize("strength", [0, -1, float("nan"), "x"])
def test_a_strength_not_above_zero_is_refused(strength):
    with pytest.raises(ValueError, match="strength must be"):
        DirichletPosterior(three_state_model(), strength=strength)


@pytest.mark.parametrize("rate", [-0.1, 1.5, "x"])
def test_a_forgetting_rate_outside_zero_to_one_is_refused(rate):
    posterior = DirichletPosterior(three_state_model(), strength=1.0)
    with pytest.raises(ValueError, match="forgetting rate must be"):
        posterior.forget(rate)


def test_steps_outside_the_model_are_refused():
    with pytest.raises(ModelError, match="outside the model"):
        expected_counts(three_state_model(), [(0, 7)])


def test_the_exploration_bonus_falls_as_its_action_is_seen_and_as_this_task_looks():
    """scale / (1 + n(s) + m(s)): n(s) the counts learnt of the action in s before the task,
    m(s) the belief in s at each of this task's decisions that took it; the models a planner
    gets keep the prior's rewards."""
    model = three_state_model()
    posterior = DirichletPosterior(model, strength=4.0)
    posterior.learn([(1, 0), (1, 0), (1, 0)])                      # a1 taken in s0 three times
    assert np.allclose(posterior.times_seen(1), [3.0, 0.0, 0.0])
    bonus = LookBonus(2.0, 1, posterior.times_seen(1))
    assert np.allclose(bonus.per_state(), [2.0 / 4, 2.0, 2.0])
    bonus.looked([0.0, 0.5, 0.5])                                  # one look, s1 or s2
    assert np.allclose(bonus.per_state(), [2.0 / 4, 2.0 / 1.5, 2.0 / 1.5])
    posterior.forget(1.0)                                          # forgotten: seen no more
    assert np.allclose(posterior.times_seen(1), 0.0)
    for planned in (posterior.mean(), posterior.sample(np.random.default_rng(2))):
        assert all((a != b).nnz == 0 for a, b in zip(planned.R, model.R))


@pytest.mark.parametrize("bonus", [-1.0, float("nan"), float("inf"), "x"])
def test_a_bad_exploration_bonus_is_refused_in_one_line(bonus):
    with pytest.raises(ValueError) as caught:
        LookBonus(bonus, 0, np.zeros(3))
    assert "the exploration bonus must be" in str(caught.value)
