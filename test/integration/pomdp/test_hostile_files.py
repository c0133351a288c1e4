"""Hostile files for info and convert: a byte-order mark (failure 4), encodings, streams, and
outputs that must be written whole or not at all."""
import os
import stat
from pathlib import Path

import pytest

from ros_hrc.pomdp import cassandra, io, output, pomdpx
from ros_hrc.commands.pomdp import run

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


def test_a_device_as_the_model_file_is_refused_before_it_is_read(tmp_path):
    endless = tmp_path / "endless.pomdp"
    endless.symlink_to("/dev/zero")       # read only: nothing is ever written to it
    result = run_hrc_pomdp(["info", str(endless), "--memory-limit", "16M"], address_space=1 * GiB)
    assert result.returncode == 2, result.stderr
    assert result.stderr == (f"hrc_pomdp: {endless}: is a character device, not a regular "
                             "file: give a model file\n")


@pytest.mark.parametrize("command", [["info"], ["convert", "-", "out.pomdpx"],
                                     ["solve", "-", "--timeout", "1"]])
def test_a_fifo_nobody_writes_as_the_model_file_is_refused_not_waited_on(tmp_path, command):
    """Before: hrc_pomdp waited for ever for a writer."""
    fifo = tmp_path / "model.pomdp"
    os.mkfifo(fifo)
    args = [str(fifo) if word == "-" else word for word in command]
    if len(args) == 1:
        args.append(str(fifo))
    result = run_hrc_pomdp(args, cwd=tmp_path, timeout=120)
    assert result.returncode == 2, result.stderr
    assert result.stderr == (f"hrc_pomdp: {fifo}: is a FIFO, not a regular file: give a model "
                             "file\n")
    assert stat.S_ISFIFO(fifo.stat().st_mode) and not (tmp_path / "out.pomdpx").exists()


HUGE = "9" * 5000


@pytest.mark.parametrize("name, text, message", [
    ("index.pomdp", TIGER.read_text() + f"\nT: listen : {HUGE} : 0 1.0\n",
     "unknown state '9999999999999999999999999999999999999999... (5000 characters)' in "),
    ("count.pomdp", f"discount: 0.9\nvalues: reward\nstates: {HUGE}\n",
     "'states:' count 9999999999999999999999999999999999999999... (5000 characters) is not a "
     "count (decimal digits, at most 18)"),
    ("start.pomdp", TIGER.read_text().replace("start: uniform", f"start: {HUGE}"),
     "'start:' expects 2 probabilities, 'uniform' or a state"),
    ("count.pomdpx", '<?xml version="1.0"?><pomdpx version="1.0"><Discount>0.9</Discount>'
     '<Variable><StateVar vnamePrev="s0" vnameCurr="s1"><NumValues>' + HUGE +
     "</NumValues></StateVar></Variable></pomdpx>",
     "<NumValues> must be a positive integer of at most 18 digits, found "
     "'9999999999999999999999999999999999999999... (5000 characters)'"),
    ("unicode.pomdp", "discount: 0.9\nvalues: reward\nstates: \u00b2\n", "'states:' count"),
])
def test_a_number_of_5000_digits_in_a_model_file_is_one_line(tmp_path, capsys, name, text,
                                                              message):
    """Before: ValueError "Exceeds the limit (4300 digits) for integer string conversion"
    with a traceback."""
    path = tmp_path / name
    path.write_text(text)
    assert run(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"hrc_pomdp: {path}:") and message in err
    assert len(err) < 400


def private_device(folder: Path) -> Path:
    """A character device of the test's own, the kernel's "full" device (1, 7): never the
    machine's /dev/full, which a rename over it would replace for everyone."""
    path = folder / "full"
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 7))
    except PermissionError:
        pytest.skip("making a device node needs root")
    return path


@pytest.mark.parametrize("kind", ["fifo", "device"])
@pytest.mark.parametrize("command", [["convert", str(TIGER)], ["solve", str(TIGER),
                                                               "--timeout", "1", "-o"]])
def test_an_output_onto_a_device_or_fifo_is_refused_and_the_node_kept(tmp_path, kind, command):
    """Before: the atomic writer renamed its file over the node (as root this replaced
    /dev/full for the whole machine)."""
    if kind == "fifo":
        target = tmp_path / "out.pomdpx"
        os.mkfifo(target)
        what, test = "a FIFO", stat.S_ISFIFO
    else:
        target = private_device(tmp_path)
        what, test = "a character device", stat.S_ISCHR
        if command[0] == "convert":
            target = target.rename(tmp_path / "full.pomdpx")
    result = run_hrc_pomdp(command + [str(target)], cwd=tmp_path, timeout=120)
    assert result.returncode == 1, result.stderr
    assert result.stderr == (f"hrc_pomdp: {target}: is {what}, not a regular file; it is never "
                             "replaced (write to a file)\n")
    assert test(os.lstat(target).st_mode), "the node was replaced"
    assert sorted(p.name for p in tmp_path.iterdir()) == [target.name]


def test_the_atomic_writer_never_replaces_a_node_that_is_not_a_regular_file(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    link = tmp_path / "link"
    link.symlink_to(fifo)
    for target in (fifo, link):
        with pytest.raises(OSError, match="is a FIFO, not a regular file; it is never replaced"):
            output.write_text_atomically(target, "text")
        assert stat.S_ISFIFO(os.stat(target).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fifo", "link"]


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
