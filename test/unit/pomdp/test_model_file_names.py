"""Every shipped model, written by the package's writers, holds only names its format allows,
so the reference tools read it too (issue #39: SARSOP's ``pomdpsol`` refused the composed
models of types, "Illegal character @ in input").

The rules here are the formats' own, written from their definitions, not taken from the
writers: Cassandra's ``.pomdp`` grammar lexes a name as STRING, ``[a-zA-Z]([a-zA-Z0-9]|[_-])*``,
and beside names a file holds only numbers, ``:``, ``*`` and its keywords (anything else is an
illegal character); POMDPX lists a variable's values in ``<ValueEnum>`` separated by white
space, and an ``<Instance>`` uses ``*`` and ``-`` alone as wildcards.
"""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from ros_hrc.errors import ModelFormatError
from ros_hrc.pomdp import cassandra, io, pomdpx

ROOT = Path(__file__).resolve().parents[3]
SHIPPED = sorted(p for p in (ROOT / "models").rglob("*.pomdp*")
                 if p.suffix in (".pomdp", ".pomdpx"))

CASSANDRA_STRING = re.compile(r"[a-zA-Z][a-zA-Z0-9_-]*")
CASSANDRA_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
CASSANDRA_KEYWORDS = {"discount", "values", "states", "actions", "observations", "T", "O", "R",
                      "uniform", "identity", "reward", "cost", "start", "include", "exclude",
                      "reset"}
POMDPX_VALUE = re.compile(r"(?![*-]$)\S+")
POMDPX_WILDCARDS = {"*", "-"}


def cassandra_names(text: str) -> list:
    """Every word of a .pomdp text that is neither a number, ``:``, ``*`` nor a keyword; a
    word that is none of these nor a name of the grammar fails the test where it stands."""
    names = []
    for number, line in enumerate(text.splitlines(), 1):
        for word in line.split("#", 1)[0].replace(":", " : ").split():
            if word in (":", "*") or CASSANDRA_NUMBER.fullmatch(word):
                continue
            assert CASSANDRA_STRING.fullmatch(word), f"line {number}: {word!r} is no name"
            if word not in CASSANDRA_KEYWORDS:
                names.append(word)
    return names


def pomdpx_names(text: str) -> list:
    """Every value a POMDPX text declares, each checked against the format's rule, after
    checking that every <Instance> word is a declared value or a wildcard."""
    root = ET.fromstring(text)
    declared = []
    for enum in root.iter("ValueEnum"):
        for word in enum.text.split():
            assert POMDPX_VALUE.fullmatch(word), f"<ValueEnum> {word!r} is no value name"
            declared.append(word)
    known = set(declared) | POMDPX_WILDCARDS
    for instance in root.iter("Instance"):
        assert set(instance.text.split()) <= known, instance.text
    return declared


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(ROOT / "models")))
def test_a_shipped_model_written_by_either_writer_holds_only_its_formats_names(path):
    model = io.load_model(path)
    every = set(model.states) | set(model.actions) | set(model.observations)
    text = cassandra.dump(model)
    assert set(cassandra_names(text)) == every
    back = cassandra.loads(text)
    assert (back.states, back.actions, back.observations) == \
        (model.states, model.actions, model.observations)
    text = pomdpx.dump(model)
    assert every <= set(pomdpx_names(text))
    back = pomdpx.loads(text)
    assert (back.states, back.actions, back.observations) == \
        (model.states, model.actions, model.observations)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: str(p.relative_to(ROOT / "models")))
def test_a_shipped_model_file_already_holds_only_its_formats_names(path):
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".pomdp":
        model = io.load_model(path)
        assert set(cassandra_names(text)) == \
            set(model.states) | set(model.actions) | set(model.observations)
    else:
        assert pomdpx_names(text)      # a factored file's joint names are not in it, its values are


def test_a_writer_refuses_a_name_its_format_does_not_allow(tmp_path):
    model = io.load_model(ROOT / "test" / "fixtures" / "tiger.95.pomdp")
    model.states = ["tiger@left", "tiger-right"]
    with pytest.raises(ModelFormatError, match=r"the state name 'tiger@left' cannot be written "
                                               r"in this format \(a name is a letter, then"):
        io.save_model(model, tmp_path / "out.pomdp")
    assert not (tmp_path / "out.pomdp").exists()
    model.states = ["*", "tiger-right"]
    with pytest.raises(ModelFormatError, match=r"the state name '\*' cannot be written"):
        io.save_model(model, tmp_path / "out.pomdpx")
    assert list(tmp_path.iterdir()) == []
