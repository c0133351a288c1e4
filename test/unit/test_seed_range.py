"""The seed has one range, ros_hrc.streams.MAX_SEED (the ROS parameter server's int), at every
door that takes one: the largest is accepted, one more is refused in one line that says the
range, before anything runs."""
import pytest

from ros_hrc import settings, streams
from ros_hrc.commands import check
from ros_hrc.commands.pomdp import build_parser as pomdp_parser
from ros_hrc.experiment import cli, fit, perturbed_humans, train_selector
from ros_hrc.processes import despot_mdp, despot_pomdp
from ros_hrc.settings import SettingError

TOP = streams.MAX_SEED
RANGE = f"must be an integer from 0 to {TOP}"
TIGER = "test/fixtures/tiger.95.pomdp"


def test_the_one_range_is_the_parameter_servers_int():
    assert TOP == 2**31 - 1 == settings.INT32_MAX
    assert settings.SETTINGS["seed"].maximum == TOP


def test_the_streams_take_the_largest_and_refuse_one_more():
    assert streams.stream_seed(TOP, 0, "human") >= 0
    with pytest.raises(ValueError) as refused:
        streams.stream(TOP + 1, 0, "human")
    assert str(refused.value) == f"seed {RANGE}, got {TOP + 1}"


def test_the_launch_argument_takes_the_largest_and_refuses_one_more(capsys):
    assert settings.parse("seed", str(TOP)) == TOP
    with pytest.raises(SettingError) as refused:
        settings.parse("seed", str(TOP + 1))
    assert str(refused.value) == f"seed:={TOP + 1}: {RANGE}"
    # the pre-flight (world.launch's: no models, no ports)
    assert check.main(["--world", f"seed:={TOP}"]) == 0
    capsys.readouterr()
    assert check.main(["--world", f"seed:={TOP + 1}"]) == 2
    assert capsys.readouterr().err == f"world.launch: seed:={TOP + 1}: {RANGE}\n"


#: (name, parser, the words before --seed) of every program with a seed option.
PARSERS = [
    ("despot_mdp", despot_mdp.build_parser, "--seed", []),
    ("despot_pomdp", despot_pomdp.build_parser, "--seed", []),
    ("hrc_experiment", cli.build_parser, "--seeds", []),
    ("hrc_train_selector", train_selector.build_parser, "--seeds", []),
    ("hrc_fit", fit.build_parser, "--seed", []),
    ("hrc_perturb_humans", perturbed_humans.build_parser, "--seed", ["--out", "x"]),
    ("hrc_pomdp simulate", pomdp_parser, "--seed",
     ["simulate", TIGER, "--planner", "mdp", "--sim-len", "1", "--sim-num", "1"]),
    ("hrc_pomdp policy", pomdp_parser, "--seed", ["policy", "robot"]),
]


@pytest.mark.parametrize("name, parser, option, words", PARSERS, ids=[p[0] for p in PARSERS])
def test_every_seed_option_takes_the_largest_and_refuses_one_more(name, parser, option, words,
                                                                   capsys):
    args = parser().parse_args(words + [option, str(TOP)])
    value = getattr(args, option.lstrip("-"))
    assert value == ([TOP] if option == "--seeds" else TOP)
    with pytest.raises(SystemExit) as refused:
        parser().parse_args(words + [option, str(TOP + 1)])
    assert refused.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"argument {option}: " in last and RANGE in last and str(TOP + 1) in last, last
