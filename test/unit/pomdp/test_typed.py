"""The type-augmented POMDP (ros_hrc.pomdp.typed): one model per type composed into one whose
hidden state is (type, state)."""
import dataclasses
import re

import numpy as np
import pytest
import scipy.sparse as sp

from ros_hrc.errors import ModelError
from ros_hrc.pomdp.belief import update
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.type_names import split_state, typed_state
from ros_hrc.pomdp.typed import TypeLayout, compose
from solver_models import build_tiger


def tiger_hearing(accuracy: float) -> Model:
    """Tiger whose listener hears the right side with ``accuracy``: a type of listener."""
    model = build_tiger()
    hear = sp.csr_matrix(np.array([[accuracy, 1 - accuracy], [1 - accuracy, accuracy]]))
    return dataclasses.replace(model, O=[hear, *model.O[1:]], name=f"tiger{accuracy}")


@pytest.fixture
def listeners():
    return {"sharp": tiger_hearing(0.9), "deaf": tiger_hearing(0.5)}


def test_every_row_of_the_composed_model_sums_to_one(listeners):
    model = compose(listeners, [0.25, 0.75])
    model.validate()
    for a in range(model.n_actions):
        assert np.allclose(np.asarray(model.T[a].sum(axis=1)).ravel(), 1.0)
        assert np.allclose(np.asarray(model.O[a].sum(axis=1)).ravel(), 1.0)
    assert model.initial_belief.sum() == pytest.approx(1.0)
    assert model.states == ["tiger-left__sharp", "tiger-right__sharp",
                            "tiger-left__deaf", "tiger-right__deaf"]
    assert TypeLayout.of(model).type_marginal(model.initial_belief) == pytest.approx([0.25, 0.75])


def test_no_transition_leaves_a_type(listeners):
    model = compose(listeners)
    for a in range(model.n_actions):
        T = model.T[a].toarray()
        assert np.all(T[:2, 2:] == 0) and np.all(T[2:, :2] == 0)


def test_with_one_type_it_is_that_types_model_renamed():
    tiger = build_tiger()
    model = compose({"only": tiger})
    assert model.states == [typed_state(s, "only") for s in tiger.states]
    assert model.actions == tiger.actions and model.observations == tiger.observations
    assert model.discount == tiger.discount
    assert np.array_equal(model.initial_belief, tiger.initial_belief)
    for a in range(tiger.n_actions):
        for table in ("T", "O", "R"):
            assert np.array_equal(getattr(model, table)[a].toarray(),
                                  getattr(tiger, table)[a].toarray()), table


def test_a_belief_fed_one_types_observations_settles_on_that_type(listeners):
    """A pinned seeded case: the tiger sits left and the sharp listener hears it; after a few
    listens the belief puts most of its weight on the sharp type."""
    model = compose(listeners)
    layout = TypeLayout.of(model)
    rng = np.random.default_rng(7)
    sharp = listeners["sharp"]
    listen = model.index("action", "listen")
    b = model.initial_belief.copy()
    history = []
    for _ in range(6):
        o = int(rng.choice(2, p=sharp.O[listen].toarray()[0]))   # the tiger is left
        b, _ = update(model, b, listen, o)
        history.append(layout.type_marginal(b)[0])
    assert history[-1] > 0.8, history
    assert layout.state_marginal(b)[0] > 0.9       # and where the tiger is


def test_a_prior_carried_over_keeps_each_types_start(listeners):
    model = compose(listeners)
    layout = TypeLayout.of(model)
    carried = layout.with_type_prior(model.initial_belief, [0.9, 0.1])
    assert layout.type_marginal(carried) == pytest.approx([0.9, 0.1])
    assert layout.blocks(carried)[0] == pytest.approx([0.45, 0.45])
    with pytest.raises(ValueError, match="2 probabilities summing to 1"):
        layout.with_type_prior(model.initial_belief, [0.9, 0.2])


def test_names_split_and_models_of_no_type_have_no_layout():
    assert split_state("S3__tired") == ("S3", "tired")
    assert split_state("S3") is None and split_state("__x") is None
    assert TypeLayout.of(build_tiger()) is None
    assert TypeLayout.of_names(["a__x", "b__x", "a__y"]) is None     # not every pair


def test_models_that_do_not_share_their_names_are_refused(listeners):
    other = dataclasses.replace(build_tiger(), actions=["listen", "left", "right"])
    with pytest.raises(ModelError, match="type odd: its actions are not type sharp's"):
        compose({"sharp": listeners["sharp"], "odd": other})
    for bad in ("a@b", "a__b", "_a", "a-b", ""):     # the separator, or outside a file's names
        with pytest.raises(ModelError, match=f"type name '{bad}' must be letters and digits"):
            compose({bad: build_tiger()})


def test_composed_names_are_names_cassandras_grammar_allows(listeners):
    """SARSOP's pomdpsol reads only [a-zA-Z][a-zA-Z0-9_-]* (it refused S3@tired)."""
    model = compose({"expert_tired": listeners["sharp"], "deaf2": listeners["deaf"]})
    assert all(re.fullmatch(r"[a-zA-Z][a-zA-Z0-9_-]*", s) for s in model.states)
    assert split_state("tiger-left__expert_tired") == ("tiger-left", "expert_tired")
    assert TypeLayout.of(model).types == ("expert_tired", "deaf2")


@pytest.mark.parametrize("true_type", ["early_warner", "tired", "distracted", "beginner"])
def test_the_shipped_seed_model_of_types_finds_a_type_from_its_observations(true_type):
    """A pinned seeded case on the real composed model (models/robot/robot_types.pomdp, the
    zoo's fit set): a human of ``true_type`` (its own fitted block: its start, its T and O),
    the robot idle; within five observations the belief puts most of its weight on that type,
    from a uniform 1/8."""
    from ros_hrc.models import load_robot_model
    model = load_robot_model("robot_types", "seed")
    layout = TypeLayout.of(model)
    k = layout.types.index(true_type)
    n = len(layout.states)
    T, O = model.dense_T, model.dense_O
    idle = model.index("action", "rIdle")
    rng = np.random.default_rng(0)
    state = k * n + int(np.argmax(layout.blocks(model.initial_belief)[k]))
    b = model.initial_belief.copy()
    history = []
    for _ in range(5):
        state = int(rng.choice(model.n_states, p=T[idle, state]))
        assert state // n == k                                  # the human stays his type
        o = int(rng.choice(model.n_observations, p=O[idle, state]))
        b, _ = update(model, b, idle, o)
        history.append(round(float(layout.type_marginal(b)[k]), 3))
    assert history[-1] > 0.5, history
    assert int(np.argmax(layout.type_marginal(b))) == k, history
