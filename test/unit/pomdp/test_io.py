"""Choosing the format by extension, exact conversions both ways, and the hrc_pomdp command."""
import json
from pathlib import Path

import pytest

from ros_hrc.errors import ModelFormatError
from ros_hrc.commands import pomdp as cli
from ros_hrc.pomdp import io

ROOT = Path(__file__).resolve().parents[3]
MODELS = sorted((ROOT / "models").glob("*/*.pomdp")) + sorted((ROOT / "models").glob("*/*.pomdpx"))
TIGER = ROOT / "test" / "fixtures" / "tiger.95.pomdp"


def test_the_repository_has_the_models_this_suite_converts():
    names = {p.name for p in MODELS}
    assert {"robot.pomdp", "robot.pomdpx", "humanModel.pomdpx"} <= names
    from ros_hrc.experiment.zoo import NOT_IN_ZOO, ZOO
    humans = {p.stem for p in MODELS if p.parent.name == "human"}
    assert humans == set(ZOO) | set(NOT_IN_ZOO)


# -- extension ---------------------------------------------------------------------------------------
def test_the_parser_is_chosen_by_extension_in_any_case(tmp_path):
    upper = tmp_path / "humanModel.POMDPx"          # as the seed spells it
    upper.write_bytes((ROOT / "models/human/humanModel.pomdpx").read_bytes())
    assert io.load_model(upper).fully_observable
    assert io.format_of(TIGER) == "Cassandra" and io.format_of(upper) == "POMDPX"


def test_an_unknown_extension_is_a_clear_error(tmp_path):
    path = tmp_path / "model.txt"
    path.write_text("discount: 0.9\n")
    with pytest.raises(ModelFormatError) as info:
        io.load_model(path)
    assert info.value.path == str(path) and "expected .pomdp (Cassandra) or .pomdpx" in info.value.what
    with pytest.raises(ModelFormatError):
        io.save_model(io.load_model(TIGER), tmp_path / "out.xml")
    assert not (tmp_path / "out.xml").exists()


# -- round trips ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("path", MODELS + [TIGER], ids=lambda p: p.name)
def test_conversion_both_ways_keeps_every_table_exactly(path, tmp_path):
    original = io.load_model(path)
    other = ".pomdpx" if path.suffix == ".pomdp" else ".pomdp"
    there = tmp_path / f"there{other}"
    back = tmp_path / f"back{path.suffix}"
    io.convert(path, there)
    io.convert(there, back)
    assert io.differences(original, io.load_model(there)) == []
    assert io.differences(original, io.load_model(back)) == []
    # and once more, from the converted file: cassandra -> pomdpx -> cassandra -> pomdpx
    again = tmp_path / f"again{other}"
    io.convert(back, again)
    assert io.differences(original, io.load_model(again)) == []


def test_differences_reports_what_changed():
    a, b = io.load_model(TIGER), io.load_model(TIGER)
    b.discount = 0.9
    b.T[0] = b.T[0] * 0.5
    found = io.differences(a, b)
    assert any("discount" in d for d in found) and any("T[listen]" in d for d in found)


# -- the command ----------------------------------------------------------------------------------------
def test_info_prints_sizes_kind_discount_and_checks(capsys):
    assert cli.run(["info", str(ROOT / "models/robot/robot.pomdp")]) == 0
    out = capsys.readouterr().out
    for words in ("Cassandra", "POMDP", "states        7", "observations  15", "discount      0.9",
                  "checks passed"):
        assert words in out, out


def test_info_json_is_one_object(capsys):
    assert cli.run(["info", str(ROOT / "models/human/humanModel.pomdpx"), "--json"]) == 0
    out = capsys.readouterr().out
    facts = json.loads(out)
    assert out.count("\n") == 1
    assert (facts["states"], facts["actions"], facts["observations"]) == (8, 5, 8)
    assert facts["kind"] == "MDP" and facts["discount"] == 0.98 and facts["checks_passed"]


def test_convert_writes_the_other_format(tmp_path, capsys):
    out = tmp_path / "tiger.pomdpx"
    assert cli.run(["convert", str(TIGER), str(out)]) == 0
    assert io.differences(io.load_model(TIGER), io.load_model(out)) == []
    assert "tiger.pomdpx" in capsys.readouterr().out


@pytest.mark.parametrize("content, name, where", [
    ("discount: 0.9\nstates: 2\nactions: 1\nobservations: 1\nT: * : 0\n0.5 0.6\n", "bad.pomdp", ":5: "),
    ("<pomdpx><Discount>0.9</Discount>\n<Variable>", "bad.pomdpx", ":2: "),
    ("anything", "bad.txt", ": unknown model format"),
])
def test_a_bad_model_gives_one_line_and_status_2(tmp_path, capsys, content, name, where):
    path = tmp_path / name
    path.write_text(content)
    assert cli.run(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"hrc_pomdp: {path}{where}"), err


def test_a_missing_file_and_a_bad_target_give_status_2(tmp_path, capsys):
    assert cli.run(["info", str(tmp_path / "nowhere.pomdp")]) == 2
    assert "cannot read the file" in capsys.readouterr().err
    assert cli.run(["convert", str(TIGER), str(tmp_path / "out.json")]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert not (tmp_path / "out.json").exists()


def test_a_wrong_command_line_gives_status_2(capsys):
    assert cli.run(["info"]) == 2
    assert cli.run(["frobnicate"]) == 2
    assert "usage" in capsys.readouterr().err


def test_progress_is_shown_only_on_a_terminal(capsys):
    cli.progress("working")
    assert capsys.readouterr().err == ""           # captured stderr is not a terminal


def test_subcommands_register_through_one_list():
    parser = cli.build_parser()
    assert {"info", "convert"} <= set(parser._subparsers._group_actions[0].choices)
    assert cli._register_info in cli.SUBCOMMANDS and cli._register_convert in cli.SUBCOMMANDS
