"""Hostile files for info and convert: a byte-order mark (failure 4), encodings, streams, and
outputs that must be written whole or not at all."""
from pathlib import Path

import pytest

from ros_hrc.pomdp import cassandra, io, pomdpx
from ros_hrc.pomdp.cli import run

from cli_process import GiB, run_hrc_pomdp

ROOT = Path(__file__).resolve().parents[3]
TIGER = ROOT / "test" / "fixtures" / "tiger.95.pomdp"
ROBOT = ROOT / "models" / "robot" / "robot.pomdp"
BOM = b"\xef\xbb\xbf"


@pytest.mark.parametrize("name", ["tiger.pomdp", "tiger.pomdpx"])
def test_a_leading_byte_order_mark_is_accepted(tmp_path, capsys, name):
    plain = tmp_path / f"plain{Path(name).suffix}"
    io.save_model(io.load_model(TIGER), plain)
    marked = tmp_path / name
    marked.write_bytes(BOM + plain.read_bytes())
    assert io.differences(io.load_model(plain), io.load_model(marked)) == []
    assert run(["info", str(marked)]) == 0
    assert "checks passed" in capsys.readouterr().out


def test_a_byte_order_mark_is_accepted_as_text_and_as_bytes_by_both_parsers(tmp_path):
    model = io.load_model(TIGER)
    text = cassandra.dump(model)
    assert io.differences(model, cassandra.loads("\ufeff" + text)) == []
    xml = pomdpx.dump(model)
    for given in ("\ufeff" + xml, BOM + xml.encode("utf-8")):
        assert io.differences(model, pomdpx.loads(given)) == []


def test_a_utf16_file_is_refused_in_one_line(tmp_path, capsys):
    path = tmp_path / "wide.pomdp"
    path.write_bytes(TIGER.read_text().encode("utf-16"))
    assert run(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{path}:1: " in err and "UTF-16" in err


def test_a_stream_is_read_only_up_to_what_the_memory_limit_allows(tmp_path):
    endless = tmp_path / "endless.pomdp"
    endless.symlink_to("/dev/zero")
    result = run_hrc_pomdp(["info", str(endless), "--memory-limit", "16M"], address_space=1 * GiB)
    assert result.returncode == 1, result.stderr
    assert result.stderr.count("\n") == 1 and "not a regular file" in result.stderr


def test_convert_leaves_no_half_written_file_when_the_disk_fills(tmp_path):
    # Every file the child writes is capped at 2 KB: the POMDPX text of the robot model
    # (6 KB) cannot be written, and neither a part of it nor a temporary file may remain.
    out = tmp_path / "robot.pomdpx"
    result = run_hrc_pomdp(["convert", str(ROBOT), str(out)], file_size=2048, cwd=tmp_path)
    assert result.returncode == 1, result.stderr
    assert result.stderr.strip() == f"hrc_pomdp: {out}: File too large"
    assert list(tmp_path.iterdir()) == []


def test_convert_keeps_the_old_file_when_writing_the_new_one_fails(tmp_path):
    out = tmp_path / "robot.pomdpx"
    out.write_text("the old file\n")
    result = run_hrc_pomdp(["convert", str(ROBOT), str(out)], file_size=2048, cwd=tmp_path)
    assert result.returncode == 1
    assert out.read_text() == "the old file\n" and list(tmp_path.iterdir()) == [out]


def test_convert_onto_its_own_input_reads_it_all_first(tmp_path, capsys):
    path = tmp_path / "tiger.pomdp"
    path.write_text(TIGER.read_text())
    assert run(["convert", str(path), str(path)]) == 0
    assert io.differences(io.load_model(TIGER), io.load_model(path)) == []


@pytest.mark.parametrize("command", [["convert", str(TIGER)], ["solve", str(TIGER), "-o"]])
def test_an_output_that_cannot_be_written_is_refused_before_any_work(tmp_path, capsys,
                                                                      monkeypatch, command):
    def must_not_read(*args, **kwargs):
        raise AssertionError("the model was read before the output was checked")

    monkeypatch.setattr(io, "load_model", must_not_read)
    folder = tmp_path / "folder.pomdpx"
    folder.mkdir()
    for target, words in ((tmp_path / "missing" / "out.pomdpx", "no such directory"),
                          (folder, "is a directory")):
        assert run(command + [str(target)]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err and "Traceback" not in err


def test_a_written_model_has_the_usual_file_mode(tmp_path):
    out = tmp_path / "tiger.pomdpx"
    io.convert(TIGER, out)
    plain = tmp_path / "plain"
    plain.write_text("")
    assert out.stat().st_mode & 0o777 == plain.stat().st_mode & 0o777
