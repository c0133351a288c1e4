"""The human zoo (ros_hrc.experiment.zoo): every model loads and fits the task; the fit and
held-out sets are disjoint, cover every human model but the listed variants, and each spans
the kinds (succeeds alone, sometimes, never; warns the robot)."""
import numpy as np
import pytest

from ros_hrc.experiment.zoo import NOT_IN_ZOO, ZOO, ZOO_FIT, ZOO_HELD_OUT, zoo_argument
from ros_hrc.models import load_human_model
from ros_hrc.model_files import MODELS_DIR
from ros_hrc.pomdp.mdp import value_iteration

STEP_LIMIT = 15          # hrc_experiment's default --step-limit


def alone(name: str, steps: int = STEP_LIMIT):
    """(P(success within ``steps`` steps), P(warns within them)) of the human's optimal policy."""
    m = load_human_model(name)
    policy = value_iteration(m).policy
    P = np.array([m.dense_T[policy[s]][s] for s in range(m.n_states)])
    warn_action = m.actions.index("warnRobot")
    b = m.initial_belief.copy()
    warns = 0.0
    for _ in range(steps):
        warns = max(warns, float(sum(b[s] for s in range(m.n_states) if policy[s] == warn_action)))
        b = b @ P
    return float(b[m.states.index("success")]), warns


@pytest.mark.parametrize("name", ZOO)
def test_every_zoo_human_loads_and_passes_the_tasks_model_checks(name):
    m = load_human_model(name)
    assert m.fully_observable and m.n_states == 8


def test_the_split_is_disjoint_and_covers_every_human_model():
    assert not set(ZOO_FIT) & set(ZOO_HELD_OUT)
    assert len(set(ZOO)) == len(ZOO) == len(ZOO_FIT) + len(ZOO_HELD_OUT)
    shipped = {p.stem for p in (MODELS_DIR / "human").glob("*.pomdpx")}
    assert set(ZOO) | set(NOT_IN_ZOO) == shipped
    assert not set(ZOO) & set(NOT_IN_ZOO)


def test_the_zoo_has_at_least_eight_new_humans_and_keeps_the_old_ones():
    old = {"humanModel", "evaluating", "beginner", "tired", "distracted", "expert"}
    assert old <= set(ZOO)
    assert len(set(ZOO) - old) >= 8


@pytest.mark.parametrize("which", [ZOO_FIT, ZOO_HELD_OUT])
def test_each_set_spans_succeeds_alone_to_never_and_has_a_warner(which):
    results = {name: alone(name) for name in which}
    success = [s for s, _ in results.values()]
    assert max(success) > 0.99 and min(success) == 0.0
    assert any(0.3 < s < 0.95 for s in success)
    assert any(w > 0.2 for _, w in results.values())


def test_the_held_out_set_holds_the_four_kinds_the_issue_names():
    assert {"deliberator", "persistent_failer", "looks_away_first", "tires_late"} <= set(ZOO_HELD_OUT)


def test_zoo_argument_is_what_human_models_takes():
    assert zoo_argument("fit").split(",") == list(ZOO_FIT)
    assert zoo_argument().split(",") == list(ZOO)
    with pytest.raises(ValueError, match="unknown zoo set"):
        zoo_argument("train")
