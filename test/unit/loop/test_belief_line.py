"""The step block's ``robot belief`` line fits a terminal (issue #41, newcomer item 7): a
model of many states (fabric's eleven: about 230 characters in the model's order) shows its
most likely states first and sums the rest; one whose states all fit is shown whole, in its
order."""
import pytest

from ros_hrc import tasks
from ros_hrc.loop.display import BELIEF_LINE_WIDTH, belief_text

FABRIC = tasks.get("fabric").robot_states
#: A fabric belief as a task's step shows one: most of it on two states, a little on many.
FABRIC_BELIEF = [0.01, 0.05, 0.201, 0.02, 0.03, 0.612, 0.04, 0.012, 0.01, 0.005, 0.01]


def test_fabric_s_belief_fits_with_the_most_likely_first_and_the_rest_summed():
    text = belief_text(FABRIC, FABRIC_BELIEF)
    assert len(text) <= BELIEF_LINE_WIDTH == 60
    assert text == "NeedsHelp 0.612 | MayBeTired 0.201 | +9 others 0.187"
    shown = text.split(" | ")
    others = shown[-1]
    assert others.startswith(f"+{len(FABRIC) - len(shown) + 1} others ")
    listed = sum(float(item.split()[-1]) for item in shown[:-1])
    assert listed + float(others.split()[-1]) == pytest.approx(sum(FABRIC_BELIEF), abs=2e-3)


def test_a_belief_that_fits_is_shown_whole_in_the_model_s_order():
    assert belief_text(["S0", "S1", "S2"], [0.2, 0.0, 0.8]) == "S0 0.200 | S1 0.000 | S2 0.800"


def test_states_that_would_show_as_zero_are_only_summed():
    seed = ["S0", "S1", "S2", "S3", "S4", "S5", "S6"]
    assert belief_text(seed, [0.0, 0.0, 0.429, 0.571, 0.0, 0.0, 0.0]) == \
        "S3 0.571 | S2 0.429 | +5 others 0.000"
    assert belief_text(seed, [1.0, 0, 0, 0, 0, 0, 0.0004]) == "S0 1.000 | +6 others 0.000"


def test_one_state_left_over_is_one_other():
    names = [f"state_named_{i}" for i in range(3)]     # three of them do not fit
    assert belief_text(names, [0.5, 0.3, 0.2]) == \
        "state_named_0 0.500 | state_named_1 0.300 | +1 other 0.200"


def test_no_belief_is_no_text():
    assert belief_text([], []) == ""
