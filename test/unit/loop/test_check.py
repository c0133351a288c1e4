"""hrc_check, the launch's pre-flight: good arguments give the whole configuration as YAML and
exit 0; any bad one gives exactly one line on stderr naming the argument or the file, exit 2,
and never a traceback."""
import socket
from pathlib import Path

import pytest
import yaml

from ros_hrc.link.transport import free_port
from ros_hrc import settings
from ros_hrc.commands.check import CheckError, check, check_display, main, parse_words
from in_process import run_main

ROOT = Path(__file__).resolve().parents[3]
SCRIPT = ROOT / "scripts" / "hrc_check"


def run(*words):
    """hrc_check's ``main`` on ``words``, in-process: (exit status, stdout, stderr). Its script
    and roslaunch's run of it: test/integration/loop/test_launch_arguments.py and
    test_launch_refuses.py."""
    return run_main(main, words)


def free_ports():
    ports = set()
    while len(ports) < 2:
        ports.add(free_port())
    return dict(zip(("pomdp_port", "human_port"), sorted(ports)))


def refused(*words):
    """The one stderr line of a refused check."""
    status, out, err = run(*words)
    assert status == 2, err
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hrc.launch: ")
    assert "Traceback" not in err
    return lines[0]


def test_good_arguments_give_the_whole_configuration_as_yaml():
    ports = free_ports()
    status, out, err = run("human_model:=tired", "seed:=3", "real_time_factor:=0",
                           *(f"{k}:={v}" for k, v in ports.items()))
    assert status == 0, err
    assert err == ""
    config = yaml.safe_load(out)
    assert list(config) == list(settings.SETTINGS)
    assert config["human_model"] == "tired" and config["seed"] == 3
    assert config["pause_when_idle"] is True            # automatic with real_time_factor 0
    assert {k: config[k] for k in ports} == ports
    for name in ("robot_model", "planner", "time_per_step", "scenarios", "depth", "lambda",
                 "belt_speed", "step_delay", "on_episode_end", "host", "policy_file"):
        assert config[name] == settings.default(name), name


def test_without_arguments_every_default(capsys):
    assert main(["--no-port-check"]) == 0
    config = yaml.safe_load(capsys.readouterr().out)
    assert config["time_per_step"] == 0.1
    assert config["human_model"] == "humanModel" and config["robot_model"] == "robot"
    assert (config["pomdp_port"], config["human_port"]) == (7070, 9090)


@pytest.mark.parametrize("word, line", [
    ("human_model:=does_not_exist", "hrc.launch: human_model:=does_not_exist: no human model "
                                    "named 'does_not_exist'"),
    ("pomdp_port:=70000", "hrc.launch: pomdp_port:=70000: must be an integer from 1 to 65535"),
    ("human_port:=abc", "hrc.launch: human_port:=abc: must be an integer from 1 to 65535, "
                        "got 'abc'"),
    ("planner:=bogus", "hrc.launch: planner:=bogus: unknown planner 'bogus' (known: despot, policy, reactive, none, "
     "explore"),
    ("time_per_step:=-1", "hrc.launch: time_per_step:=-1: must be 0 or a number from 0.001 to 60 (s)"),
    ("scenarios:=0", "hrc.launch: scenarios:=0: must be an integer from 1 to 100000"),
    ("step_delay:=-1", "hrc.launch: step_delay:=-1: must be a number from 0 to 3600 (s)"),
    ("belt_speed:=-5", "hrc.launch: belt_speed:=-5: must be a number from 0 to 0.5 (m/s)"),
    ("seed:=-1", "hrc.launch: seed:=-1: must be an integer from 0 to 2147483647"),
    ("on_episode_end:=never", "hrc.launch: on_episode_end:=never: must be one of wait, reset, "
                              "continue"),
    ("bogus_argument:=1", "hrc.launch: bogus_argument:=1: no such argument; known: human_model, "),
    ("planner:=policy", "hrc.launch: policy_file:=: planner:=policy needs a policy file"),
    ("robot_model:=tired", "hrc.launch: robot_model:=tired: no robot model named 'tired'"),
    ("human_port:=7070", "hrc.launch: human_port:=7070: the same port as pomdp_port"),
    ("not-a-setting", "hrc.launch: 'not-a-setting': expected name:=value"),
])
def test_a_bad_argument_is_one_line_naming_it(word, line):
    assert refused("--no-port-check", word).startswith(line)


def test_a_truncated_robot_model_is_one_line_naming_the_file(tmp_path):
    cut = tmp_path / "cut.pomdpx"
    cut.write_text((ROOT / "models" / "robot" / "robot.pomdpx").read_text()[:3000])
    assert refused("--no-port-check", f"robot_model:={cut}").startswith(f"hrc.launch: {cut}:")
    cut = tmp_path / "cut.pomdp"
    text = (ROOT / "models" / "robot" / "robot.pomdp").read_text().splitlines()
    cut.write_text("\n".join(text[:len(text) // 2]) + "\n")
    assert refused("--no-port-check", f"robot_model:={cut}").startswith(f"hrc.launch: {cut}")


def test_a_robot_model_with_other_observation_names_is_refused(tmp_path):
    bad = tmp_path / "o36.pomdp"
    bad.write_text((ROOT / "models" / "robot" / "robot.pomdp").read_text().replace("O35", "O36"))
    assert refused("--no-port-check", f"robot_model:={bad}") == (
        f"hrc.launch: {bad}: observations O36 are not the task's observations (missing: O35)")


def test_a_bad_policy_file_for_planner_policy_is_refused(tmp_path):
    policy = tmp_path / "p.policy"
    policy.write_text("not a policy")
    line = refused("--no-port-check", "planner:=policy", f"policy_file:={policy}")
    assert line.startswith(f"hrc.launch: policy_file:={policy}: ")


def test_a_port_in_use_is_one_line_naming_it():
    ports = free_ports()
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        taken = busy.getsockname()[1]
        ports["human_port"] = taken
        line = refused(*(f"{k}:={v}" for k, v in ports.items()))
    assert line.startswith(f"hrc.launch: human_port:={taken}: port {taken} is already in use "
                           "on 127.0.0.1")


def test_the_pomdp_port_may_be_served_already_when_the_pomdp_process_runs_by_hand():
    ports = free_ports()
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        ports["pomdp_port"] = busy.getsockname()[1]
        words = [f"{k}:={v}" for k, v in ports.items()]
        assert run(*words, "start_pomdp:=false")[0] == 0
        assert refused(*words).startswith(f"hrc.launch: pomdp_port:={ports['pomdp_port']}: ")


def test_a_host_that_is_not_this_machine_is_refused():
    # TEST-NET-1 (RFC 5737): never an address of this machine.
    line = refused(*(f"{k}:={v}" for k, v in free_ports().items()), "host:=192.0.2.1")
    assert line.startswith("hrc.launch: host:=192.0.2.1: cannot bind port ")


def test_the_words_are_name_value_pairs():
    assert parse_words(["a:=1", "b:=", "c:=x:=y"]) == {"a": "1", "b": "", "c": "x:=y"}
    assert check(["seed:=1", "human_model:=expert"], port_check=False)["seed"] == 1


def test_the_script_is_an_executable_shim():
    assert SCRIPT.stat().st_mode & 0o111
    assert "ros_hrc.commands.check" in SCRIPT.read_text()
    assert len(SCRIPT.read_text().strip().splitlines()) <= 4


def test_a_link_session_makes_the_launch_s_private_token_once_every_check_passed(
        tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("ROS_HOME", str(tmp_path))
    assert main(["--no-port-check", "start_pomdp:=false", "--link-session=hrc_link_t1"]) == 0
    out, err = capsys.readouterr()
    token_file = tmp_path / "ros_hrc" / "links" / "hrc_link_t1.token"
    assert yaml.safe_load(out)["token_file"] == str(token_file)
    assert oct(token_file.stat().st_mode & 0o777) == "0o600"
    # The secret is in the file only: not in the configuration, not on the terminal.
    token = token_file.read_text().split()[0]
    assert token not in out and token not in err
    assert err.splitlines() == [f"hrc.launch: run despot_pomdp by hand: rosrun ros_hrc "
                                f"despot_pomdp --model robot --host 127.0.0.1 --port 7070 "
                                f"--token-file {token_file}"]
    # A refused launch makes no token.
    assert main(["--no-port-check", "seed:=-1", "--link-session=hrc_link_t2"]) == 2
    assert not (tmp_path / "ros_hrc" / "links" / "hrc_link_t2.token").exists()


def test_world_mode_checks_and_prints_only_the_world_s_arguments(capsys):
    assert main(["--world", "seed:=4", "belt_speed:=0.1"]) == 0
    assert yaml.safe_load(capsys.readouterr().out) == {"seed": 4, "belt_speed": 0.1}
    assert main(["--world", "seed:=-1"]) == 2
    assert capsys.readouterr().err == ("world.launch: seed:=-1: must be an integer from 0 to "
                                       "2147483647\n")


@pytest.mark.parametrize("word, line", [
    (f"seed:={2**31}", f"world.launch: seed:={2**31}: must be an integer from 0 to 2147483647"),
    ("real_time_factor:=-1",
     "world.launch: real_time_factor:=-1: must be 0 or a number from 0.001 to 1000"),
    ("camera_rate:=nan", "world.launch: camera_rate:=nan: must be a number from 0 to 30"),
    ("belt_speed:=fast", "world.launch: belt_speed:=fast"),
])
def test_world_mode_refuses_a_bad_world_argument_in_one_line(word, line, capsys):
    assert main(["--world", word]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(line), err


def test_world_mode_needs_a_display_that_answers_for_rviz(monkeypatch, capsys):
    number = next(n for n in range(190, 290) if not Path(f"/tmp/.X11-unix/X{n}").exists())
    monkeypatch.setenv("DISPLAY", f":{number}")
    assert main(["--world", "rviz:=true"]) == 2
    assert capsys.readouterr().err.startswith("world.launch: rviz:=true: needs a display")


def test_world_mode_decides_pause_when_idle_from_the_loop_s_mode(capsys):
    assert main(["--world", "pause_when_idle:=auto", "mode:=manual"]) == 0
    assert yaml.safe_load(capsys.readouterr().out)["pause_when_idle"] is True
    assert main(["--world", "pause_when_idle:=auto", "mode:=auto"]) == 0
    assert yaml.safe_load(capsys.readouterr().out)["pause_when_idle"] is False


def test_every_path_is_made_absolute_where_the_check_runs(tmp_path, monkeypatch, capsys):
    """The processes of the launch run in $ROS_HOME: they get only absolute paths."""
    root = tmp_path / "my models é"
    root.mkdir()
    (root / "r.pomdp").write_text((ROOT / "models" / "robot" / "robot.pomdp").read_text())
    (root / "h.pomdpx").write_text((ROOT / "models" / "human" / "tired.pomdpx").read_text())
    monkeypatch.chdir(root)
    assert main(["--no-port-check", "robot_model:=./r.pomdp", "human_model:=h.pomdpx",
                 "snapshot_dir:=../shots"]) == 0
    config = yaml.safe_load(capsys.readouterr().out)
    assert config["robot_model"] == str(root / "r.pomdp")
    assert config["human_model"] == str(root / "h.pomdpx")
    assert config["snapshot_dir"] == str(tmp_path / "shots")


@pytest.mark.parametrize("world", [[], ["--world"]], ids=["hrc.launch", "world.launch"])
def test_an_empty_snapshot_dir_is_printed_as_the_folder_it_stands_for(tmp_path, monkeypatch,
                                                                       capsys, world):
    """The doc says empty is $ROS_HOME/hrc_snapshots: the configuration printed says which."""
    monkeypatch.setenv("ROS_HOME", str(tmp_path / "ros home"))
    assert main(world + ["--no-port-check", "snapshot_dir:="]) == 0
    config = yaml.safe_load(capsys.readouterr().out)
    assert config["snapshot_dir"] == str(tmp_path / "ros home" / "hrc_snapshots")
    monkeypatch.delenv("ROS_HOME")
    monkeypatch.setenv("HOME", str(tmp_path))
    assert main(world + ["--no-port-check", "snapshot_dir:="]) == 0
    assert yaml.safe_load(capsys.readouterr().out)["snapshot_dir"] == str(
        tmp_path / ".ros" / "hrc_snapshots")


def test_a_window_needs_a_display_that_answers(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    for name in ("gui", "rviz"):
        assert refused("--no-port-check", f"{name}:=true") == (
            f"hrc.launch: {name}:=true: needs a display, but DISPLAY is not set (run it on a "
            f"desktop or under Xvfb, or leave {name}:=false)")
    with pytest.raises(CheckError, match="DISPLAY=nonsense is not a display name"):
        check_display({"gui": True}, {"DISPLAY": "nonsense"})
    with socket.socket() as unused:       # a port nobody listens on: display number - 6000
        unused.bind(("127.0.0.1", 0))
        port = unused.getsockname()[1]
    if port > 6000:
        with pytest.raises(CheckError, match="no X server answers on DISPLAY=127.0.0.1:"):
            check_display({"rviz": True}, {"DISPLAY": f"127.0.0.1:{port - 6000}"})
    check_display({"gui": False, "rviz": False}, {})      # no window: no display needed


def test_the_session_s_settings_beside_its_token_are_the_solver_s_options(
        tmp_path, monkeypatch, capsys):
    """What a solver given --link-session runs with: the check's resolved settings, paths
    absolute (it runs in $ROS_HOME, not where the user typed them); its own options win."""
    from ros_hrc.command_line import parse_launch_options
    from ros_hrc.processes import despot_mdp, despot_pomdp

    monkeypatch.setenv("ROS_HOME", str(tmp_path / "home"))
    (tmp_path / "r.pomdp").write_text((ROOT / "models" / "robot" / "robot.pomdp").read_text())
    monkeypatch.chdir(tmp_path)
    assert main(["--no-port-check", "robot_model:=r.pomdp", "seed:=9", "mode:=manual",
                 "human_port:=9191", "--link-session=hrc_link_t3"]) == 0
    capsys.readouterr()
    monkeypatch.chdir(tmp_path / "home")
    pomdp = parse_launch_options(despot_pomdp.build_parser(),
                                 ["--link-session=hrc_link_t3", "__name:=despot_pomdp"])
    assert (pomdp.robot_model, pomdp.seed) == (str(tmp_path / "r.pomdp"), 9)
    mdp = parse_launch_options(despot_mdp.build_parser(),
                               ["--link-session=hrc_link_t3", "--seed=4"])
    assert (mdp.human_model, mdp.mode, mdp.human_port, mdp.seed) == \
        ("humanModel", "manual", 9191, 4)
    with pytest.raises(SystemExit):
        parse_launch_options(despot_mdp.build_parser(), ["--link-session=hrc_link_none"])
    assert "no settings for link session hrc_link_none" in capsys.readouterr().err


def test_the_printed_hand_run_command_is_one_the_solver_takes(tmp_path, monkeypatch, capsys):
    """Before: it gave only --token-file, not the port, host or model of this launch."""
    import shlex

    from ros_hrc.command_line import parse_launch_options
    from ros_hrc.processes import despot_mdp, despot_pomdp

    monkeypatch.setenv("ROS_HOME", str(tmp_path))
    folder = tmp_path / "my models"
    folder.mkdir()
    (folder / "r.pomdp").write_text((ROOT / "models" / "robot" / "robot.pomdp").read_text())
    monkeypatch.chdir(tmp_path)
    assert main(["--no-port-check", "start_mdp:=false", "start_pomdp:=false", "mode:=manual",
                 "human_port:=9393", "robot_model:=my models/r.pomdp", "planner:=reactive",
                 "--link-session=hrc_link_t4"]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 2
    commands = {}
    for line in lines:
        head, _, command = line.partition(" by hand: ")
        words = shlex.split(command)
        assert words[:2] == ["rosrun", "ros_hrc"]
        commands[words[2]] = words[3:]
    mdp = parse_launch_options(despot_mdp.build_parser(), commands["despot_mdp"])
    assert (mdp.human_port, mdp.host, mdp.mode, mdp.human_model) == \
        (9393, "127.0.0.1", "manual", "humanModel")
    assert mdp.token_file == str(tmp_path / "ros_hrc" / "links" / "hrc_link_t4.token")
    pomdp = parse_launch_options(despot_pomdp.build_parser(), commands["despot_pomdp"])
    assert (pomdp.pomdp_port, pomdp.planner, pomdp.robot_model) == \
        (7070, "reactive", str(folder / "r.pomdp"))


# -- the task (issue #22) -----------------------------------------------------------------------

def test_task_fabric_runs_its_own_models_by_default(capsys):
    assert main(["--no-port-check", "task:=fabric"]) == 0
    config = yaml.safe_load(capsys.readouterr().out)
    assert (config["task"], config["human_model"], config["robot_model"]) == (
        "fabric", "beginner_nontired_collaborative", "base")
    assert main(["--no-port-check", "task:=fabric", "human_model:=auto",
                 "robot_model:=policy3"]) == 0
    config = yaml.safe_load(capsys.readouterr().out)
    assert (config["human_model"], config["robot_model"]) == (
        "beginner_nontired_collaborative", "policy3")


def test_task_fabric_takes_its_reactive_robot_and_its_wait(capsys):
    """planner:=reactive with task:=fabric is fabric's reactive MDP robot (it was refused
    while only the seed had one); reactive_wait is its wait in simulated seconds."""
    assert main(["--no-port-check", "task:=fabric", "planner:=reactive"]) == 0
    config = yaml.safe_load(capsys.readouterr().out)
    assert (config["planner"], config["reactive_wait"]) == ("reactive", 15.0)
    assert main(["--no-port-check", "task:=fabric", "planner:=reactive",
                 "reactive_wait:=7.5"]) == 0
    assert yaml.safe_load(capsys.readouterr().out)["reactive_wait"] == 7.5
    said = refused("--no-port-check", "task:=fabric", "planner:=reactive", "reactive_wait:=-1")
    assert said.startswith("hrc.launch: reactive_wait:=-1: "), said


SEED_ROBOT = ROOT / "models" / "robot" / "robot.pomdp"
FABRIC_ROBOT = ROOT / "models" / "fabric" / "robot" / "base.pomdpx"


@pytest.mark.parametrize("words, line", [
    (("task:=fabric", f"robot_model:={SEED_ROBOT}"),
     f"hrc.launch: {SEED_ROBOT.relative_to(ROOT)}: states S0, S1, S2, S3, S4, S5, S6 are not "
     "task fabric's states (missing: TaskHuman, "),
    ((f"robot_model:={FABRIC_ROBOT}",),
     f"hrc.launch: {FABRIC_ROBOT.relative_to(ROOT)}: states TaskHuman, "),
    (("task:=fabric", "human_model:=humanModel"),
     "hrc.launch: human_model:=humanModel: no human model named 'humanModel' in "),
    (("task:=seeds",), "hrc.launch: task:=seeds: must be one of seed, fabric"),
])
def test_a_model_of_another_task_is_refused_in_one_line(words, line):
    said = refused("--no-port-check", *words)
    assert said.startswith(line), said
    if "robot_model" in words[-1]:
        other = "seed" if "task:=fabric" in words else "fabric"
        assert said.endswith(f"; it is a model of task {other} (task:={other})"), said


@pytest.mark.parametrize("words, hint", [
    (("human_model:=tierd",), "human_model:=tierd: no human model named 'tierd' in "
                              f"{ROOT / 'models' / 'human'}; did you mean tired? known: beginner, "),
    (("task:=fabric", "robot_model:=bse"), "did you mean base? known: "),
    (("human_modle:=tired",), "human_modle:=tired: no such argument; did you mean human_model? "
                              "known: human_model, "),
    (("tasks:=2", "schedule:=tierd*2"), "unknown human type 'tierd'; did you mean tired? known:"),
])
def test_a_mistyped_name_is_refused_with_the_nearest_known_one(words, hint):
    # As a mistyped launch argument is (commands/launch_arguments.py): one hint, difflib's.
    said = refused("--no-port-check", *words)
    assert hint in said, said
    assert "\n" not in said.strip()


def test_the_hand_run_commands_carry_the_task(tmp_path, monkeypatch, capsys):
    import shlex

    from ros_hrc.command_line import parse_launch_options
    from ros_hrc.processes import despot_mdp, despot_pomdp

    monkeypatch.setenv("ROS_HOME", str(tmp_path))
    assert main(["--no-port-check", "task:=fabric", "start_mdp:=false", "start_pomdp:=false",
                 "--link-session=hrc_link_t5"]) == 0
    commands = {}
    for line in capsys.readouterr().err.splitlines():
        words = shlex.split(line.partition(" by hand: ")[2])
        commands[words[2]] = words[3:]
    mdp = parse_launch_options(despot_mdp.build_parser(), commands["despot_mdp"])
    pomdp = parse_launch_options(despot_pomdp.build_parser(), commands["despot_pomdp"])
    assert (mdp.task, mdp.human_model) == ("fabric", "beginner_nontired_collaborative")
    assert (pomdp.task, pomdp.robot_model) == ("fabric", "base")
