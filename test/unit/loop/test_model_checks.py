"""ros_hrc.models: the shipped models fit the task's tables; a model that does not is
refused in one line naming the file and the offending names.

(Named test_model_checks.py, not test_models.py: pytest's rootdir imports need unique test
file names, and test/unit/pomdp/test_models.py exists.)"""
import re
from pathlib import Path

import pytest

from ros_hrc.errors import HrcError, ModelError, ModelFormatError
from ros_hrc import models
from ros_hrc.tasks import seed as task
from ros_hrc.models import (ModelNotFound, check_human_model, check_robot_model,
                                 load_human_model, load_robot_model)

from loop_fakes import refusal

MODELS = Path(__file__).resolve().parents[3] / "models"
HUMANS = ("humanModel", "expert", "beginner", "tired", "distracted")


def edited_copy(source: Path, target: Path, pattern: str, replacement: str) -> Path:
    text = source.read_text()
    edited = re.sub(pattern, replacement, text)
    assert edited != text, f"{pattern!r} not found in {source}"
    target.write_text(edited)
    return target


@pytest.mark.parametrize("name", HUMANS)
def test_the_shipped_human_models_fit_the_task(name):
    model = load_human_model(name)
    assert tuple(model.states) == task.HUMAN_STATES
    assert load_human_model(str(MODELS / "human" / f"{name}.pomdpx")).states == model.states


@pytest.mark.parametrize("path", ["robot", str(MODELS / "robot" / "robot.pomdp"),
                                  str(MODELS / "robot" / "robot.pomdpx")])
def test_the_shipped_robot_model_fits_the_task_in_both_formats(path):
    model = load_robot_model(path)
    assert set(model.observations) == {f"O{b}" for b in task.LEGAL_BITS}
    assert models.ROBOT_OBSERVATIONS == tuple(f"O{b}" for b in task.LEGAL_BITS)


def test_a_robot_model_with_O35_renamed_O36_is_refused_naming_the_file_and_O36(tmp_path):
    bad = edited_copy(MODELS / "robot" / "robot.pomdp", tmp_path / "x.pomdp", r"\bO35\b", "O36")
    text = refusal(load_robot_model, bad)
    assert text == f"{bad}: observations O36 are not the task's observations (missing: O35)"


def test_a_robot_model_with_an_extra_observation_is_refused():
    model = load_robot_model("robot")
    model.observations = list(model.observations[:-1]) + ["O63"]
    with pytest.raises(ModelError, match=r"^here\.pomdp: observations O63 are not the task's "
                                         r"observations \(missing: O35\)$"):
        check_robot_model(model, "here.pomdp")


def test_a_robot_model_with_renamed_actions_or_states_is_refused(tmp_path):
    bad = edited_copy(MODELS / "robot" / "robot.pomdp", tmp_path / "a.pomdp", r"\brStop_all\b",
                      "rFreeze")
    assert refusal(load_robot_model, bad) == (f"{bad}: actions rFreeze are not the task's actions "
                                              "(missing: rStop_all)")
    bad = edited_copy(MODELS / "robot" / "robot.pomdp", tmp_path / "s.pomdp", r"\bS6\b", "S7")
    assert refusal(load_robot_model, bad) == (f"{bad}: states S7 are not the task's states "
                                              "(missing: S6)")



def test_a_model_of_human_types_fits_when_each_types_states_are_the_tasks(tmp_path):
    from ros_hrc.pomdp.fit import write_fitted
    from ros_hrc.pomdp.typed import compose
    robot = load_robot_model("robot")
    path = tmp_path / "types.pomdp"
    write_fitted(compose({"tired": robot, "expert": robot}), path)
    assert load_robot_model(str(path)).states[:2] == ["S0__tired", "S1__tired"]
    bad = edited_copy(path, tmp_path / "s.pomdp", r"\bS6__expert\b", "S7__expert")
    assert refusal(load_robot_model, bad).startswith(f"{bad}: states ")

def test_a_human_model_with_a_renamed_state_is_refused(tmp_path):
    bad = edited_copy(MODELS / "human" / "tired.pomdpx", tmp_path / "h.pomdpx", r"\bevaluating\b",
                      "thinking")
    assert refusal(load_human_model, bad) == (f"{bad}: states thinking are not the task's states "
                                              "(missing: evaluating)")


def test_a_human_model_with_the_states_out_of_order_is_refused():
    model = load_human_model("tired")
    model.states = [model.states[1], model.states[0]] + list(model.states[2:])
    with pytest.raises(ModelError) as info:
        check_human_model(model, "h.pomdpx")
    text = str(info.value)
    assert text.startswith("h.pomdpx: states are in the order success, task_assigned, ")
    assert "manual mode types state numbers" in text


def test_a_human_model_must_be_fully_observable_with_the_task_s_actions(tmp_path):
    bad = edited_copy(MODELS / "human" / "tired.pomdpx", tmp_path / "po.pomdpx",
                      r'fullyObs="true"', 'fullyObs="false"')
    assert refusal(load_human_model, bad) == (f"{bad}: a human model must be fully observable "
                                              "(POMDPX: fullyObs=\"true\")")
    bad = edited_copy(MODELS / "human" / "tired.pomdpx", tmp_path / "act.pomdpx",
                      r"\bwarnRobot\b", "shout")
    assert refusal(load_human_model, bad) == (f"{bad}: actions shout are not the task's actions "
                                              "(missing: warnRobot)")


def test_a_robot_model_is_no_human_model_and_back():
    text = refusal(load_human_model, MODELS / "robot" / "robot.pomdp")
    assert text.startswith("models/robot/robot.pomdp: states S0, S1, S2, S3, S4, S5, S6 are not "
                           "the task's states (missing: task_assigned, ")
    text = refusal(load_robot_model, MODELS / "human" / "tired.pomdpx")
    assert text.startswith("models/human/tired.pomdpx: states task_assigned, ")


def test_a_missing_model_names_the_scenario_and_what_exists(tmp_path):
    with pytest.raises(ModelNotFound) as info:
        load_human_model("does_not_exist")
    text = str(info.value)
    from ros_hrc.experiment.zoo import NOT_IN_ZOO, ZOO
    known = ", ".join(sorted(set(ZOO) | set(NOT_IN_ZOO)))
    assert "'does_not_exist'" in text and f"known: {known}" in text
    assert isinstance(info.value, HrcError)
    with pytest.raises(ModelNotFound, match="no model file"):
        load_robot_model(str(tmp_path / "gone.pomdp"))


def test_parser_errors_pass_through_naming_file_and_line(tmp_path):
    lines = (MODELS / "robot" / "robot.pomdpx").read_text()[:3000]
    cut = tmp_path / "cut.pomdpx"
    cut.write_text(lines)
    with pytest.raises(ModelFormatError) as info:
        load_robot_model(str(cut))
    assert str(info.value).startswith(f"{cut}:")
    empty = tmp_path / "empty.pomdp"
    empty.write_text("")
    with pytest.raises(ModelFormatError):
        load_robot_model(str(empty))
