"""ros_hrc.settings: one default per launch argument, one line per refused value."""
import argparse
import importlib.util
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from ros_hrc.errors import HrcError
from ros_hrc import settings
from ros_hrc.settings import SETTINGS, Setting, SettingError

ROOT = Path(__file__).resolve().parents[3]
LAUNCH = ROOT / "launch" / "hrc.launch"
WORLD_LAUNCH = ROOT / "launch" / "world.launch"
MAKER = ROOT / "tools" / "make_settings_files.py"

DEFAULTS = {
    "task": "seed", "human_model": "humanModel", "robot_model": "robot", "mode": "auto",
    "gui": False,
    "seed": 0, "use_sim_time": False, "real_time_factor": 1.0, "pause_when_idle": None,
    "belt_speed": 0.02, "away_time": None, "viz": True, "rviz": False, "snapshot_dir": "", "camera_rate": 0.0,
    "publish_rate": 10.0,
    "host": "127.0.0.1", "pomdp_port": 7070,
    "human_port": 9090, "link_read_timeout": 5.0, "start_mdp": True, "mdp_xterm": None, "human_choice": "optimal",
    "temperature": 1.0, "manual_share": 0.8, "step_delay": 1.0, "max_steps": 0,
    "on_episode_end": "wait", "end_on_goal": True, "episodes": "live", "wait_for_listener": False,
    "start_pomdp": True, "planner": "despot", "planner_options": "",
    "policy_file": "", "time_per_step": 0.1, "scenarios": 500, "depth": 90, "lambda": 0.1,
    "max_trials": 0, "reactive_budget": 8, "reactive_wait": 15.0, "read_stdin": True,
    "verbose": False, "tasks": None, "schedule": "", "selector": "fixed", "library": "auto",
    "selector_model": "auto", "task_timeout": None, "bpr_forgetting": 0.05,
    "learning_strength": 20.0, "learning_forgetting": 0.1, "learning_draws": 8,
    "learning_bonus": None,
}


def refusal(name, value):
    with pytest.raises(SettingError) as info:
        settings.parse(name, value)
    return str(info.value)


def test_every_setting_has_its_default():
    assert set(SETTINGS) == set(DEFAULTS)
    for name, expected in DEFAULTS.items():
        assert settings.default(name) == expected, name
        assert type(settings.default(name)) is type(expected), name
        assert settings.parse(name, "") == expected
        assert settings.parse(name, None) == expected
        assert isinstance(SETTINGS[name], Setting) and SETTINGS[name].name == name
        assert SETTINGS[name].doc


def test_one_time_per_step_default_for_every_entry_point():
    assert settings.default("time_per_step") == 0.1


def make_settings_files():
    """tools/make_settings_files.py, which writes hrc.launch's arguments and docs/settings.md
    from the table."""
    spec = importlib.util.spec_from_file_location("make_settings_files", MAKER)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_hrc_launch_and_the_settings_reference_are_written_from_the_table():
    """The table is the only place a default is written: hrc.launch's <arg> lines and
    docs/settings.md are what tools/make_settings_files.py writes from it."""
    for path, text in make_settings_files().written_files(ROOT).items():
        assert path.read_text(encoding="utf-8") == text, (
            f"{path} is not what the settings table writes: python tools/make_settings_files.py")


def test_a_default_edited_in_hrc_launch_by_hand_is_caught_and_written_back(tmp_path, capsys):
    maker = make_settings_files()
    _copy_written_files(tmp_path)
    copy = tmp_path / "launch" / "hrc.launch"
    edited = copy.read_text().replace('name="belt_speed" default="0.02"',
                                      'name="belt_speed" default="0.03"')
    assert edited != copy.read_text()
    copy.write_text(edited)
    assert maker.main(["--check", "--root", str(tmp_path)]) == 1
    assert "hrc.launch differs from the settings table" in capsys.readouterr().err
    assert maker.main(["--root", str(tmp_path)]) == 0
    assert copy.read_text() == LAUNCH.read_text()
    assert maker.main(["--check", "--root", str(tmp_path)]) == 0
    copy.write_text(edited.replace(maker.BEGIN, "<!-- gone -->"))
    assert maker.main(["--root", str(tmp_path)]) == 2


def _copy_written_files(root):
    """The files tools/make_settings_files.py writes, copied under ``root``."""
    for path in (LAUNCH, WORLD_LAUNCH, ROOT / "docs" / "settings.md"):
        (root / path.parent.name).mkdir(exist_ok=True)
        (root / path.relative_to(ROOT)).write_text(path.read_text(encoding="utf-8"))


def test_a_default_edited_in_world_launch_by_hand_is_caught_and_written_back(tmp_path, capsys):
    maker = make_settings_files()
    _copy_written_files(tmp_path)
    copy = tmp_path / "launch" / "world.launch"
    edited = copy.read_text().replace('name="camera_rate" default="0.0"',
                                      'name="camera_rate" default="5"')
    assert edited != copy.read_text()
    copy.write_text(edited)
    assert maker.main(["--check", "--root", str(tmp_path)]) == 1
    assert "world.launch differs from the settings table" in capsys.readouterr().err
    assert maker.main(["--root", str(tmp_path)]) == 0
    assert copy.read_text() == WORLD_LAUNCH.read_text()


def test_world_launch_takes_the_world_settings_with_the_tables_defaults_and_checks_them_all():
    root = ET.parse(WORLD_LAUNCH).getroot()
    args = {a.get("name"): a.get("default") for a in root.iter("arg")
            if not a.get("name").startswith("_")}
    assert tuple(args) == settings.WORLD_SETTINGS
    for name, default in args.items():
        own = SETTINGS[name].world_default     # the world alone's, where it differs
        assert default == (own if own is not None else SETTINGS[name].launch_default), name
    # the world alone runs freely, whatever its real-time factor (world_sim_time.test)
    assert args["pause_when_idle"] == "false"
    # its pre-flight (hrc_check --world) is given every one of them
    command = next(p.get("command") for p in root.iter("param") if "hrc_check" in
                   (p.get("command") or ""))
    given = re.findall(r"(\w+):=", command)
    assert sorted(given) == sorted(settings.WORLD_SETTINGS)


def test_the_table_covers_every_argument_of_hrc_launch_with_its_default():
    # Private derived arguments (_name) and computed defaults ($(eval ...)) aside.
    for arg in ET.parse(LAUNCH).getroot().iter("arg"):
        name = arg.get("name")
        if name.startswith("_"):
            continue
        assert name in SETTINGS, f"hrc.launch argument {name} has no setting"
        text = arg.get("default")
        if text is not None and "$(" not in text:
            assert settings.parse(name, text) == settings.parse(name, settings.default(name)) \
                or (text == "" and settings.default(name) in ("", None)), name


@pytest.mark.parametrize("name, value, line", [
    ("pomdp_port", "70000", "pomdp_port:=70000: must be an integer from 1 to 65535"),
    ("human_port", "abc", "human_port:=abc: must be an integer from 1 to 65535, got 'abc'"),
    ("pomdp_port", "0", "pomdp_port:=0: must be an integer from 1 to 65535"),
    ("pomdp_port", "80.5", "pomdp_port:=80.5: must be an integer from 1 to 65535, got '80.5'"),
    ("seed", "-1", "seed:=-1: must be an integer from 0 to 2147483647"),
    ("seed", "x", "seed:=x: must be an integer from 0 to 2147483647, got 'x'"),
    # Past int32 the ROS parameter server cannot carry it (roslaunch died with a traceback).
    ("seed", "2147483648", "seed:=2147483648: must be an integer from 0 to 2147483647"),
    ("seed", str(2**64), f"seed:={2**64}: must be an integer from 0 to 2147483647"),
    ("max_steps", str(2**40), f"max_steps:={2**40}: must be an integer from 0 to 2147483647"),
    ("max_trials", str(2**31), f"max_trials:={2**31}: must be an integer from 0 to 2147483647"),
    ("reactive_budget", str(2**31),
     f"reactive_budget:={2**31}: must be an integer from 0 to 2147483647"),
    ("step_delay", "-1", "step_delay:=-1: must be a number from 0 to 3600 (s)"),
    # time.sleep and queue timeouts overflow on such a delay
    ("step_delay", "1e300", "step_delay:=1e300: must be a number from 0 to 3600 (s)"),
    ("belt_speed", "-5", "belt_speed:=-5: must be a number from 0 to 0.5 (m/s)"),
    ("belt_speed", "0.6", "belt_speed:=0.6: must be a number from 0 to 0.5 (m/s)"),
    ("time_per_step", "-1", "time_per_step:=-1: must be 0 or a number from 0.001 to 60 (s)"),
    ("time_per_step", "0.0001", "time_per_step:=0.0001: must be 0 or a number from 0.001 to 60 (s)"),
    ("time_per_step", "61", "time_per_step:=61: must be 0 or a number from 0.001 to 60 (s)"),
    ("time_per_step", "nan", "time_per_step:=nan: must be 0 or a number from 0.001 to 60 (s), got 'nan'"),
    ("scenarios", "0", "scenarios:=0: must be an integer from 1 to 100000"),
    ("scenarios", "100001", "scenarios:=100001: must be an integer from 1 to 100000"),
    ("depth", "0", "depth:=0: must be an integer from 1 to 1000"),
    # a server that never cut off a client that stopped reading would hold its frames for good
    ("link_read_timeout", "0", "link_read_timeout:=0: must be a number > 0 and <= 3600 (s)"),
    ("lambda", "-0.1", "lambda:=-0.1: must be a number from 0 to 1000000"),
    ("max_trials", "-1", "max_trials:=-1: must be an integer from 0 to 2147483647"),
    ("reactive_budget", "-2", "reactive_budget:=-2: must be an integer from 0 to 2147483647"),
    ("max_steps", "-1", "max_steps:=-1: must be an integer from 0 to 2147483647"),
    ("real_time_factor", "-1", "real_time_factor:=-1: must be 0 or a number from 0.001 to 1000"),
    # the world would sleep longer per physics step than a clock can count
    ("real_time_factor", "1e-300",
     "real_time_factor:=1e-300: must be 0 or a number from 0.001 to 1000"),
    ("temperature", "0", "temperature:=0: must be a number > 0"),
    ("temperature", "nan", "temperature:=nan: must be a number > 0, got 'nan'"),
    ("manual_share", "0", "manual_share:=0: must be a number > 0 and <= 1"),
    ("manual_share", "1.5", "manual_share:=1.5: must be a number > 0 and <= 1"),
    ("mode", "semi", "mode:=semi: must be one of auto, manual"),
    ("planner", "bogus", "planner:=bogus: unknown planner 'bogus' (known: despot, policy, reactive, none, "
     "explore, or module:Class)"),
    ("planner", "despt", "planner:=despt: unknown planner 'despt'; did you mean despot? (known: despot, "
     "policy, reactive, none, explore, or module:Class)"),
    ("on_episode_end", "stop", "on_episode_end:=stop: must be one of wait, reset, continue"),
    ("human_choice", "greedy", "human_choice:=greedy: must be one of optimal, softmax, random"),
    ("gui", "maybe", "gui:=maybe: must be true or false (also 1/0, yes/no, on/off), got 'maybe'"),
    ("host", "999.1.1.1", "host:=999.1.1.1: must be an IPv4 or IPv6 address or a host name"),
    ("host", "bad host", "host:=bad host: must be an IPv4 or IPv6 address or a host name"),
    ("host", "-x.org", "host:=-x.org: must be an IPv4 or IPv6 address or a host name"),
])
def test_a_bad_value_is_one_line_naming_the_argument(name, value, line):
    text = refusal(name, value)
    assert text == line
    assert "\n" not in text


def test_a_setting_error_is_an_hrc_error_with_its_parts():
    with pytest.raises(HrcError) as info:
        settings.parse("pomdp_port", 70000)
    error = info.value
    assert isinstance(error, SettingError)
    assert (error.name, error.value) == ("pomdp_port", 70000)
    assert error.requirement == "must be an integer from 1 to 65535"


def test_numbers_and_python_values():
    assert settings.parse("seed", "  42 ") == 42
    assert settings.parse("seed", 7) == 7
    assert settings.parse("seed", str(2**31 - 1)) == 2**31 - 1
    assert settings.parse("pomdp_port", "65535") == 65535
    assert settings.parse("time_per_step", "60") == 60.0
    assert settings.parse("time_per_step", 1) == 1.0
    assert settings.parse("belt_speed", "0") == 0.0
    assert settings.parse("real_time_factor", "0") == 0.0
    assert settings.parse("lambda", "1e-3") == 0.001
    assert settings.parse("manual_share", "1") == 1.0
    with pytest.raises(SettingError,
                       match=r"^seed:=true: must be an integer from 0 to 2147483647, got 'true'$"):
        settings.parse("seed", True)
    with pytest.raises(SettingError):
        settings.parse("scenarios", 2.5)
    with pytest.raises(SettingError):
        settings.parse("time_per_step", "inf")


@pytest.mark.parametrize("word", ["true", "True", "TRUE", "1", "yes", "Yes", "on", "ON", True, 1])
def test_true_spellings(word):
    assert settings.parse("gui", word) is True


@pytest.mark.parametrize("word", ["false", "False", "0", "no", "NO", "off", "Off", False, 0])
def test_false_spellings(word):
    assert settings.parse("use_sim_time", word) is False


def test_hosts():
    for host in ("127.0.0.1", "0.0.0.0", "::1", "[::1]", "fe80::1", "localhost", "my-pc.lan",
                 "example.org."):
        assert settings.parse("host", host) == host
    with pytest.raises(SettingError):
        settings.parse("host", "a" * 64 + ".org")


def test_models_are_names_or_paths_checked_elsewhere():
    assert settings.parse("human_model", " tired ") == "tired"
    assert settings.parse("robot_model", "/tmp/x.pomdp") == "/tmp/x.pomdp"


def test_paths_are_made_absolute_against_the_directory_the_command_runs_in(tmp_path,
                                                                           monkeypatch):
    """The processes that use them run elsewhere (roslaunch starts them in $ROS_HOME): the
    entry point resolves every path once. Scenario names stay names."""
    folder = tmp_path / "my models é"
    folder.mkdir()
    (folder / "p.policy").write_bytes(b"x")
    monkeypatch.chdir(tmp_path)
    assert settings.parse("robot_model", "my models é/r.pomdp") == str(folder / "r.pomdp")
    assert settings.parse("human_model", "./tired.pomdpx") == str(tmp_path / "tired.pomdpx")
    assert settings.parse("human_model", "tired.pomdpx") == str(tmp_path / "tired.pomdpx")
    assert settings.parse("human_model", "tired") == "tired"
    assert settings.parse("policy_file", "my models é/p.policy") == str(folder / "p.policy")
    assert settings.parse("snapshot_dir", "shots") == str(tmp_path / "shots")
    monkeypatch.setenv("HOME", str(tmp_path))
    assert settings.parse("snapshot_dir", "~/shots") == str(tmp_path / "shots")
    assert settings.parse("snapshot_dir", "") == ""
    assert refusal("snapshot_dir", "my models é/p.policy").endswith("is not a directory")


def test_a_policy_file_must_be_readable(tmp_path):
    policy = tmp_path / "p.policy"
    policy.write_bytes(b"x")
    assert settings.parse("policy_file", str(policy)) == str(policy)
    missing = tmp_path / "none.policy"
    assert refusal("policy_file", str(missing)) == \
        f"policy_file:={missing}: no readable file there (looked for {missing})"
    assert "no readable file there" in refusal("policy_file", str(tmp_path))
    assert settings.parse("policy_file", "none") == ""   # the launch file's default


def test_unknown_names_are_refused_naming_them():
    assert refusal("belt_sped", "1").startswith(
        "belt_sped:=1: no such argument; did you mean belt_speed? known: ")
    with pytest.raises(SettingError, match=r"^belt_sped:=0.1: no such argument; did you mean "
                                           r"belt_speed\? known: human_model, "):
        settings.resolve({"belt_sped": "0.1"})
    with pytest.raises(SettingError, match="^foo, bar:=: no such arguments"):
        settings.resolve({"foo": "1", "bar": "2", "seed": "1"})
    with pytest.raises(SettingError):
        settings.default("nope")


def test_resolve_fills_every_default_in_table_order():
    config = settings.resolve({}, environ={"ROS_HOME": "/ros home"})
    assert list(config) == list(SETTINGS)
    expected = dict(DEFAULTS, pause_when_idle=False, mdp_xterm=False, away_time=0.0,
                    task_timeout=80.0, tasks=0, snapshot_dir="/ros home/hrc_snapshots",
                    learning_bonus=10.0)
    assert config == expected


@pytest.mark.parametrize("task, bonus", [("seed", 10.0), ("fabric", 10.0)])
def test_the_learning_bonus_is_the_tasks_unless_given(task, bonus):
    """learning_bonus:=auto is the bonus chosen for the task (docs/learning.md): a bonus
    tuned on one task's humans is not carried to another's."""
    assert settings.resolve({"task": task}, environ={})["learning_bonus"] == bonus
    assert settings.resolve({"task": task, "learning_bonus": "2.5"},
                            environ={})["learning_bonus"] == 2.5


def test_resolve_parses_what_is_given():
    config = settings.resolve({"seed": "3", "gui": "yes", "belt_speed": "0.1",
                               "human_model": "tired", "planner": "reactive"}, environ={})
    assert (config["seed"], config["gui"], config["belt_speed"]) == (3, True, 0.1)
    assert (config["human_model"], config["planner"]) == ("tired", "reactive")


def test_resolve_refuses_the_first_bad_value():
    with pytest.raises(SettingError, match=r"^pomdp_port:=70000: must be an integer"):
        settings.resolve({"seed": "1", "pomdp_port": "70000"})


def test_the_ports_must_differ():
    with pytest.raises(SettingError) as info:
        settings.resolve({"human_port": "7070"})
    assert str(info.value) == ("human_port:=7070: the same port as pomdp_port; the ports "
                               "must differ")
    with pytest.raises(SettingError, match="^human_port:=8080: the same port as pomdp_port"):
        settings.resolve({"pomdp_port": "8080", "human_port": "8080"})
    assert settings.resolve({"pomdp_port": "1", "human_port": "3"})


def test_a_policy_file_goes_with_planner_policy_and_only_with_it(tmp_path):
    with pytest.raises(SettingError) as info:
        settings.resolve({"planner": "policy"})
    assert str(info.value).startswith("policy_file:=: planner:=policy needs a policy file")
    policy = tmp_path / "p.policy"
    policy.write_bytes(b"x")
    config = settings.resolve({"planner": "policy", "policy_file": str(policy)})
    assert config["policy_file"] == str(policy)
    with pytest.raises(SettingError) as info:
        settings.resolve({"planner": "despot", "policy_file": str(policy)})
    assert str(info.value) == (f"policy_file:={policy}: only used with planner:=policy, "
                               "not planner:=despot")


def test_pause_when_idle_is_automatic_unless_given():
    assert settings.resolve({"real_time_factor": "0"})["pause_when_idle"] is True
    assert settings.resolve({"real_time_factor": "0.5"})["pause_when_idle"] is False
    assert settings.resolve({"real_time_factor": "0", "pause_when_idle": ""})[
        "pause_when_idle"] is True
    assert settings.resolve({"real_time_factor": "0", "pause_when_idle": "false"})[
        "pause_when_idle"] is False
    assert settings.resolve({"pause_when_idle": "true"})["pause_when_idle"] is True
    assert settings.resolve({"real_time_factor": "0", "pause_when_idle": "auto"})[
        "pause_when_idle"] is True


def test_manual_mode_pauses_the_world_while_a_state_is_typed_unless_told_otherwise():
    """Before: the world ran on between steps in manual mode, so the seed's 5, 6, 6 (Figures
    3.11-3.13) ended the episode before the third state was typed."""
    assert settings.resolve({"mode": "manual"})["pause_when_idle"] is True
    assert settings.resolve({"mode": "manual", "pause_when_idle": "auto"})[
        "pause_when_idle"] is True
    assert settings.resolve({"mode": "manual", "real_time_factor": "2"})[
        "pause_when_idle"] is True
    assert settings.resolve({"mode": "manual", "pause_when_idle": "false"})[
        "pause_when_idle"] is False
    assert settings.resolve({"mode": "auto"})["pause_when_idle"] is False


def test_mdp_xterm_is_automatic_in_manual_mode_with_a_display():
    assert settings.resolve({"mode": "manual"}, environ={"DISPLAY": ":0"})["mdp_xterm"] is True
    assert settings.resolve({"mode": "manual"}, environ={})["mdp_xterm"] is False
    assert settings.resolve({"mode": "auto"}, environ={"DISPLAY": ":0"})["mdp_xterm"] is False
    assert settings.resolve({"mdp_xterm": "no", "mode": "manual"},
                            environ={"DISPLAY": ":0"})["mdp_xterm"] is False


class Refused(Exception):
    pass


class RaisingParser(argparse.ArgumentParser):
    def error(self, message):
        raise Refused(message)


def test_add_argument_gives_the_flag_type_default_and_help():
    parser = RaisingParser()
    settings.add_argument(parser, "time_per_step")
    settings.add_argument(parser, "human_port")
    settings.add_argument(parser, "lambda", dest="lambda_")
    settings.add_argument(parser, "gui")
    settings.add_argument(parser, "planner", "-p")
    settings.add_argument(parser, "pause_when_idle")
    args = parser.parse_args([])
    assert (args.time_per_step, args.human_port, args.lambda_, args.gui, args.planner) == \
        (0.1, 9090, 0.1, False, "despot")
    assert args.pause_when_idle is None
    args = parser.parse_args(["--time-per-step", "0.5", "--human-port", "9091", "--lambda", "1",
                              "--gui", "yes", "-p", "reactive", "--pause-when-idle", "on"])
    assert (args.time_per_step, args.human_port, args.lambda_, args.gui, args.planner) == \
        (0.5, 9091, 1.0, True, "reactive")
    assert args.pause_when_idle is True
    assert parser.parse_args(["--time-per-step", ""]).time_per_step == 0.1   # empty: default
    help_text = parser.format_help()
    assert "DESPOT's time budget per decision (0: none, " in " ".join(help_text.split())
    assert "(default: 0.1 s)" in " ".join(help_text.split())
    assert "(default: 9090)" in help_text


@pytest.mark.parametrize("argv, message", [
    (["--time-per-step", "-1"], "argument --time-per-step: must be 0 or a number from 0.001 to 60 (s), "
                                "got '-1'"),
    (["--human-port", "70000"], "argument --human-port: must be an integer from 1 to 65535, "
                                "got '70000'"),
    (["--human-port", "abc"], "argument --human-port: must be an integer from 1 to 65535, "
                              "got 'abc'"),
])
def test_add_argument_errors_are_argparse_errors(argv, message):
    parser = RaisingParser()
    settings.add_argument(parser, "time_per_step")
    settings.add_argument(parser, "human_port")
    with pytest.raises(Refused) as info:
        parser.parse_args(argv)
    assert str(info.value) == message


def test_add_argument_kwargs_win():
    parser = RaisingParser()
    settings.add_argument(parser, "seed", default=5, help="x")
    assert parser.parse_args([]).seed == 5


def test_no_time_budget_needs_a_trial_cap():
    """time_per_step:=0 takes the clock out of DESPOT's decisions (experiments): the trials
    alone bound them, so there must be some."""
    assert settings.resolve({"time_per_step": "0", "max_trials": "600"}, environ={})[
        "time_per_step"] == 0.0
    with pytest.raises(SettingError, match=r"^time_per_step:=0: 0 \(no time budget\) needs "
                                           r"max_trials > 0"):
        settings.resolve({"time_per_step": "0"}, environ={})


@pytest.mark.parametrize("text, canonical", [
    ("live", "live"), ("", "live"), ("2,5-7", "2,5-7"), (" 7 , 0-3,5", "0-3,5,7"), ("4", "4")])
def test_episodes_is_live_or_a_schedule(text, canonical):
    assert settings.parse("episodes", text) == canonical


@pytest.mark.parametrize("text", ["-1", "a", "3-1", "1,,2", "5000000000"])
def test_a_bad_episode_schedule_is_one_line(text):
    assert refusal("episodes", text).startswith(
        f"episodes:={text}: must be live or episode numbers and ranges, e.g. 2,5-7")
