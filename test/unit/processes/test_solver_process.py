"""The solver processes' common options and start-up are one definition
(ros_hrc.processes.solver_process): both take the same options the same way, and both answer
what keeps them from starting in one line, exit status 2."""
import pytest

from ros_hrc.processes import despot_mdp, despot_pomdp
from ros_hrc.processes.solver_process import CANNOT_START, solver_parser, start_solver

PROCESSES = [(despot_mdp, "human_model", "human_port"),
             (despot_pomdp, "robot_model", "pomdp_port")]


def _options(parser):
    return {action.dest: action for action in parser._actions}


@pytest.mark.parametrize("process, model, port", PROCESSES, ids=lambda p: getattr(p, "NAME", p))
def test_each_solver_takes_the_common_options_as_the_shared_parser_makes_them(process, model,
                                                                              port):
    shared = _options(solver_parser(process.NAME, "", model, port))
    own = _options(process.build_parser())
    assert set(shared) <= set(own)
    for dest, action in shared.items():
        mine = own[dest]
        assert (mine.option_strings, mine.default, mine.help) == (
            action.option_strings, action.default, action.help), dest
    assert own[model].option_strings == ["--model"] and own[port].option_strings == ["--port"]


@pytest.mark.parametrize("process", [despot_mdp, despot_pomdp], ids=lambda p: p.NAME)
def test_a_solver_that_cannot_start_says_why_in_one_line(process, tmp_path, capsys,
                                                          monkeypatch):
    monkeypatch.delenv("HRC_LINK_TOKEN_FILE", raising=False)
    missing = tmp_path / "nowhere.pomdp"
    assert process.main(["--model", str(missing), "--token-file", str(tmp_path / "t")]) \
        == CANNOT_START == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{process.NAME}: ") and "nowhere" in err[0]


def test_the_token_is_read_after_what_the_process_is_built_from(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("HRC_LINK_TOKEN_FILE", raising=False)
    built = []
    parser = solver_parser("solver", "", "robot_model", "pomdp_port")
    assert start_solver("solver", parser, [], lambda args: built.append(args.seed)) is None
    assert built == [0]
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("solver: no link token")
    token = tmp_path / "token"
    token.write_text("ab" * 32 + "\n")
    token.chmod(0o600)
    started = start_solver("solver", parser, ["--token-file", str(token), "--seed", "7"],
                           lambda args: args.seed * 2)
    assert started.built == 14 and started.args.seed == 7 and started.token == "ab" * 32
