"""The fuzz frame generator of the launched fuzz test (test/rostest/fuzz_frames.py), without a
network: same seed, same frames; every frame and every call bounded; every kind present and
of the kind it says; the limits it aims at are the protocol's."""
import hashlib
import importlib.util
import json
import math
import sys
from pathlib import Path

import pytest

from ros_hrc.link import protocol, transport
from ros_hrc.link.protocol import Error, Hello, MessageError, decode

# test/rostest is no package (rostest runs its files as scripts): load the module by path.
_PATH = Path(__file__).resolve().parents[2] / "rostest" / "fuzz_frames.py"
_spec = importlib.util.spec_from_file_location("fuzz_frames", _PATH)
ff = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("fuzz_frames", ff)
_spec.loader.exec_module(ff)


def digest(frames):
    h = hashlib.sha256()
    for f in frames:
        h.update(f"{f.kind}|{f.binary}|{f.fragments}|{f.size}|".encode())
        h.update(f.payload)
    return h.hexdigest()


def what_a_server_reads(frame):
    return frame.payload if frame.binary else frame.text


@pytest.fixture(scope="module")
def frames():
    return ff.generate(11, 3000)


def test_same_seed_same_frames_other_seed_other_frames():
    assert ff.generate(5, 400) == ff.generate(5, 400)
    assert ff.generate("5:robot", 400) == ff.generate("5:robot", 400)
    assert digest(ff.generate(5, 400)) != digest(ff.generate(6, 400))
    assert digest(ff.generate("5:robot", 400)) != digest(ff.generate("5:human", 400))
    # A generator's stream goes on where it left off, the same way every time.
    a, b = ff.FrameGenerator(3), ff.FrameGenerator(3)
    assert a.frames(50) + a.frames(50) == b.frames(50) + b.frames(50)


def test_every_frame_and_every_call_is_bounded(frames):
    assert len(frames) == 3000
    assert max(f.size for f in frames) <= ff.MAX_FRAME_BYTES
    assert sum(f.size for f in frames) <= ff.DEFAULT_MAX_TOTAL_BYTES
    # A tight budget: frames that would break it are replaced by tiny ones.
    tight = ff.generate(11, 600, max_total_bytes=300_000)
    assert len(tight) == 600
    assert sum(f.size for f in tight) <= 300_000
    assert any(f.kind == "tiny" for f in tight)
    assert all(f.size <= ff.TINY_MAX_BYTES for f in tight if f.kind == "tiny")
    # Smaller frames: the oversized kinds are left out, all else stays.
    small = ff.generate(11, 600, max_frame_bytes=10_000)
    assert max(f.size for f in small) <= 10_000
    kinds = {f.kind for f in small}
    assert not kinds & {"oversized_frame", "oversized_message"}
    assert set(ff.KINDS) - {"oversized_frame", "oversized_message"} <= kinds
    with pytest.raises(ValueError):
        ff.generate(1, 100, max_total_bytes=100 * ff.TINY_MAX_BYTES - 1)


def test_every_kind_is_present_and_weighted():
    assert set(ff.WEIGHTS) == set(ff.KINDS)
    assert {f.kind for f in ff.generate(2, len(ff.KINDS))} == set(ff.KINDS)
    for seed in range(5):
        assert {f.kind for f in ff.generate(seed, len(ff.KINDS))} == set(ff.KINDS)


def test_the_limits_are_the_protocols():
    assert ff.MESSAGE_LIMIT_BYTES == protocol.MAX_MESSAGE_BYTES
    assert ff.FRAME_LIMIT_BYTES == transport.FRAME_LIMIT_BYTES
    assert set(ff.MESSAGE_TYPES) == set(protocol.MESSAGE_TYPES)
    assert ff.FRAME_LIMIT_BYTES < ff.MAX_FRAME_BYTES


def test_kinds_are_what_they_say(frames):
    by_kind = {}
    for f in frames:
        by_kind.setdefault(f.kind, []).append(f)
    assert all(f.binary for f in by_kind["binary_random"] + by_kind["binary_message"])
    assert all(f.over_frame_limit and f.closes for f in by_kind["oversized_frame"])
    assert all(ff.MESSAGE_LIMIT_BYTES < f.size <= ff.FRAME_LIMIT_BYTES
               for f in by_kind["oversized_message"])
    assert all(f.invalid_utf8 and f.closes and f.text is None for f in by_kind["invalid_utf8"])
    assert all(f.fragments >= 2 for f in by_kind["fragmented"])
    assert all(f.fragments == 1 for f in frames if f.kind != "fragmented")
    # Only these two kinds make a server close the connection.
    assert {f.kind for f in frames if f.closes} == {"oversized_frame", "invalid_utf8"}
    assert all(f.size <= ff.MESSAGE_LIMIT_BYTES for f in frames
               if f.kind in ("long_string", "deep_nesting", "huge_number"))
    # valid: every one decodes; binary_message: the same text, rejected as binary
    for f in by_kind["valid"]:
        decode(f.text)
    for f in by_kind["binary_message"]:
        decode(f.payload.decode("utf-8"))
        with pytest.raises(MessageError):
            decode(f.payload)
    # error_malformed: every one is an error the protocol never answers
    for f in by_kind["error_malformed"]:
        try:
            assert isinstance(decode(f.text), Error)
        except MessageError as exc:
            assert exc.msg_type == Error.TYPE, f.preview()
    # hello_unproven: a hello that proves nothing (no proof, or a malformed or random one)
    for f in by_kind["hello_unproven"]:
        try:
            msg = decode(f.text)
        except MessageError:
            continue
        assert isinstance(msg, Hello)
        assert msg.auth is None or msg.nonce is None or len(msg.auth) == 64


def test_most_fuzz_frames_are_rejected_and_decoding_never_fails_otherwise(frames):
    rejected = 0
    for f in frames:
        if f.closes:
            continue
        try:
            decode(what_a_server_reads(f))
        except MessageError:
            rejected += 1
    assert rejected > 0.75 * len(frames)


def test_mutations_reach_every_message_type_and_the_notes_say_what(frames):
    mutated = [f for f in frames if f.kind == "mutated"]
    assert {f.note.split(":")[0] for f in mutated} >= set(ff.MESSAGE_TYPES)
    assert all(f.note for f in frames)
    special = " ".join(f.note for f in frames)
    for literal in ("NaN", "Infinity", "1e999", "4294967296", "9007199254740992",
                    "5000-digit", "\\ud800", "twice", "nested", "characters"):
        assert literal in special, literal


def test_dumps_writes_what_no_encoder_would():
    assert ff.dumps(ff.Obj([("a", 1), ("a", 2)])) == '{"a":1,"a":2}'
    assert ff.dumps({"x": ff.Raw("NaN"), "y": [math.inf, -math.inf]}) == \
        '{"x":NaN,"y":[Infinity,-Infinity]}'
    deep = ff.dumps([ff.Raw("[" * 100_000 + "]" * 100_000)])
    assert len(deep) == 200_002
    nested = [1]
    for _ in range(5000):  # deeper than Python's recursion limit: written iteratively
        nested = [nested]
    assert ff.dumps(nested).count("[") == 5001
    text = ff.dumps({"k": "é", "l": [True, None, 1.5]}, style=1, ascii_only=True)
    assert json.loads(text) == {"k": "é", "l": [True, None, 1.5]}


def test_fragment_sizes_cover_the_payload(frames):
    for f in frames:
        sizes = ff.fragment_sizes(f)
        assert len(sizes) == f.fragments
        assert sum(sizes) == f.size
