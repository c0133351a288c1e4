"""The selector model file (ros_hrc.agents.selector_model): the trainer's arithmetic by hand,
the round trip through the file, and each refusal of the reader in one line naming the file."""
import json

import numpy as np
import pytest

from ros_hrc import tasks
from ros_hrc.agents.selector_model import (
    FORMAT, HEADER_KEYS, SIGNATURE_CODES, STD_FLOOR, SelectorModel, TrainingTask, from_tasks,
    load_selector_model, write_selector_model)
from ros_hrc.errors import HrcError

HEADER = {"how": "unit test", "from": "hand-made rows", "seeds": [1, 2],
          "command": "pytest", "date": "2026-11-27T21:00:00Z"}
POLICIES = ("base", "reactive")
TYPES = ("expert", "tired")

# Two types x two policies. expert with base: utilities 0.5, 0.7, 0.9 (mean 0.7, sample std
# sqrt(((-0.2)^2 + 0 + 0.2^2) / 2) = 0.2), codes 1, 1, 5 over its tasks; expert with reactive:
# one task, 0.4 -> std = the floor; tired with base: 0.1 and 0.1 -> std 0 -> the floor;
# tired with reactive: -0.5 and 0.3 (mean -0.1, std sqrt((0.4^2 + 0.4^2) / 1) = 0.5657).
ROWS = [
    TrainingTask("expert", "base", 0.5, (1, 1)),
    TrainingTask("expert", "base", 0.7, (5,)),
    TrainingTask("expert", "base", 0.9, ()),
    TrainingTask("expert", "reactive", 0.4, (33,)),
    TrainingTask("tired", "base", 0.1, (33, 33, 35)),
    TrainingTask("tired", "base", 0.1, (33,)),
    TrainingTask("tired", "reactive", -0.5, (2,)),
    TrainingTask("tired", "reactive", 0.3, ()),
]


def trained():
    return from_tasks(ROWS, task="fabric", policies=POLICIES, types=TYPES, header=HEADER,
                      manifest="models/fabric/library.toml")


def test_from_tasks_by_hand():
    model = trained()
    assert model.mean == pytest.approx(np.array([[0.7, 0.4], [0.1, -0.1]]))
    assert model.std == pytest.approx(np.array([[0.2, STD_FLOOR], [STD_FLOOR, 0.5656854]]))
    assert model.tasks_per_pair.tolist() == [[2 + 1, 1], [2, 2]]
    # expert with base: 3 steps (1, 1, 5) + the add-one prior over 64 codes: 3 + 64 = 67.
    base_expert = model.signature[0, 0]
    assert base_expert[1] == pytest.approx(3 / 67) and base_expert[5] == pytest.approx(2 / 67)
    assert base_expert[0] == pytest.approx(1 / 67)
    # tired with base: 4 steps, three of code 33 -> (3 + 1) / (4 + 64).
    assert model.signature[0, 1, 33] == pytest.approx(4 / 68)
    assert model.signature.sum(axis=2) == pytest.approx(np.ones((2, 2)))
    assert model.policy_index("reactive") == 1 and model.type_index("tired") == 1
    assert model.type_index("stranger") is None


def test_from_tasks_refuses_incomplete_or_foreign_rows():
    cases = [
        (ROWS[:-2], "no training task of tired with reactive"),
        (ROWS + [TrainingTask("novice", "base", 0.0, ())], "human type 'novice'"),
        (ROWS + [TrainingTask("expert", "policy7", 0.0, ())], "policy 'policy7'"),
        (ROWS + [TrainingTask("expert", "base", 0.0, (64,))], "signature code 64"),
        (ROWS + [TrainingTask("expert", "base", float("nan"), ())], "utility nan"),
    ]
    for rows, message in cases:
        with pytest.raises(ValueError, match=message):
            from_tasks(rows, task="fabric", policies=POLICIES, types=TYPES, header=HEADER)
    with pytest.raises(ValueError, match="header lacks command, date"):
        from_tasks(ROWS, task="fabric", policies=POLICIES, types=TYPES,
                   header={"how": "", "from": "", "seeds": []})


def test_round_trip(tmp_path):
    model = trained()
    path = tmp_path / "selector_model.json"
    write_selector_model(model, path)
    data = json.loads(path.read_text())
    assert data["format"] == FORMAT and data["task"] == "fabric"
    assert data["library"] == {"manifest": "models/fabric/library.toml",
                               "policies": list(POLICIES)}
    assert data["signature_codes"] == SIGNATURE_CODES and data["header"] == HEADER
    assert list(data)[0] == "format"
    loaded = load_selector_model(path, tasks.get("fabric"), POLICIES)
    assert loaded.path == path and loaded.task == "fabric" and loaded.types == TYPES
    for name in ("mean", "std", "signature"):
        assert np.array_equal(getattr(loaded, name), getattr(model, name))
    assert loaded.tasks_per_pair.tolist() == model.tasks_per_pair.tolist()
    assert loaded.header == HEADER and loaded.utility == model.utility
    with pytest.raises(ValueError):
        loaded.mean[0, 0] = 1.0                                  # read-only tables


def test_write_replaces_whole_and_refuses_what_is_not_a_file(tmp_path):
    path = tmp_path / "selector_model.json"
    path.write_text("the old model\n")
    write_selector_model(trained(), path)
    assert json.loads(path.read_text())["format"] == FORMAT
    assert sorted(p.name for p in tmp_path.iterdir()) == ["selector_model.json"]   # no temp left
    with pytest.raises(OSError):
        write_selector_model(trained(), tmp_path)                # a directory is never replaced
    with pytest.raises(OSError):
        write_selector_model(trained(), tmp_path / "no such folder" / "model.json")


def written(tmp_path, change):
    """The trained model's JSON, changed by ``change(data)``, written to a file of its own."""
    data = json.loads(json.dumps({
        "format": FORMAT, "task": "fabric",
        "library": {"manifest": "m", "policies": list(POLICIES)}, "types": list(TYPES),
        "signature_codes": 64, "utility": "u", "mean": trained().mean.tolist(),
        "std": trained().std.tolist(), "signature": trained().signature.tolist(),
        "tasks_per_pair": trained().tasks_per_pair.tolist(), "header": HEADER}))
    change(data)
    path = tmp_path / "model.json"
    path.write_text(json.dumps(data, indent=1))
    return path


def set_(key, value):
    def change(data):
        data[key] = value
    return change


def test_every_refusal_is_one_line_naming_the_file(tmp_path):
    def negative_std(data):
        data["std"][1][0] = -0.1

    def row_not_one(data):
        data["signature"][1][0][5] += 0.25

    def ragged(data):
        data["mean"][0].append(1.0)

    def short_signature(data):
        data["signature"] = data["signature"][:1]

    cases = [
        (set_("format", "ros_hrc selector model 0"), "format is 'ros_hrc selector model 0'"),
        (set_("task", "seed"), "a selector model of task 'seed', not 'fabric'"),
        (set_("library", {"manifest": "m", "policies": ["base", "policy3"]}),
         "trained on the policies base, policy3; the library's are base, reactive"),
        (negative_std, "std of type 'tired' with policy 'base' is -0.1"),
        (row_not_one, "signature of policy 'reactive' on type 'expert' sums to 1.25"),
        (ragged, "rows of different lengths"),
        (short_signature, "signature is 1 x 2 x 64, expected policies x types x codes = 2 x 2"),
        (set_("mean", [[0.1, 0.2]]), "mean is 1 x 2, expected types x policies = 2 x 2"),
        (set_("types", ["expert", "expert"]), "a name twice among the types"),
        (set_("signature_codes", 32), "signature_codes is 32, expected 64"),
        (set_("header", {"how": "x"}), "header lacks from, seeds, command, date"),
        (set_("tasks_per_pair", [[1, 2], [3, 0.5]]), "whole numbers"),
    ]
    for change, message in cases:
        path = written(tmp_path, change)
        with pytest.raises(HrcError, match=message) as caught:
            load_selector_model(path, "fabric", POLICIES)
        text = str(caught.value)
        assert text.startswith(str(path)) and "\n" not in text, text


@pytest.mark.parametrize("change, message", [
    (set_("types", [0, 1]), "types[0] is 0, not a name: each of the types is named by a string"),
    (set_("types", ["expert", 7]), "types[1] is 7, not a name"),
    (set_("library", {"manifest": "m", "policies": ["base", 3]}),
     "library.policies[1] is 3, not a name"),
])
def test_a_name_that_is_not_a_string_is_refused_naming_the_file_and_field(tmp_path, change,
                                                                          message):
    """str() made integer types the names "0".."9", which no human's type matched: the oracle
    then identified nobody, without a word."""
    path = written(tmp_path, change)
    with pytest.raises(HrcError) as caught:
        load_selector_model(path, "fabric", POLICIES)
    text = str(caught.value)
    assert text.startswith(f"{path}: {message}") and "\n" not in text, text


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(HrcError, match="no such selector model file.*make train-selector"):
        load_selector_model(tmp_path / "none.json", "fabric", POLICIES)
    broken = tmp_path / "broken.json"
    broken.write_text('{"format": "ros_hrc selector model 1",\n "task": "fabric",\n "types": [\n')
    with pytest.raises(HrcError, match=rf"^{broken}:4: not JSON") as caught:
        load_selector_model(broken, "fabric", POLICIES)
    assert "\n" not in str(caught.value)
    listed = tmp_path / "list.json"
    listed.write_text("[1, 2]\n")
    with pytest.raises(HrcError, match="one JSON object"):
        load_selector_model(listed, "fabric", POLICIES)


def test_model_checks_itself_on_construction():
    good = trained()
    with pytest.raises(ValueError, match="std of type 'expert' with policy 'base' is 0"):
        SelectorModel(task="fabric", policies=POLICIES, types=TYPES, mean=good.mean,
                      std=np.zeros((2, 2)), signature=good.signature,
                      tasks_per_pair=good.tasks_per_pair, header=HEADER)
    assert set(HEADER_KEYS) == set(HEADER)
