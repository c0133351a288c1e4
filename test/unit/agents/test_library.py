"""The policy library per task (ros_hrc.agents.library; issue #30): the shipped manifests
load with their policies, every refusal is one line naming the file (and the line), and a
manifest's paths are its folder's wherever the command runs."""
import math
import re
import shutil
from pathlib import Path

import pytest

from ros_hrc.agents.library import (LibraryError, LibraryPolicy, UnknownPolicy,
                                    library_manifest, load_library)
from ros_hrc.model_files import MODELS_DIR
from ros_hrc.models import load_robot_model
from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner

FABRIC_POLICIES = ("base", "policy1", "policy3", "policy4", "policy5", "policy6", "policy7",
                   "policy8", "policy9", "policy10", "policy11", "policy12", "reactive")
SEED_POLICIES = ("authors", "fitted", "considerate", "considerate_fitted", "reactive@1",
                 "reactive@3", "reactive@5", "reactive@7", "reactive@9")
FABRIC_BASE = MODELS_DIR / "fabric" / "robot" / "base.pomdpx"
SEED_ROBOT = MODELS_DIR / "robot" / "robot.pomdp"


# -- the shipped libraries ----------------------------------------------------------------------
def test_fabrics_library_is_the_authors_policies_but_policy2_in_their_order():
    library = load_library("auto", "fabric")
    assert library.task == "fabric"
    assert library.manifest == MODELS_DIR / "fabric" / "library.toml"
    assert library.names() == FABRIC_POLICIES
    for policy in library.policies[:-1]:
        assert policy.planner == "despot" and policy.options == {}
        assert policy.robot_model == MODELS_DIR / "fabric" / "robot" / f"{policy.name}.pomdpx"
    assert library.get("reactive") == LibraryPolicy("reactive", "reactive", None,
                                                    {"reactive_wait": 15.0})


def test_fabrics_library_holds_every_policy_model_the_generator_writes():
    planned = {p.robot_model.name for p in load_library("auto", "fabric").policies
               if p.robot_model is not None}
    written = {p.name for p in (MODELS_DIR / "fabric" / "robot").glob("*.pomdpx")}
    assert planned == written - {"reactive.pomdpx"}     # the reactive planner loads its own


def test_the_seed_library_is_the_four_robot_models_and_the_reactive_robot_at_five_budgets():
    library = load_library("auto", "seed")
    assert library.manifest == MODELS_DIR / "robot" / "library.toml"
    assert library.names() == SEED_POLICIES
    assert [p.robot_model.name for p in library.policies[:4]] == [
        "robot.pomdp", "robot_fitted.pomdp", "robot_considerate.pomdp",
        "robot_considerate_fitted.pomdp"]
    assert [(p.planner, p.robot_model, dict(p.options)) for p in library.policies[4:]] == [
        ("reactive", None, {"reactive_budget": budget}) for budget in (1, 3, 5, 7, 9)]


def test_each_manifest_says_where_its_policies_came_from():
    for task in ("fabric", "seed"):
        text = library_manifest(task).read_text()
        assert f'task = "{task}"' in text.splitlines()
        header = "".join(line for line in text.splitlines() if line.startswith("#"))
        for name in load_library("auto", task).names():
            assert name.split("@")[0] in header, (task, name)


def test_auto_a_folder_and_the_file_are_the_same_library(monkeypatch):
    monkeypatch.chdir(MODELS_DIR)
    assert load_library("auto", "fabric") == load_library("fabric", "fabric") == \
        load_library("fabric/library.toml", "fabric") == load_library("", "fabric")


def test_despot_decides_with_every_policy_of_fabrics_library():
    for policy in load_library("auto", "fabric").policies:
        if policy.planner != "despot":
            continue
        model = load_robot_model(str(policy.robot_model), "fabric")
        planner = DespotPlanner(model, DespotConfig(time_per_step=math.inf, max_trials=20),
                                seed=0)
        assert 0 <= planner.act() < model.n_actions, policy.name


def test_a_policys_settings_are_what_the_launch_takes():
    library = load_library("auto", "seed")
    assert library.get("reactive@3").settings() == {"planner": "reactive",
                                                    "reactive_budget": 3}
    assert library.get("fitted").settings() == {
        "planner": "despot", "robot_model": str(MODELS_DIR / "robot" / "robot_fitted.pomdp")}


def test_an_unknown_policy_is_refused_naming_the_nearest():
    library = load_library("auto", "fabric")
    with pytest.raises(KeyError) as caught:
        library.get("polcy3")
    assert isinstance(caught.value, UnknownPolicy)
    text = str(caught.value)
    assert "\n" not in text and "did you mean policy3?" in text
    assert "models/fabric/library.toml" in text and "base, policy1" in text


# -- a manifest of our own ----------------------------------------------------------------------
def write(folder: Path, body: str, name: str = "library.toml") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(body)
    return path


def despot(name: str, model: Path) -> str:
    return f'[[policy]]\nname = "{name}"\nplanner = "despot"\nmodel = "{model}"\n'


def test_a_relative_model_is_the_manifests_folders_wherever_the_command_runs(tmp_path,
                                                                              monkeypatch):
    shutil.copy(FABRIC_BASE, tmp_path / "mine.pomdpx")
    manifest = write(tmp_path / "library", 'task = "fabric"\n' +
                     despot("mine", Path("../mine.pomdpx")) +
                     '[[policy]]\nname = "offline"\nplanner = "policy"\n'
                     'model = "../mine.pomdpx"\npolicy_file = "../mine.pomdpx"\n')
    elsewhere = tmp_path / "somewhere" / "else"
    elsewhere.mkdir(parents=True)
    monkeypatch.chdir(elsewhere)
    for given in (str(manifest), "../../library", "../../library/library.toml"):
        library = load_library(given, "fabric")
        assert library.manifest == manifest
        assert library.get("mine").robot_model == tmp_path / "mine.pomdpx"
        assert library.get("offline").options == {"policy_file": str(tmp_path / "mine.pomdpx")}


def refusal(tmp_path, body, task="fabric") -> str:
    """The one line loading the manifest ``body`` is refused with."""
    with pytest.raises(LibraryError) as caught:
        load_library(str(write(tmp_path, body)), task)
    text = str(caught.value)
    assert "\n" not in text, text
    return text


def at(tmp_path, line: int) -> str:
    return f"{tmp_path / 'library.toml'}:{line}: "


@pytest.mark.parametrize("body, line, says", [
    ('task = "fabric"\n[[policy]]\nname = "a"\nplanner = "desspot"\nmodel = "x"\n', 4,
     "policy 'a': planner:=desspot: unknown planner 'desspot'; did you mean despot? (known: despot, "
         "policy, reactive, none, explore"),
    ('task = "fabric"\n[[policy]]\nname = "a"\nmodel = "x"\n', 3,
     "policy 'a' has no planner (a name the planner setting takes: a planner of ours (despot, "
     "policy, reactive, none, explore), an installed package's"),
    ('task = "fabric"\n[[policy]]\nname = "a"\nplanner = "despot"\n', 3,
     "policy 'a': planner despot needs a model"),
    ('task = "fabric"\n[[policy]]\nname = "fixed:base"\nplanner = "none"\n', 3,
     "policy 1 has name 'fixed:base'"),
    ('task = "fabric"\n[[policy]]\nplanner = "none"\n', 2, "policy 1 has no name"),
    ('task = "fabric"\n[[policy]]\nname = "a"\nplanner = "despot"\nmodel = "x"\ndepht = 3\n', 6,
     "policy 'a': unknown key 'depht' for planner despot (its options: time_per_step, "
     "scenarios, depth, lambda, max_trials"),
    ('task = "fabric"\n[[policy]]\nname = "a"\nplanner = "despot"\nmodel = "x"\n'
     'reactive_wait = 3\n', 6, "unknown option 'reactive_wait' for planner despot"),
    ('task = "fabric"\n[[policy]]\nname = "r"\nplanner = "reactive"\nreactive_budget = 3\n', 5,
     "policy 'r': unknown option 'reactive_budget' for planner reactive (its options: "
     "reactive_wait"),
    ('task = "seed"\n[[policy]]\nname = "r"\nplanner = "reactive"\nreactive_budget = -1\n', 5,
     "policy 'r': reactive_budget:=-1: must be an integer from 0 to"),
    ('task = "fabric"\n[[policy]]\nname = "r"\nplanner = "none"\nscenarios = 5\n', 5,
     "unknown option 'scenarios' for planner none (it takes no option"),
    ('task = "fabric"\n[[policy]]\nname = "p"\nplanner = "policy"\nmodel = "x"\n', 4,
     "policy 'p': policy_file:=: planner:=policy needs a policy file"),
    ('task = "fabric"\n[[policy]]\nname = "a"\nplanner = "none"\n\n[[policy]]\nname = "b"\n'
     'planner = "none"\n\n[[policy]]\nname = "a"\nplanner = "explore"\n', 11,
     "policy 'a' is named twice (first at "),
    ('task = "fabric"\nextra = 1\n', 2, "unknown key 'extra' (a manifest has task and policy"),
])
def test_a_bad_policy_is_refused_in_one_line_naming_the_manifests_line(tmp_path, body, line,
                                                                      says):
    text = refusal(tmp_path, body.replace('model = "x"', f'model = "{FABRIC_BASE}"'),
                   task=re.search(r'task = "(\w+)"', body).group(1))
    assert text.startswith(at(tmp_path, line)), text
    assert says in text, text


def test_the_first_of_twice_named_policies_is_named(tmp_path):
    text = refusal(tmp_path, 'task = "fabric"\n[[policy]]\nname = "a"\nplanner = "none"\n'
                             '[[policy]]\nname = "a"\nplanner = "none"\n')
    assert text.endswith(f"(first at {tmp_path / 'library.toml'}:3)")


def test_a_model_of_another_task_is_refused_naming_the_task_it_fits(tmp_path):
    text = refusal(tmp_path, 'task = "fabric"\n' + despot("base", FABRIC_BASE) +
                   despot("seeds", SEED_ROBOT))
    assert text.startswith(at(tmp_path, 9) + "policy 'seeds': models/robot/robot.pomdp: ")
    assert text.endswith("it is a model of task seed (task:=seed)")


def test_a_missing_model_is_refused_naming_it(tmp_path):
    text = refusal(tmp_path, 'task = "fabric"\n' + despot("gone", Path("gone.pomdpx")))
    assert text.startswith(at(tmp_path, 5) + "policy 'gone': no model file")
    assert str(tmp_path / "gone.pomdpx") in text


def test_a_malformed_model_is_refused_naming_its_line(tmp_path):
    (tmp_path / "bad.pomdpx").write_text("<pomdpx>\n<oops>\n")
    text = refusal(tmp_path, 'task = "fabric"\n' + despot("bad", Path("bad.pomdpx")))
    assert text.startswith(at(tmp_path, 5) + "policy 'bad': ")
    assert "bad.pomdpx" in text.split("policy 'bad': ", 1)[1]


def test_a_manifest_of_another_task_is_refused(tmp_path):
    text = refusal(tmp_path, '# the seed\ntask = "seed"\n' + despot("a", SEED_ROBOT))
    assert text == at(tmp_path, 2) + "a library of task seed, not of task fabric (task:=seed)"
    with pytest.raises(LibraryError, match=r"models/robot/library.toml:\d+: a library of task "
                                           r"seed, not of task fabric"):
        load_library(str(library_manifest("seed")), "fabric")


@pytest.mark.parametrize("body, says", [
    ("", "no task line (task = \"fabric\""),
    ('task = "fabric"\n', "no policies (a library needs at least one [[policy]] table)"),
    ('task = "fabric"\npolicy = "base"\n', "policy must be [[policy]] tables"),
    ('task = "seeds"\n', "task = 'seeds' is not a task (known: seed, fabric)"),
    ('task = "fabric"\n[[policy]\nname = "a"\n', "not a valid TOML manifest: "),
])
def test_a_bad_manifest_is_refused_in_one_line(tmp_path, body, says):
    text = refusal(tmp_path, body)
    assert text.startswith(str(tmp_path / "library.toml")) and says in text, text


def test_malformed_toml_is_refused_naming_its_line(tmp_path):
    assert "(at line 3" in refusal(tmp_path, 'task = "fabric"\n\nname = = "a"\n')


def test_a_missing_manifest_or_folder_is_refused_naming_it(tmp_path):
    for given in (tmp_path / "none.toml", tmp_path / "nowhere"):
        with pytest.raises(LibraryError, match=f"^{re.escape(str(given))}: no such manifest "
                                               f"or folder"):
            load_library(str(given), "fabric")
    with pytest.raises(LibraryError, match="a folder without a library.toml"):
        load_library(str(tmp_path), "fabric")
