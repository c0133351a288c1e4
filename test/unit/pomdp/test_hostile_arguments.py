"""Hostile command lines (failure 3) and the help texts (failure 5).

Every bad number of every subcommand is argparse's error: the usage line, then
``hrc_pomdp <command>: error: argument <option>: ...``, exit status 2, no traceback, nothing run.
"""
from pathlib import Path

import pytest

from ros_hrc.commands.pomdp import build_parser, run

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
TIGER = str(FIXTURES / "tiger.95.pomdp")

SOLVE = ["solve", TIGER]
SIMULATE = ["simulate", TIGER, "--planner", "despot", "--max-trials", "1", "--sim-len", "1",
            "--sim-num", "1"]
INFO = ["info", TIGER]
CONVERT = ["convert", TIGER, "out.pomdpx"]

NOT_FINITE = ["nan", "inf", "-inf", "NaN", "Infinity"]

#: (command, option, values it must refuse): non-finite, negative where meaningless, too large.
BAD = [
    (SOLVE, "--timeout", NOT_FINITE + ["-1", "1e7"]),
    (SOLVE, "--precision", NOT_FINITE + ["0", "-0.1", "1e200"]),
    (SIMULATE, "--sim-len", NOT_FINITE + ["0", "-3", "1.5", "10000001"]),
    (SIMULATE, "--sim-num", NOT_FINITE + ["0", "-3", "10000001"]),
    (SIMULATE, "--seed", NOT_FINITE + ["-1", "1e3", str(2**31), str(2**64)]),
    (SIMULATE, "--time-per-step", NOT_FINITE + ["-0.5", "0.0005", "61", "1e9"]),
    (SIMULATE, "--scenarios", NOT_FINITE + ["0", "-1", "100001", "1000000001"]),
    (SIMULATE, "--depth", NOT_FINITE + ["-1", "0", "1001", "1000000000"]),
    (SIMULATE, "--lambda", NOT_FINITE + ["-0.1", "1e300"]),
    (SIMULATE, "--xi", NOT_FINITE + ["-0.1", "1.5"]),
    (SIMULATE, "--max-trials", NOT_FINITE + ["-1", "1e3", str(2**31), "10" * 20]),
    (SIMULATE, "--particles", NOT_FINITE + ["0", "-5", "100000000000"]),
] + [(command, "--memory-limit", NOT_FINITE + ["0", "-1G", "512K", "5Q", "2P"])
     for command in (INFO, CONVERT, SOLVE, SIMULATE)]


def _cases():
    for command, option, values in BAD:
        for value in values:
            yield pytest.param(command, option, value, id=f"{command[0]} {option} {value}")


def _assert_argparse_error(capsys, argv, command: str, option: str) -> None:
    assert run(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    err = captured.err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert lines[0].startswith(f"usage: hrc_pomdp {command} "), err
    assert lines[-1].startswith(f"hrc_pomdp {command}: error: argument {option}: "), err


@pytest.mark.parametrize("command, option, value", list(_cases()))
def test_a_bad_number_is_an_argparse_error(capsys, tmp_path, monkeypatch, command, option,
                                           value):
    monkeypatch.chdir(tmp_path)
    # "--memory-limit 1G" last, when the option under test is another: a command line that a
    # parser without that option accepts is refused before any work starts (nothing runs).
    tail = [] if option == "--memory-limit" else ["--memory-limit", "1G"]
    _assert_argparse_error(capsys, command + [option, value] + tail, command[0], option)
    assert not (tmp_path / "out.pomdpx").exists()


def test_a_negative_seed_is_an_argparse_error(capsys):
    _assert_argparse_error(capsys, SIMULATE + ["--seed", "-1"], "simulate", "--seed")


def test_a_timeout_that_is_not_a_number_is_an_argparse_error(capsys):
    _assert_argparse_error(capsys, SOLVE + ["--timeout", "nan"], "solve", "--timeout")


def test_too_many_steps_in_all_is_an_argparse_error(capsys):
    argv = ["simulate", TIGER, "--planner", "despot", "--sim-len", "100000", "--sim-num",
            "1000", "--memory-limit", "1G"]
    _assert_argparse_error(capsys, argv, "simulate", "--sim-num")


@pytest.mark.parametrize("text, size", [("512M", 512 << 20), ("4G", 4 << 30), ("2048", 2 << 30),
                                        ("1.5GiB", 3 << 29), ("1T", 1 << 40)])
def test_memory_sizes_read_with_units_and_plain_numbers_are_mib(text, size):
    args = build_parser().parse_args(["info", TIGER, "--memory-limit", text])
    assert args.memory_limit == size


def test_the_largest_good_numbers_are_accepted():
    args = build_parser().parse_args(SIMULATE + ["--seed", str(2**31 - 1), "--xi", "1",
                                                 "--time-per-step", "0", "--depth", "1000"])
    assert args.seed == 2**31 - 1 and args.xi == 1.0 and args.depth == 1000


# -- help (failure 5) -----------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [["--help"], ["info", "--help"], ["convert", "--help"],
                                  ["solve", "--help"], ["simulate", "--help"]])
def test_help_shows_a_single_percent_sign(capsys, argv):
    assert run(argv) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: hrc_pomdp")
    assert "%%" not in out and "%(" not in out
    if argv[0] == "simulate":
        assert "95 % confidence interval" in " ".join(out.split())
