"""The extension surface (ros_hrc.registry, docs/extending.md): planners, selectors and robot
policies found by the entry points of installed distributions (a real dist-info written to a
folder on sys.path, read by importlib.metadata) or as module:Class, ours by the same lookup;
every refusal one line; a planner or selector of a package's own runs through the robot
process's code with nothing but the interface's defaults."""
import argparse
import itertools
import textwrap

import numpy as np
import pytest

from ros_hrc import registry, settings
from ros_hrc.agents.library import LibraryError, load_library
from ros_hrc.agents.selectors import Selector, TaskResult, make_selector
from ros_hrc.experiment.episode import RobotPolicy, robot_policy
from ros_hrc.pomdp.planner import Planner, planner_class
from ros_hrc.processes import despot_pomdp

_NUMBERS = itertools.count()

PLANNERS_PY = '''
import numpy as np
from ros_hrc.pomdp.planner import Planner, PlannerStats


class FirstAction(Planner):
    """Only what Planner makes abstract: no reseed, no observe_time, no rule, no policy text."""

    options = {"action": 0}

    def __init__(self, model, seed=None, action=0):
        self.model = model
        self.action = action
        self.last_stats = PlannerStats()
        self._belief = np.asarray(model.initial_belief, dtype=float)

    def reset(self, belief=None):
        self._belief = np.asarray(model_belief(self.model) if belief is None else belief)

    def act(self):
        return self.action

    def update(self, action, observation):
        pass

    @property
    def belief(self):
        return self._belief


class OnModel(FirstAction):
    plans_on_model = True


def model_belief(model):
    return np.asarray(model.initial_belief, dtype=float)


class NotAPlanner:
    pass
'''

SELECTORS_PY = '''
from ros_hrc.agents.selectors import Selector


class Last(Selector):
    def __init__(self, policies, rng):
        self.policies = policies

    def choose(self):
        return self.policies[-1]
'''


def distribution(folder, package, entry_points, files, version="0.1"):
    """A package and its dist-info under ``folder``, as pip would leave them."""
    (folder / package).mkdir()
    (folder / package / "__init__.py").write_text("")
    for name, text in files.items():
        (folder / package / name).write_text(textwrap.dedent(text))
    info = folder / f"{package}-{version}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {package}\nVersion: {version}\n")
    (info / "entry_points.txt").write_text(entry_points)


@pytest.fixture
def package(tmp_path, monkeypatch):
    """A distribution of a fresh name on sys.path: a planner, a selector and a policy."""
    name = f"their_robot_{next(_NUMBERS)}"
    distribution(tmp_path, name, textwrap.dedent(f"""\
        [ros_hrc.planners]
        first_action = {name}.planners:FirstAction
        on_model = {name}.planners:OnModel
        broken = {name}.broken:Whatever
        [ros_hrc.selectors]
        last = {name}.selectors:Last
        [ros_hrc.policies]
        their_robot = {name}.policies:THEIRS
        """), {"planners.py": PLANNERS_PY, "selectors.py": SELECTORS_PY,
               "broken.py": "raise RuntimeError('half written')\n",
               "policies.py": "from ros_hrc.experiment.episode import RobotPolicy\n"
                              "THEIRS = RobotPolicy('first_action')\n"})
    monkeypatch.syspath_prepend(str(tmp_path))
    return name


def test_ours_are_found_by_the_same_lookup():
    assert registry.names(registry.PLANNERS)[:5] == ("despot", "policy", "reactive", "none",
                                                     "explore")
    assert planner_class("despot").plans_on_model and not planner_class("none").plans_on_model
    assert robot_policy("pomdp_fitted").robot_model == "robot_fitted"


def test_an_installed_package_s_names_are_found_and_loaded(package):
    assert "first_action" in registry.names(registry.PLANNERS)
    assert planner_class("first_action").__module__ == f"{package}.planners"
    assert planner_class(f"{package}.planners:FirstAction") is planner_class("first_action")
    assert isinstance(robot_policy("their_robot"), RobotPolicy)
    assert settings.parse("planner", "first_action") == "first_action"
    assert "last" in settings.selector_words()


def test_each_refusal_is_one_line_naming_it_and_why(package):
    cases = {
        "fist_action": "unknown planner 'fist_action'; did you mean first_action? (known: "
                       "despot, policy, reactive, none, explore, broken, first_action, on_model, "
                       "or module:Class)",
        "broken": f"planner 'broken' ({package} 0.1: {package}.broken:Whatever): cannot import "
                  f"{package}.broken (RuntimeError: half written)",
        f"{package}.planners:Nothing": f"planner {package}.planners:Nothing: module "
                                       f"{package}.planners has no Nothing",
        f"{package}.planners:NotAPlanner": f"planner {package}.planners:NotAPlanner: NotAPlanner "
                                           "is not a subclass of ros_hrc.pomdp.planner.Planner",
        "no_such_module.x:Y": "planner no_such_module.x:Y: cannot import no_such_module.x "
                              "(ModuleNotFoundError: No module named 'no_such_module')",
    }
    for name, says in cases.items():
        with pytest.raises(registry.RegistryError) as refused:
            planner_class(name)
        assert str(refused.value).startswith(says)
        assert "\n" not in str(refused.value)
    with pytest.raises(settings.SettingError, match="planner:=fist_action: unknown planner"):
        settings.parse("planner", "fist_action")


def test_a_name_two_packages_declare_differently_is_refused_naming_both(tmp_path, monkeypatch):
    for number in (1, 2):
        folder = tmp_path / str(number)
        folder.mkdir()
        distribution(folder, f"twin_{number}_{next(_NUMBERS)}",
                     f"[ros_hrc.planners]\ntwin = twin_{number}.planners:X\n"
                     f"despot = twin_{number}.planners:X\n", {})
        monkeypatch.syspath_prepend(str(folder))
    with pytest.raises(registry.RegistryError, match=r"planner 'twin' is declared more than "
                                                     r"once: twin_\d_\d+ 0.1: twin_\d.planners:X; "
                                                     r"twin_\d_\d+ 0.1: twin_\d.planners:X"):
        planner_class("twin")
    # A name of ours stays ours.
    assert planner_class("despot").__module__ == "ros_hrc.pomdp.despot"


def robot_args(planner, **more):
    values = {"task": "seed", "robot_model": "robot", "planner": planner, "seed": 4,
              "planner_options": "",
              "policy_file": "", "reactive_budget": 8, "reactive_wait": 0.0,
              "time_per_step": 0.1, "scenarios": 50, "depth": 10, "lambda_": 0.1,
              "max_trials": 20, "selector": "fixed", "bpr_forgetting": 0.05, **more}
    return argparse.Namespace(**values)


def test_a_planner_with_only_the_abstract_methods_runs_in_the_robot_process(package):
    model, planner, sequence = despot_pomdp.build_robot(robot_args("first_action", action=2))
    assert type(planner).__name__ == "FirstAction" and planner.action == 2
    agent = next(iter(sequence.agents.values()))
    agent.reset(episode=3)                       # the base's reseed: nothing drawn
    action, _, note = agent.step(model.observations[0], elapsed=None)
    assert (action, note) == (2, "")
    assert planner.policy_text() is None and planner.last_rule is None
    assert not planner.reads_time
    # The reports name a planner that decides without the model by its own name.
    assert despot_pomdp.fixed_policy_name(robot_args("first_action")) == "first_action"
    assert despot_pomdp.fixed_policy_name(robot_args("on_model")) == "robot"


def test_a_library_takes_a_package_s_planner_and_its_options(package, tmp_path):
    def library(body):
        path = tmp_path / f"library_{next(_NUMBERS)}.toml"
        path.write_text('task = "seed"\n\n[[policy]]\nname = "theirs"\n' + body)
        return load_library(str(path), "seed")

    loaded = library(f'planner = "{package}.planners:FirstAction"\naction = 1\n')
    assert loaded.policies[0].options == {"action": 1} and loaded.policies[0].robot_model is None
    assert library('planner = "on_model"\nmodel = "robot"\n').policies[0].robot_model.name == \
        "robot.pomdpx"
    for body, says in (
            ('planner = "on_model"\n', ":4: policy 'theirs': planner on_model needs a model"),
            ('planner = "first_action"\naction = "two"\n',
             ":6: policy 'theirs': option action must be a int like its default 0, got 'two'"),
            ('planner = "first_action"\nspeed = 2\n',
             ":6: policy 'theirs': unknown key 'speed' for planner first_action (its options: "
             "action;"),
            ('planner = "broken"\n', ":5: policy 'theirs': planner 'broken' (")):
        with pytest.raises(LibraryError) as refused:
            library(body)
        assert says in str(refused.value)


def test_a_package_s_selector_is_made_with_the_base_s_defaults(package):
    selector = make_selector("last", ("a", "b"), None, seed=0, forgetting=0.0)
    assert isinstance(selector, Selector) and selector.name == "last"
    assert selector.choose() == "b"
    selector.observe(TaskResult("b", (1, 2), 0.5))
    selector.tell_true_type("tired")
    assert (selector.note, selector.type_names, len(selector.belief())) == ("", (), 0)
    assert make_selector(f"{package}.selectors:Last", ("a", "b"), None, 0, 0.0).choose() == "b"
    with pytest.raises(ValueError, match="is not a subclass of ros_hrc.agents.selectors.Selector"):
        make_selector(f"{package}.planners:FirstAction", ("a",), None, 0, 0.0)


def test_the_robot_process_asks_the_interface_not_the_object():
    """No ability is probed for: the planner's and the selector's are all on their bases."""
    import inspect
    source = inspect.getsource(despot_pomdp)
    assert not [line for line in source.splitlines()
                if ("getattr(" in line or "hasattr(" in line) and ("planner" in line
                                                                   or "selector" in line)]
    for name in ("reseed", "observe_time", "policy_text", "from_settings", "settings_used"):
        assert callable(getattr(Planner, name))
    for name in ("plans_on_model", "reads_time", "options", "last_rule", "mdp_state"):
        assert hasattr(Planner, name)
    assert Selector.note == "" and Selector.needs_model is False
    assert np.array_equal(Selector.belief(Selector()), np.zeros(0))


def test_the_launch_s_planner_options_reach_a_package_s_planner_checked(package):
    _, planner, _ = despot_pomdp.build_robot(robot_args("first_action", planner_options="action=3"))
    assert planner.action == 3
    for text, says in (("speed=1", "--planner-options speed=1: unknown option 'speed' (its "
                                   "options: action)"),
                       ("action=1.5", "--planner-options action=1.5: option action must be a "
                                      "int like its default 0, got 1.5")):
        with pytest.raises(ValueError) as refused:
            despot_pomdp.build_robot(robot_args("first_action", planner_options=text))
        assert str(refused.value) == says
    with pytest.raises(settings.SettingError, match=r"^planner_options:=action: must be "
                                                    r"NAME=VALUE pairs, comma-separated"):
        settings.resolve({"planner_options": "action"})
    assert settings.planner_option_values('a=1,b="x y",c=true') == {"a": 1, "b": "x y",
                                                                      "c": True}
    assert settings.planner_option_values(settings.planner_options_text(
        {"a": 1, "b": "x, \"y\"", "c": False, "d": 0.25})) == {"a": 1, "b": "x, \"y\"",
                                                               "c": False, "d": 0.25}


def test_a_study_policy_s_options_go_to_its_cells_launch(package, tmp_path):
    from ros_hrc.experiment.stack import CellSpec, launch_arguments
    (tmp_path / package / "tuned.py").write_text(
        "from ros_hrc.experiment.episode import RobotPolicy\n"
        "TUNED = RobotPolicy('first_action', options={'action': 2})\n")
    words = launch_arguments(CellSpec("tired", f"{package}.tuned:TUNED", 0, episodes=[0]),
                             {"master": 1, "pomdp": 2, "human": 3})
    assert "planner:=first_action" in words and "planner_options:=action=2" in words
    assert not [w for w in launch_arguments(CellSpec("tired", "pomdp", 0, episodes=[0]),
                                            {"master": 1, "pomdp": 2, "human": 3})
                if w.startswith("planner_options")]
