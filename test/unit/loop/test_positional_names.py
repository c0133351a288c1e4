"""ros_hrc.models: a model whose names are generic (s0.., a0.., o0.., as POMDPX
<NumValues> names them, e.g. the seed's pomdp_FINAL.pomdpx) in the task's sizes is read by
position with the task's names, and the mapping is one start-up line; generic names in
another size are refused in one line; any other names must match as before.

The tables are compared with whatever the shipped models hold when the test runs."""
import dataclasses

import pytest
import yaml

from ros_hrc.errors import ModelError
from ros_hrc import models, settings
from ros_hrc.tasks import seed as task
from ros_hrc.commands.check import main as hrc_check
from ros_hrc.models import (load_human_model, load_robot_model, name_by_position,
                                 positional_mapping_line, positional_mapping_lines)
from ros_hrc.pomdp.io import differences, load_model, save_model

from loop_fakes import refusal

ROBOT_NAMES = {"states": list(task.ROBOT_STATES), "actions": list(task.ROBOT_ACTION_SERVICES),
               "observations": [task.observation_name(b) for b in task.LEGAL_BITS]}
HUMAN_NAMES = {"states": list(task.HUMAN_STATES), "actions": list(task.HUMAN_ACTION_SERVICES)}
PREFIX = {"states": "s", "actions": "a", "observations": "o"}


def generic(n, prefix):
    return [f"{prefix}{i}" for i in range(n)]


def shipped(kind):
    """The shipped model of the launch's default (robot) or of a human scenario, as the
    file holds it (no check, no renaming)."""
    name = settings.default("robot_model") if kind == "robot" else "tired"
    return load_model(str(models.model_path(name, kind)))


def renamed_copy(model, path, **lists):
    """``model`` saved at ``path`` with some of its lists renamed."""
    save_model(dataclasses.replace(model, **lists), str(path))
    return path


def positional_robot(tmp_path, name="positional.pomdpx"):
    named = shipped("robot")
    path = renamed_copy(named, tmp_path / name, states=generic(named.n_states, "s"),
                        actions=generic(named.n_actions, "a"),
                        observations=generic(named.n_observations, "o"))
    return named, path


def test_a_positional_robot_model_gets_the_task_s_names_and_the_same_tables(tmp_path):
    named, path = positional_robot(tmp_path)
    assert load_model(str(path)).states[:2] == ["s0", "s1"]       # the file is generic
    model = load_robot_model(str(path))
    assert model.states == ROBOT_NAMES["states"]
    assert model.actions == ROBOT_NAMES["actions"]
    assert model.observations == ROBOT_NAMES["observations"]
    assert differences(model, named) == []          # the same tables, bit for bit
    assert differences(model, load_robot_model(settings.default("robot_model"))) == []
    assert model.meta["positional_names"]["actions"] == [
        ("a0", "rIdle"), ("a1", "rPoint_obj"), ("a2", "rGrasp_obj"), ("a3", "rStop_all")]
    assert model.meta["positional_names"]["observations"][4] == ("o4", "O7")


def test_the_mapping_is_one_line_naming_the_file_and_every_pair(tmp_path):
    _, path = positional_robot(tmp_path)
    model = load_robot_model(str(path))
    lines = positional_mapping_lines(model)
    assert [line.split()[0] for line in lines] == ["states", "actions", "observations"]
    for line, label in zip(lines, ("states", "actions", "observations")):
        pairs = [f"{old}={new}" for old, new in zip(generic(len(ROBOT_NAMES[label]),
                                                            PREFIX[label]), ROBOT_NAMES[label])]
        assert line == f"{label} " + " ".join(pairs)
    line = positional_mapping_line(model)
    assert "\n" not in line
    assert line == f"{path}: names by position: " + "; ".join(lines)
    assert "actions a0=rIdle a1=rPoint_obj a2=rGrasp_obj a3=rStop_all;" in line
    assert "o4=O7 " in line and line.endswith("o14=O35")


def test_each_list_is_judged_on_its_own(tmp_path):
    named = shipped("robot")
    path = renamed_copy(named, tmp_path / "actions_only.pomdpx",
                        actions=generic(named.n_actions, "a"))
    model = load_robot_model(str(path))
    assert model.actions == ROBOT_NAMES["actions"]
    assert list(model.meta["positional_names"]) == ["actions"]
    assert positional_mapping_line(model) == (
        f"{path}: names by position: actions a0=rIdle a1=rPoint_obj a2=rGrasp_obj a3=rStop_all")


def test_the_task_s_own_names_give_no_mapping_line():
    model = load_robot_model(settings.default("robot_model"))
    assert "positional_names" not in model.meta
    assert positional_mapping_lines(model) == [] and positional_mapping_line(model) is None
    assert name_by_position(model, "robot") is model


@pytest.mark.parametrize("label, size, line", [
    ("states", 6, "states s0..s5 are positional but the task has 7 states: "
                  "S0, S1, S2, S3, S4, S5, S6"),
    ("actions", 5, "actions a0..a4 are positional but the task has 4 actions: "
                   "rIdle, rPoint_obj, rGrasp_obj, rStop_all"),
    ("observations", 14, "observations o0..o13 are positional but the task has 15 "
                         "observations: O0, O1, O2, O3, O7, O10, O11, O16, O17, O18, O19, O32, "
                         "O33, O34, O35"),
])
def test_generic_names_of_the_wrong_size_are_refused_in_one_line(label, size, line):
    model = dataclasses.replace(shipped("robot"), **{label: generic(size, PREFIX[label])})
    with pytest.raises(ModelError) as info:
        name_by_position(model, "robot", "x.pomdpx")
    assert str(info.value) == f"x.pomdpx: {line}"


def fewer_observations(model):
    """``model`` with its last two observations merged into one: 14 observations."""
    import scipy.sparse as sp

    def merged(o):
        dense = o.toarray()
        dense[:, -2] += dense[:, -1]
        return sp.csr_matrix(dense[:, :-1])

    n = model.n_observations - 1
    return dataclasses.replace(model, observations=generic(n, "o"),
                               O=[merged(o) for o in model.O])


def test_a_positional_file_of_the_wrong_size_is_refused_naming_it(tmp_path):
    path = tmp_path / "small.pomdpx"
    save_model(fewer_observations(shipped("robot")), str(path))
    assert load_model(str(path)).n_observations == 14
    assert refusal(load_robot_model, path) == (
        f"{path}: observations o0..o13 are positional but the task has 15 observations: "
        "O0, O1, O2, O3, O7, O10, O11, O16, O17, O18, O19, O32, O33, O34, O35")


def test_mixed_names_are_refused_as_before(tmp_path):
    named = shipped("robot")
    mixed = generic(2, "s") + ROBOT_NAMES["states"][2:]                 # s0 s1 S2 ... S6
    path = renamed_copy(named, tmp_path / "mixed.pomdpx", states=mixed)
    assert refusal(load_robot_model, path) == (
        f"{path}: states s0, s1 are not the task's states (missing: S0, S1)")
    # generic states renamed, but a wrong action name is still refused as before
    path = renamed_copy(named, tmp_path / "wrong_action.pomdpx",
                        states=generic(named.n_states, "s"),
                        actions=ROBOT_NAMES["actions"][:-1] + ["rFreeze"])
    assert refusal(load_robot_model, path) == (
        f"{path}: actions rFreeze are not the task's actions (missing: rStop_all)")
    # the other prefix is not positional for this list
    path = renamed_copy(named, tmp_path / "prefix.pomdpx", actions=generic(named.n_actions, "s"))
    assert refusal(load_robot_model, path) == (
        f"{path}: actions s0, s1, s2, s3 are not the task's actions "
        "(missing: rIdle, rPoint_obj, rGrasp_obj, rStop_all)")


def test_a_positional_human_model_gets_the_task_s_names(tmp_path):
    named = shipped("human")
    assert named.fully_observable
    path = renamed_copy(named, tmp_path / "human.pomdpx", states=generic(8, "s"),
                        observations=generic(8, "s"), actions=generic(5, "a"))
    assert load_model(str(path)).states[0] == "s0"
    model = load_human_model(str(path))
    assert model.states == HUMAN_NAMES["states"] and model.observations == model.states
    assert model.actions == HUMAN_NAMES["actions"]
    assert differences(model, load_human_model("tired")) == []
    line = positional_mapping_line(model)
    assert line == (f"{path}: names by position: states s0=task_assigned s1=success "
                    "s2=failed_to_grasp s3=no_attention s4=evaluating s5=tired s6=recovery "
                    "s7=warningTheRobot; actions a0=graspAttempt a1=lookAround a2=idle "
                    "a3=walkAway a4=warnRobot")
    wrong = renamed_copy(named, tmp_path / "human7.pomdpx", actions=generic(4, "a") + ["warnRobot"])
    assert refusal(load_human_model, wrong) == (
        f"{wrong}: actions a0, a1, a2, a3 are not the task's actions "
        "(missing: graspAttempt, lookAround, idle, walkAway)")


def test_a_positional_human_model_of_the_wrong_size_is_refused():
    named = shipped("human")
    with pytest.raises(ModelError, match=r"^h\.pomdpx: actions a0\.\.a5 are positional but the "
                                         r"task has 5 actions: graspAttempt, lookAround, idle, "
                                         r"walkAway, warnRobot$"):
        name_by_position(dataclasses.replace(named, actions=generic(6, "a")), "human", "h.pomdpx")


def test_hrc_check_accepts_a_positional_model_and_prints_the_mapping_on_stderr(tmp_path, capsys):
    _, path = positional_robot(tmp_path)
    named = shipped("human")
    human = renamed_copy(named, tmp_path / "human.pomdpx", states=generic(8, "s"),
                         observations=generic(8, "s"), actions=generic(5, "a"))
    assert hrc_check([f"robot_model:={path}", f"human_model:={human}", "--no-port-check"]) == 0
    out, err = capsys.readouterr()
    config = yaml.safe_load(out)
    assert config["robot_model"] == str(path)
    lines = err.splitlines()
    assert lines == [f"hrc.launch: {positional_mapping_line(load_human_model(str(human)))}",
                     f"hrc.launch: {positional_mapping_line(load_robot_model(str(path)))}"]
    assert lines[1].startswith(f"hrc.launch: {path}: names by position: states s0=S0 ")


def test_hrc_check_refuses_a_positional_model_of_the_wrong_size_in_one_line(tmp_path, capsys):
    path = tmp_path / "small.pomdpx"
    save_model(fewer_observations(shipped("robot")), str(path))
    assert hrc_check([f"robot_model:={path}", "--no-port-check"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.splitlines() == [f"hrc.launch: {path}: observations o0..o13 are positional but "
                                "the task has 15 observations: O0, O1, O2, O3, O7, O10, O11, "
                                "O16, O17, O18, O19, O32, O33, O34, O35"]


def test_hrc_experiment_s_grid_check_prints_each_mapping_once_per_model_file(tmp_path, capsys):
    from ros_hrc.experiment.cli import build_parser, validate_grid

    _, robot = positional_robot(tmp_path)
    human = renamed_copy(shipped("human"), tmp_path / "human.pomdpx", states=generic(8, "s"),
                         observations=generic(8, "s"), actions=generic(5, "a"))
    same_file = f"{tmp_path}/./human.pomdpx"                # another name, the same file
    args = build_parser().parse_args(["--robot-model", str(robot), "--human-models",
                                      f"{human},tired,{same_file}", "--policies", "reactive"])
    validate_grid(args)
    out = capsys.readouterr().out.splitlines()
    assert out == [f"hrc_experiment: {positional_mapping_line(load_robot_model(str(robot)))}",
                   f"hrc_experiment: {positional_mapping_line(load_human_model(str(human)))}"]
