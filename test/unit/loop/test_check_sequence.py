"""The launch's pre-flight refuses a sequence it could not play (docs/sequences.md): one line
naming the argument or the file (that roslaunch then stops before anything starts is
test/integration/loop/test_launch_refuses.py's, for any refusal of the pre-flight)."""
import pytest

from ros_hrc.commands.check import check
from ros_hrc.errors import HrcError

FABRIC_TYPE = "expert_tired_noncollaborative"


def refusal(*words):
    with pytest.raises(HrcError) as info:
        check(list(words), port_check=False)
    line = " ".join(str(info.value).split())
    assert line == str(info.value)
    return line


def test_a_schedule_file_is_refused_with_its_file_and_line(tmp_path):
    path = tmp_path / "week.toml"
    path.write_text(f'[[block]]\nhuman = "{FABRIC_TYPE}"\ntasks = 3\n\n[[block]]\n'
                    'human = "nobody"\ntasks = 2\n')
    assert refusal("task:=fabric", "tasks:=5", f"schedule:={path}").startswith(
        f"schedule:={path}: {path}:5: unknown human type 'nobody'; known: "
        "beginner_nontired_collaborative, ")
    path.write_text('[[block]\nhuman = "x"\n')
    assert f"{path}: not TOML: " in refusal("task:=fabric", "tasks:=5", f"schedule:={path}")
    folder = tmp_path / "folder.toml"      # (unreadable as a file, even to root)
    folder.mkdir()
    assert f"{folder}: cannot read it" in refusal("task:=fabric", "tasks:=5",
                                                  f"schedule:={folder}")


def test_a_library_of_another_task_is_refused_naming_the_file():
    line = refusal("task:=fabric", "tasks:=3", "selector:=random",
                   "library:=models/robot/library.toml")
    assert line.startswith("library:=") and "a library of task seed, not of task fabric" in line


def test_a_selector_model_of_another_task_is_refused(tmp_path):
    path = tmp_path / "model.json"
    path.write_text('{"format": "ros_hrc selector model 1", "task": "seed"}')
    line = refusal("task:=fabric", "tasks:=3", "selector:=bpr", f"selector_model:={path}")
    assert line.startswith(f"selector_model:={path}: ") and "of task 'seed'" in line


def test_a_selector_that_needs_a_model_without_one_names_make_train_selector(
        library_without_model):
    line = refusal("task:=fabric", "tasks:=3", "selector:=oracle",
                   f"library:={library_without_model}")
    assert line.startswith("selector:=oracle needs a selector model") and \
        "make train-selector" in line


def test_a_sequence_without_a_selector_model_runs_the_selectors_that_need_none():
    for selector in ("random", "bandit", "fixed:policy3", "fixed"):
        config = check(["task:=fabric", "tasks:=3", f"selector:={selector}"], port_check=False)
        assert config["tasks"] == 3 and config["selector"] == selector


@pytest.mark.parametrize("words, line", [
    (("tasks:=0",), "hrc.launch: tasks:=0: must be an integer from 1 to 2147483647"),
    (("task:=fabric", "selector:=bpr"), "hrc.launch: selector:=bpr: only with a sequence: a "
                                        "selector chooses between the tasks of a sequence"),
    (("task:=fabric", "tasks:=5", "schedule:=sleepy*3"),
     "hrc.launch: schedule:=sleepy*3: unknown human type 'sleepy'; known: "),
    (("task:=fabric", "tasks:=5", "selector:=bpr", "selector_model:=/nowhere/model.json"),
     "hrc.launch: selector_model:=/nowhere/model.json: "),
])
def test_a_bad_sequence_argument_is_one_line_naming_it(words, line):
    assert f"hrc.launch: {refusal(*words)}".startswith(line)


def test_a_refused_library_is_named_as_typed_and_the_file_it_looked_for_in_full(tmp_path,
                                                                                   monkeypatch):
    """Before: `library:=/abs/nolib.toml: /abs/nolib.toml: no such manifest ...` for a user who
    typed ./nolib.toml; the path as typed, once, then where it looked."""
    monkeypatch.chdir(tmp_path)
    assert refusal("task:=fabric", "tasks:=3", "selector:=random", "library:=./nolib.toml") == (
        f"library:=./nolib.toml: no such manifest or folder (looked for {tmp_path / 'nolib.toml'})")
    line = refusal("task:=fabric", "tasks:=3", "selector:=bpr", "selector_model:=./none.json")
    assert line.startswith(f"selector_model:=./none.json: {tmp_path / 'none.json'}: ")
