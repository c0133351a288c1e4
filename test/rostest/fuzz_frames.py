"""A seeded, bounded generator of hostile websocket frames for the links (docs/protocol.md):
what test_fuzz.py throws at the three servers of a running stack. No ROS, no sockets, no
import of ros_hrc: a frame is bytes and a few labels, so the unit tests
(test/unit/link/test_fuzz_frames.py) check the generator itself without a network.

Deterministic: everything comes from one ``random.Random(seed)``, so the same seed and count
give the same frames, byte for byte (an integer or string seed; string seeds do not depend on
PYTHONHASHSEED). Bounded: no frame is larger than ``max_frame_bytes`` (default
:data:`MAX_FRAME_BYTES`, 300 KiB) and a call's frames together are at most
``max_total_bytes`` (default :data:`DEFAULT_MAX_TOTAL_BYTES`): a frame that would break the
budget is replaced by a tiny one (at most :data:`TINY_MAX_BYTES`), and room for those is kept.

What a frame is (:class:`Frame`): ``payload`` (bytes), sent as a ``binary`` or a text frame,
split into ``fragments`` websocket fragments (1: one frame), with its ``kind`` (one of
:data:`KINDS`) and a short ``note`` saying what was done to it. The kinds:

======================  ====================================================================
binary_random           random bytes in a binary frame
binary_message          a valid message's JSON in a binary frame (binary frames are rejected)
text_random             random Unicode text (every plane but surrogates; control characters)
text_noise              random JSON-ish ASCII: braces, quotes, colons, digits, escapes
empty                   "", whitespace, a BOM, "{}", "null", "[]"
json_truncated          a message's JSON cut short
json_corrupted          a message's JSON with characters flipped, dropped, inserted, repeated
json_not_object         valid JSON that is not an object (number, string, array, ...)
mutated                 a valid message of a random type with 1 to 3 random mutations below
missing_field           a field removed (a required one, or ``type``)
wrong_type              a field given a value of another JSON type (or null)
huge_number             an integer field set to 2**32, 2**53, 2**64, -1, 4300/4301/5000-digit
                        integers, a float, an exponent
special_number          NaN, Infinity, -Infinity, 1e999, -1e999, 1e-999 literals
surrogate               lone surrogate escapes (\\ud800, \\udfff, ...) in strings, or a pair
control_chars           control characters (C0, DEL, C1, U+2028) in a string, escaped or raw
long_string             a string of 129, 1025, 5000 or up to 60000 characters (<= ~60 KB)
deep_nesting            arrays (64 to 30000) or objects (64 to 10000) nested deep
duplicate_key           a key twice (``type`` too)
unknown_type            an unknown or odd ``type`` (``teleport``, ``Error``, ``""``, ...)
envelope                ``epoch`` / ``id`` / ``reply_to`` out of range or of a wrong type
belief                  beliefs not summing to 1, negative, empty, mismatched names, ...
field_range             ``bits``, ``step``, ``state_index``, ``version``, ``episode`` out of
                        range; names too long or empty
extra_fields            unknown extra fields: odd names, nested values, non-finite numbers
hello_unproven          a hello without nonce/auth, with a wrong proof, malformed hex, ...
error_malformed         ``error`` frames malformed in every way (never to be answered)
valid                   a valid message of a random type, unmutated (rare: it may act)
fragmented              a (mutated or valid) message split into 2 to 6 fragments
oversized_message       a text frame over 64 KiB (the message limit) but at most 256 KiB
oversized_frame         a frame over 256 KiB (the frame limit), at most ``max_frame_bytes``
invalid_utf8            a text frame whose bytes are not UTF-8
======================  ====================================================================

The first ``len(KINDS)`` frames of a call take every kind once (in a seeded order), so any
call of at least that many frames holds every kind; the rest are drawn by :data:`WEIGHTS`
(large and connection-closing kinds are rare). Oversized kinds are skipped when
``max_frame_bytes`` is too small for them.

Run it to look at frames: ``python fuzz_frames.py --seed 1 --count 30``.
"""
import argparse
import json
import math
import random
import re
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

#: The protocol's limits (ros_hrc.link.protocol.MAX_MESSAGE_BYTES and
#: ros_hrc.link.transport.FRAME_LIMIT_BYTES; the unit test checks they agree).
MESSAGE_LIMIT_BYTES = 64 * 1024
FRAME_LIMIT_BYTES = 256 * 1024
#: Largest frame this module makes.
MAX_FRAME_BYTES = 300 * 1024
#: Default bound of one call's frames, all together.
DEFAULT_MAX_TOTAL_BYTES = 32 * 1024 * 1024
#: A frame that replaces one that would break the total budget is at most this large.
TINY_MAX_BYTES = 64

KINDS: Tuple[str, ...] = (
    "binary_random", "binary_message", "text_random", "text_noise", "empty", "json_truncated",
    "json_corrupted", "json_not_object", "mutated", "missing_field", "wrong_type",
    "huge_number", "special_number", "surrogate", "control_chars", "long_string",
    "deep_nesting", "duplicate_key", "unknown_type", "envelope", "belief", "field_range",
    "extra_fields", "hello_unproven", "error_malformed", "valid", "fragmented",
    "oversized_message", "oversized_frame", "invalid_utf8")

#: Relative weights of the kinds after the first round.
WEIGHTS: Dict[str, float] = {
    "binary_random": 4, "binary_message": 2, "text_random": 4, "text_noise": 4, "empty": 1,
    "json_truncated": 6, "json_corrupted": 6, "json_not_object": 2, "mutated": 14,
    "missing_field": 5, "wrong_type": 5, "huge_number": 5, "special_number": 4, "surrogate": 3,
    "control_chars": 3, "long_string": 3, "deep_nesting": 2, "duplicate_key": 3,
    "unknown_type": 4, "envelope": 6, "belief": 5, "field_range": 4, "extra_fields": 3,
    "hello_unproven": 3, "error_malformed": 8, "valid": 1.5, "fragmented": 2,
    "oversized_message": 0.6, "oversized_frame": 0.2, "invalid_utf8": 0.3,
}

#: The message types of the protocol.
MESSAGE_TYPES: Tuple[str, ...] = ("hello", "step", "observation", "decision", "action", "reset",
                                  "next_state", "ack", "error", "reaction", "task_end",
                                  "task_report", "configure")

_HUMAN_ACTIONS = ("graspAttempt", "lookAround", "idle", "walkAway", "warnRobot")
_HUMAN_STATES = ("task_assigned", "success", "failed_to_grasp", "no_attention", "evaluating",
                 "tired", "recovery", "warningTheRobot")
_ROBOT_ACTIONS = ("rIdle", "rPoint_obj", "rGrasp_obj", "rStop_all")
_ROBOT_STATES = ("S0", "S1", "S2", "S3", "S4", "S5", "S6")
_LEGAL_BITS = (0, 1, 2, 3, 7, 10, 11, 16, 17, 18, 19, 32, 33, 34, 35)
_ERROR_CODES = ("stale", "busy", "seat_taken", "invalid", "unknown_type", "refused", "failed",
                "version", "episode_over", "not_ready", "unauthorized")
_WHO = ("despot_mdp", "despot_pomdp", "hrc_obs", "hrc_human", "hrc_robot", "fuzz")
_INT_FIELDS = ("step", "bits", "state_index", "version", "episode", "epoch", "id", "reply_to",
               "state")
_ENVELOPE = ("epoch", "id", "reply_to")
_HEX = "0123456789abcdef"
# How a frame that cannot be parsed still shows it is an error (as the protocol reads it).
_ERROR_TYPE = re.compile(r'"type"\s*:\s*"error"')

# Integer literals of every size that matters: the uint32, envelope and double limits, and the
# 4300-digit limit of Python's int().
_BIG_INTS = ("4294967295", "4294967296", "9007199254740991", "9007199254740992",
             "18446744073709551615", "18446744073709551616", "-1", "-4294967296",
             "-9223372036854775808", "2147483647", "2147483648", "256", "64", "0", "-0")
_NUMBER_ODDITIES = ("3.0", "0.5", "1e3", "1E400", "-1e-400", "00", "01", "1.", ".5", "+1", "0x10",
                    "1_000", "9" * 400 + ".0", "1e309")
_SPECIAL_NUMBERS = ("NaN", "Infinity", "-Infinity", "1e999", "-1e999", "1e-999", "nan", "inf",
                    "-NaN", "1.7976931348623157e308", "1.7976931348623159e308")
_SURROGATES = ("\\ud800", "\\udfff", "\\udbff", "\\uDC00", "\\uD800", "a\\ud800b", "\\ud800\\u0041",
               "\\udc00\\ud800", "\\ud800\\ud800", "\\ud83d", "\\ude00")
_SURROGATE_PAIRS = ("\\ud83d\\ude00", "\\uD83D\\uDE00", "\\udbff\\udfff")
_CONTROL = [chr(c) for c in range(0x20)] + ["\x7f", "\x80", "\x85", "\x9f", "\u2028",
                                            "\u2029", "\ufeff", "\ufffe"]
_ODD_TYPES = ("teleport", "", " ", "Error", "ERROR", "error ", " error", "errors", "hello\u0000",
              "Hello", "step\n", "ack\u00a0", "\u00e9rror", "x" * 200, "__proto__", "constructor",
              "null", "reset;", "observation ", "decisio", "next-state", "nextState", "stepp")
_NOT_OBJECTS = ("0", "-1", "1e999", "NaN", "true", "false", "null", '"step"', '"{\\"type\\":1}"',
                "[]", '[{"type":"step"}]', "[1,2,3]", '"error"', "3.14", '""',
                '[{"type":"error","message":"x"}]')


class Raw(str):
    """JSON text put into a frame as it is (a literal no JSON encoder would write)."""


class Obj(list):
    """A JSON object as a list of (key, value) pairs: keeps order and allows a key twice."""

    def get(self, key: str, default: Any = None) -> Any:
        for k, v in self:
            if k == key:
                return v
        return default

    def keys(self) -> List[str]:
        return [k for k, _ in self]

    def set(self, key: str, value: Any) -> None:
        for i, (k, _) in enumerate(self):
            if k == key:
                self[i] = (k, value)
                return
        self.append((key, value))

    def drop(self, key: str) -> None:
        self[:] = [(k, v) for k, v in self if k != key]


@dataclass(frozen=True)
class Frame:
    """One frame to send: ``payload`` as a binary or a text frame (a text frame's payload may
    be invalid UTF-8 on purpose), split into ``fragments`` websocket fragments."""

    kind: str
    note: str
    payload: bytes
    binary: bool = False
    fragments: int = 1

    @property
    def size(self) -> int:
        """Payload bytes."""
        return len(self.payload)

    @property
    def text(self) -> Optional[str]:
        """What a server reads from a text frame (``None``: binary, or not UTF-8)."""
        if self.binary:
            return None
        try:
            return self.payload.decode("utf-8")
        except UnicodeDecodeError:
            return None

    @property
    def over_frame_limit(self) -> bool:
        """Larger than the frame limit: the server closes the connection (1009)."""
        return self.size > FRAME_LIMIT_BYTES

    @property
    def invalid_utf8(self) -> bool:
        """A text frame that is not UTF-8: the websocket layer closes the connection (1007)."""
        return not self.binary and self.text is None

    @property
    def closes(self) -> bool:
        """A server closes the connection this frame arrives on, whatever its content."""
        return self.over_frame_limit or self.invalid_utf8

    def preview(self, limit: int = 160) -> str:
        """The payload shortened for a report line."""
        data = self.payload[:limit]
        shown = data.decode("utf-8", "backslashreplace")
        more = f"... ({self.size} bytes)" if self.size > limit else ""
        return f"{shown!r}{more}"


# -- JSON text with the odd bits no encoder writes ------------------------------------------

# Marks literal text on dumps()'s work stack.
_LIT = object()


def _dump_string(value: str, ascii_only: bool) -> str:
    return json.dumps(value, ensure_ascii=ascii_only)


def dumps(value: Any, style: int = 0, ascii_only: bool = False) -> str:
    """JSON text of ``value``: :class:`Obj` (pairs, duplicates kept), dict, list, tuple,
    :class:`Raw` (as is), str, bool, None, int, float (non-finite ones as ``NaN`` /
    ``Infinity`` literals). ``style`` picks the separators: 0 compact, 1 spaced, 2 with
    newlines and tabs. Iterative, so nesting depth does not matter."""
    item_sep, key_sep = ((",", ":"), (", ", ": "), (",\n\t", " :\n "))[style % 3]
    out: List[str] = []
    # A stack of work: values to write, or literal text (a tuple (_LIT, text)).
    stack: List[Any] = [value]
    while stack:
        v = stack.pop()
        if isinstance(v, tuple) and len(v) == 2 and v[0] is _LIT:
            out.append(v[1])
        elif isinstance(v, Raw):
            out.append(str(v))
        elif isinstance(v, Obj) or isinstance(v, dict):
            pairs = list(v) if isinstance(v, Obj) else list(v.items())
            work: List[Any] = [(_LIT, "{")]
            for i, (k, item) in enumerate(pairs):
                if i:
                    work.append((_LIT, item_sep))
                key = k if isinstance(k, Raw) else _dump_string(str(k), ascii_only)
                work.append((_LIT, key + key_sep))
                work.append(item)
            work.append((_LIT, "}"))
            stack.extend(reversed(work))
        elif isinstance(v, (list, tuple)):
            work = [(_LIT, "[")]
            for i, item in enumerate(v):
                if i:
                    work.append((_LIT, item_sep))
                work.append(item)
            work.append((_LIT, "]"))
            stack.extend(reversed(work))
        elif isinstance(v, str):
            out.append(_dump_string(v, ascii_only))
        elif v is None or isinstance(v, bool):
            out.append(json.dumps(v))
        elif isinstance(v, int):
            out.append(str(v))
        elif isinstance(v, float):
            if math.isnan(v):
                out.append("NaN")
            elif math.isinf(v):
                out.append("Infinity" if v > 0 else "-Infinity")
            else:
                out.append(repr(v))
        else:
            raise TypeError(f"cannot write {type(v).__name__} as JSON")
    return "".join(out)



# -- the generator ---------------------------------------------------------------------------

class FrameGenerator:
    """Frames from one seeded random stream. ``frames(n)`` gives the next ``n``; every call of
    a new generator with the same arguments gives the same frames."""

    def __init__(self, seed: Union[int, str], *, max_frame_bytes: int = MAX_FRAME_BYTES,
                 max_total_bytes: int = DEFAULT_MAX_TOTAL_BYTES) -> None:
        if max_frame_bytes < TINY_MAX_BYTES:
            raise ValueError(f"max_frame_bytes must be at least {TINY_MAX_BYTES}")
        self.rng = random.Random(seed)
        self.max_frame_bytes = int(max_frame_bytes)
        self.max_total_bytes = int(max_total_bytes)
        self.total_bytes = 0

    # -- the stream --------------------------------------------------------------------------

    def frames(self, count: int) -> List[Frame]:
        """The next ``count`` frames: each kind once first (in a seeded order; kinds too large
        for ``max_frame_bytes`` left out), then by :data:`WEIGHTS`. Raises ``ValueError`` when
        the total budget cannot hold ``count`` tiny frames."""
        left = self.max_total_bytes - self.total_bytes
        if count * TINY_MAX_BYTES > left:
            raise ValueError(f"{count} frames need a budget of at least "
                             f"{count * TINY_MAX_BYTES} bytes, {left} are left")
        kinds = [k for k in KINDS if self._fits(k)]
        first = list(kinds)
        self.rng.shuffle(first)
        weights = [WEIGHTS[k] for k in kinds]
        out: List[Frame] = []
        for i in range(count):
            kind = first[i] if i < len(first) else self.rng.choices(kinds, weights)[0]
            frame = self.frame(kind)
            # Keep room for the frames still to come, each at worst a tiny one.
            allowed = (self.max_total_bytes - self.total_bytes
                       - (count - i - 1) * TINY_MAX_BYTES)
            if frame.size > min(allowed, self.max_frame_bytes):
                frame = self._tiny(f"instead of a {kind} frame of {frame.size} bytes "
                                   "(over the budget)")
            self.total_bytes += frame.size
            out.append(frame)
        return out

    def _fits(self, kind: str) -> bool:
        if kind == "oversized_frame":
            return self.max_frame_bytes > FRAME_LIMIT_BYTES + 1024
        if kind == "oversized_message":
            return self.max_frame_bytes > MESSAGE_LIMIT_BYTES + 1024
        return True

    def frame(self, kind: str) -> Frame:
        """One frame of ``kind`` (not yet bounded by the budget: :meth:`frames` does that)."""
        if kind not in WEIGHTS:
            raise ValueError(f"unknown kind {kind!r}; known: {', '.join(KINDS)}")
        return getattr(self, "_k_" + kind)()

    # -- helpers -----------------------------------------------------------------------------

    def _text_frame(self, kind: str, note: str, text: str, fragments: int = 1) -> Frame:
        return Frame(kind, note, text.encode("utf-8"), False, fragments)

    def _encode(self, obj: Any) -> str:
        r = self.rng
        return dumps(obj, style=r.choice((0, 0, 0, 1, 2)), ascii_only=r.random() < 0.3)

    def _tiny(self, note: str) -> Frame:
        r = self.rng
        choice = r.randrange(4)
        if choice == 0:
            text = '{"type":"' + r.choice(_ODD_TYPES[:12]).strip("\x00\n") + '"}'
        elif choice == 1:
            text = r.choice(_NOT_OBJECTS)
        elif choice == 2:
            text = "".join(r.choices('{}[]":,0123456789abcdefnulltrue ', k=r.randrange(40)))
        else:
            text = '{"type":"reset","id":' + str(r.randrange(10 ** 6)) + "}"
        data = text.encode("utf-8")[:TINY_MAX_BYTES]
        return Frame("tiny", note, data, False, 1) if _utf8(data) else \
            Frame("tiny", note, b"{}", False, 1)

    def _name(self, pool: Sequence[str]) -> str:
        return self.rng.choice(pool)

    def _hex(self, n: int) -> str:
        return "".join(self.rng.choice(_HEX) for _ in range(n))

    def _belief_list(self, n: int = 7) -> List[float]:
        r = self.rng
        weights = [r.random() ** 3 for _ in range(n)]
        total = sum(weights) or 1.0
        probs = [w / total for w in weights]
        if r.random() < 0.5:  # printed with 6 significant digits, as a C++ solver would
            probs = [float(f"{p:.6g}") for p in probs]
        return probs

    def _small_int(self) -> int:
        return self.rng.choice((0, 1, 2, 3, 5, 10, 42, 99, 1000, 65535))

    def _random_unicode(self, n: int) -> str:
        r = self.rng
        chars = []
        for _ in range(n):
            pick = r.random()
            if pick < 0.5:
                c = r.randrange(0x20, 0x7f)
            elif pick < 0.6:
                c = r.choice((r.randrange(0, 0x20), 0x7f, r.randrange(0x80, 0xa0)))
            elif pick < 0.8:
                c = r.randrange(0xa0, 0xd800)
            elif pick < 0.9:
                c = r.randrange(0xe000, 0x10000)
            else:
                c = r.randrange(0x10000, 0x110000)
            chars.append(chr(c))
        return "".join(chars)

    # -- valid messages ----------------------------------------------------------------------

    def message(self, msg_type: Optional[str] = None) -> Obj:
        """A valid message (as :class:`Obj`) of ``msg_type`` (random when ``None``), with a
        random part of the envelope and sometimes an unknown extra field."""
        r = self.rng
        t = msg_type or r.choice(MESSAGE_TYPES)
        o = Obj([("type", t)])
        if t == "hello":
            o.append(("who", self._name(_WHO)))
            if r.random() < 0.8:
                o.append(("version", 2))
            if r.random() < 0.7:
                o.append(("nonce", self._hex(32)))
                o.append(("auth", self._hex(64)))
        elif t == "step":
            o += [("step", self._small_int()), ("action", self._name(_HUMAN_ACTIONS)),
                  ("state", self._name(_HUMAN_STATES))]
            if r.random() < 0.5:
                o.append(("reward", r.choice((-1.0, 0.0, 10.0, -0.5, 1e-3))))
            if r.random() < 0.5:
                o.append(("state_index", r.randrange(8)))
            if r.random() < 0.5:
                states = r.sample(_HUMAN_STATES, r.randint(1, 4))
                o.append(("belief", dict(zip(states, self._belief_list(len(states))))))
            if r.random() < 0.3:
                o.append(("manual", r.random() < 0.5))
        elif t == "observation":
            bits = r.choice(_LEGAL_BITS)
            o += [("step", self._small_int()), ("observation", f"O{bits}"),
                  ("bits", bits if r.random() < 0.8 else r.randrange(64)),
                  ("state", self._name(_ROBOT_STATES))]
        elif t == "decision":
            o += [("step", self._small_int()), ("action", self._name(_ROBOT_ACTIONS)),
                  ("belief", self._belief_list())]
            if r.random() < 0.5:
                o.append(("belief_states", list(_ROBOT_STATES)))
            if r.random() < 0.5:
                o.append(("decision_ms", round(r.random() * 100, 3)))
            if r.random() < 0.3:
                o.append(("surprise", r.random() < 0.5))
            if r.random() < 0.3:
                o.append(("rule", r.choice(("warning", "start", "budget"))))
        elif t == "action":
            o += [("step", self._small_int()), ("action", self._name(_ROBOT_ACTIONS))]
            if r.random() < 0.4:
                o.append(("belief", self._belief_list()))
                if r.random() < 0.5:
                    o.append(("belief_states", list(_ROBOT_STATES)))
            if r.random() < 0.3:
                o.append(("decision_ms", round(r.random() * 100, 3)))
        elif t == "reset":
            if r.random() < 0.6:
                o.append(("reason", r.choice(("fuzz", "enter pressed", "/hrc/reset called"))))
            if r.random() < 0.6:
                o.append(("episode", self._small_int()))
            if r.random() < 0.3:
                o += [("task_index", 1 + self._small_int()),
                      ("true_type", r.choice(("tired", "expert>tired@0.25"))),
                      ("human_model", r.choice(("tired", "/models/human/tired.pomdpx")))]
                if r.random() < 0.5:
                    o += [("drift_to", "expert"), ("drift", r.choice((0.0, 0.5, 1.0)))]
        elif t == "configure":
            if r.random() < 0.6:
                o.append(("reason", r.choice(("fuzz", "/hrc/configure called"))))
        elif t == "task_end":
            o += [("task_index", 1 + self._small_int()),
                  ("outcome", r.choice(("success", "fail", "timeout"))),
                  ("warnings", r.randrange(4)), ("preemptions", r.randrange(2)),
                  ("steps", self._small_int()), ("duration", round(r.random() * 80, 3)),
                  ("utility", round(r.random() * 2.5 - 1.5, 3))]
            if r.random() < 0.6:
                o.append(("who_succeeded", r.choice(("human", "robot"))))
        elif t == "task_report":
            o += [("selector", r.choice(("bpr", "random", "fixed:policy3"))),
                  ("policy", r.choice(("base", "policy3", "reactive")))]
            if r.random() < 0.5:
                o.append(("robot_model", "/models/fabric/robot/base.pomdpx"))
            if r.random() < 0.5:
                o += [("type_names", ["tired", "expert", "walker"][:3]),
                      ("type_belief", self._belief_list(3))]
            if r.random() < 0.5:
                o.append(("signature", [r.randrange(64) for _ in range(r.randrange(6))]))
            if r.random() < 0.4:
                o.append(("total_disc_reward", round(r.random() * 20 - 5, 3)))
        elif t == "next_state":
            o.append(("state", r.choice((None, 0, 3, 7))))
        elif t == "reaction":
            o += [("step", self._small_int()), ("state", self._name(_HUMAN_STATES))]
            if r.random() < 0.5:
                o.append(("state_index", r.randrange(8)))
            if r.random() < 0.4:
                o.append(("rule", r.choice(("robot_grasped", "robot_pointed", "model"))))
            if r.random() < 0.3:
                o.append(("reward", r.choice((-1.0, 0.0, 4.0))))
        elif t == "ack":
            o.append(("step", self._small_int()))
            if r.random() < 0.5:
                o.append(("of", r.choice(("reset", "step", "action", "next_state"))))
            if r.random() < 0.4:
                o.append(("action", self._name(_ROBOT_ACTIONS)))
            if r.random() < 0.4:
                o.append(("success", r.random() < 0.5))
            if r.random() < 0.4:
                o.append(("result", r.choice(("", "done", "robot points at the object"))))
            if r.random() < 0.3:
                o.append(("episode", self._small_int()))
            if r.random() < 0.3:
                o.append(("episode_over", r.random() < 0.5))
            if r.random() < 0.2:
                o.append(("end_reason", r.choice(("success", "step_limit"))))
        elif t == "error":
            o.append(("message", r.choice(("nope", "fuzz error", "x" * 200))))
            if r.random() < 0.6:
                o.append(("code", r.choice(_ERROR_CODES + ("made_up",))))
            if r.random() < 0.4:
                o.append(("in_reply_to", r.choice(MESSAGE_TYPES)))
            if r.random() < 0.3:
                o.append(("step", self._small_int()))
        for name in _ENVELOPE:
            if r.random() < 0.4:
                # epoch: a ROS uint32 on the wire to ROS; id and reply_to: up to 2**53 - 1.
                top = 2 ** 32 - 1 if name == "epoch" else 2 ** 53 - 1
                o.append((name, r.choice((0, 1, r.randrange(1 << 20), top))))
        if r.random() < 0.1:
            o.append(("x_fuzz", r.choice((1, "extra", [1, {"a": None}], {"nested": [True]}))))
        return o

    # -- mutations (each changes one message in place and says what it did) ---------------------

    def _field(self, o: Obj, prefer: Sequence[str] = ()) -> str:
        keys = [k for k in o.keys() if isinstance(k, str)]
        preferred = [k for k in keys if k in prefer]
        return self.rng.choice(preferred or keys or ["type", "step", "x"])

    def _m_missing_field(self, o: Obj) -> str:
        key = self._field(o)
        o.drop(key)
        return f"removed {key}"

    def _wrong_value(self, current: Any) -> Any:
        r = self.rng
        pool = [None, True, False, 0, -3, 1.5, "3", "", "x", [], [1, "a"], {}, {"k": 1},
                Raw('"\\u0000"'), [[[]]], "true", "null", 3.0]
        value = r.choice(pool)
        if type(value) is type(current) and value == current:
            return None if current is not None else "x"
        return value

    def _m_wrong_type(self, o: Obj) -> str:
        key = self._field(o)
        value = self._wrong_value(o.get(key))
        o.set(key, value)
        return f"{key} = {dumps(value)[:40]}"

    def _m_huge_number(self, o: Obj) -> str:
        r = self.rng
        key = self._field(o, _INT_FIELDS) if r.random() < 0.85 else r.choice(_INT_FIELDS)
        pick = r.random()
        if pick < 0.25:
            digits = r.choice((4300, 4301, 5000, 5000))
            text = r.choice("123456789") + "".join(r.choices("0123456789", k=digits - 1))
            if r.random() < 0.2:
                text = "-" + text
            note = f"{len(text.lstrip('-'))}-digit integer"
        elif pick < 0.85:
            text = r.choice(_BIG_INTS)
            note = text
        else:
            text = r.choice(_NUMBER_ODDITIES)
            note = text[:30]
        o.set(key, Raw(text))
        return f"{key} = {note}"

    def _m_special_number(self, o: Obj) -> str:
        r = self.rng
        keys = o.keys()
        numeric = [k for k in keys if k in _INT_FIELDS + ("reward", "decision_ms")]
        literal = Raw(r.choice(_SPECIAL_NUMBERS))
        if "belief" in keys and r.random() < 0.4:
            belief = o.get("belief")
            if isinstance(belief, list) and belief:
                belief = list(belief)
                belief[r.randrange(len(belief))] = literal
                o.set("belief", belief)
                return f"belief entry = {literal}"
            if isinstance(belief, dict) and belief:
                belief = dict(belief)
                belief[r.choice(list(belief))] = literal
                o.set("belief", belief)
                return f"belief value = {literal}"
        key = r.choice(numeric) if numeric and r.random() < 0.8 else r.choice(
            ("x_number", "reward", "decision_ms", "step"))
        o.set(key, literal)
        return f"{key} = {literal}"

    def _string_field(self, o: Obj) -> str:
        keys = [k for k, v in o if isinstance(v, str) and k != "type"]
        if keys and self.rng.random() < 0.85:
            return self.rng.choice(keys)
        return self.rng.choice(("who", "action", "state", "observation", "message", "reason",
                                "result", "code", "in_reply_to", "of", "rule", "x_text",
                                "type"))

    def _m_surrogate(self, o: Obj) -> str:
        r = self.rng
        key = self._string_field(o)
        esc = r.choice(_SURROGATES) if r.random() < 0.85 else r.choice(_SURROGATE_PAIRS)
        current = o.get(key)
        prefix = current[:10] if isinstance(current, str) else ""
        if r.random() < 0.15:  # in a key instead of a value
            o.append((Raw(f'"k{esc}"'), 1))
            return f"key with {esc}"
        o.set(key, Raw(json.dumps(prefix)[:-1] + esc + '"'))
        return f"{key} with {esc}"

    def _m_control_chars(self, o: Obj) -> str:
        r = self.rng
        key = self._string_field(o)
        c = r.choice(_CONTROL)
        current = o.get(key)
        base = current if isinstance(current, str) and current else "ab"
        at = r.randrange(len(base) + 1)
        value = base[:at] + c + base[at:]
        if r.random() < 0.3 and c not in '"\\':
            o.set(key, Raw('"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'))
            how = "raw"
        else:
            o.set(key, value)
            how = "escaped"
        return f"{key} with U+{ord(c):04X} ({how})"

    def _m_long_string(self, o: Obj) -> str:
        r = self.rng
        key = self._string_field(o)
        unit = r.choice(("a", "\u00e9", "\u4e2d", "\U0001f600", "ab ", "\\"))
        n = r.choice((129, 1025, 5000, r.randrange(20000, 60000)))
        # At most ~60 KB however it is written (\ud83d\ude00 is 12 bytes): under the
        # message limit, so the field's own check answers, not the size check.
        n = min(n, 60000 * len(unit) // (len(json.dumps(unit)) - 2))
        o.set(key, (unit * n)[:n])
        return f"{key} of {n} characters"

    def _m_deep_nesting(self, o: Obj) -> str:
        r = self.rng
        depth = r.choice((64, 100, 1000, 5000, 20000, 30000))
        key = self._field(o) if r.random() < 0.7 else "x_deep"
        if r.random() < 0.7:
            value = Raw("[" * depth + ("1" if r.random() < 0.5 else "") + "]" * depth)
            what = "arrays"
        else:
            depth = min(depth, 10000)  # 6 bytes a level: still under the message limit
            value = Raw('{"a":' * depth + "0" + "}" * depth)
            what = "objects"
        if r.random() < 0.1:  # never closed
            value = Raw(str(value)[: len(value) // 2])
            what += ", unclosed"
        o.set(key, value)
        return f"{key} = {what} nested {depth} deep"

    def _m_duplicate_key(self, o: Obj) -> str:
        r = self.rng
        key = self._field(o)
        value = o.get(key) if r.random() < 0.5 else self._wrong_value(o.get(key))
        o.insert(r.randrange(len(o) + 1), (key, value))
        return f"{key} twice"

    def _m_unknown_type(self, o: Obj) -> str:
        r = self.rng
        pick = r.random()
        if pick < 0.7:
            value: Any = r.choice(_ODD_TYPES)
        elif pick < 0.9:
            value = r.choice((1, None, True, ["error"], {"type": "error"}, 2.5, ["step"]))
        else:
            o.drop("type")
            o.append(("Type", r.choice(MESSAGE_TYPES)))
            return "Type instead of type"
        o.set("type", value)
        return f"type = {dumps(value)[:40]}"

    def _m_envelope(self, o: Obj) -> str:
        r = self.rng
        key = r.choice(_ENVELOPE)
        value = r.choice((Raw("-1"), Raw("4294967295"), Raw("4294967296"),
                          Raw("9007199254740991"), Raw("9007199254740992"),
                          Raw("18446744073709551616"), Raw("-9007199254740992"), True, False,
                          3.0, Raw("1e2"), "3", None, [], {}, Raw("1e999"), Raw("NaN"),
                          Raw("5" * 5000), 0.5, Raw("-0")))
        o.set(key, value)
        return f"{key} = {dumps(value)[:30]}"

    def _m_belief(self, o: Obj) -> str:
        r = self.rng
        t = o.get("type")
        if t not in ("step", "decision", "action"):
            o.set("type", t := r.choice(("step", "decision", "action")))
            for name, value in self.message(t):
                if name not in o.keys():
                    o.append((name, value))
        n = r.randint(1, 8)
        probs: List[Any] = self._belief_list(n)
        names: List[str] = [f"h{i}" for i in range(n)] if t == "step" else list(_ROBOT_STATES[:n])
        pick = r.randrange(12)
        if pick == 0:
            probs = [p * r.choice((0.5, 2.0, 0.999, 1.001)) for p in probs]
            note = "not summing to 1"
        elif pick == 1:
            probs[0] -= 0.5
            probs[-1] += 0.5
            note = "with a negative probability"
        elif pick == 2:
            probs, names = [], []
            note = "empty"
        elif pick == 3:
            probs = [p + 2e-4 / n for p in probs]
            note = "off by 2e-4"
        elif pick == 4:
            probs = [p + 5e-5 / n for p in probs]
            note = "off by 5e-5 (within the tolerance)"
        elif pick == 5:
            probs = [str(p) for p in probs]
            note = "of strings"
        elif pick == 6:
            probs = [0.0] * n
            note = "all zero"
        elif pick == 7:
            probs = [1e308] * n
            note = "of 1e308 each (the sum overflows)"
        elif pick == 8:
            probs = [1.0 / n] * n + [None]
            names = names + ["hnull"]
            note = "with a null entry"
        elif pick == 9:
            probs = [probs, probs]
            names = names[:2] if len(names) >= 2 else ["a", "b"]
            note = "nested"
        elif pick == 10:
            o.set("belief", r.choice(("0.5", 1, True, None, {"S0": 1.0}, [[1.0]], [])))
            return "belief of a wrong type"
        elif t == "step":
            names = [r.choice(("", " ", "x" * 129, "a\u0000", "S0")) for _ in range(n)]
            note = "with odd state names"
        else:
            o.set("belief", probs)
            choice = r.randrange(3)
            if choice == 0:
                o.set("belief_states", names + ["extra"])
                return "belief_states longer than the belief"
            if choice == 1:
                o.set("belief_states", ["S0"] * n)
                return "belief_states repeating a name"
            o.drop("belief")
            o.set("belief_states", names)
            return "belief_states without a belief"
        if t == "step":
            o.set("belief", Obj(list(zip(names, probs))))
        else:
            o.set("belief", probs)
        return f"belief {note}"

    def _m_field_range(self, o: Obj) -> str:
        r = self.rng
        t = o.get("type")
        options = {
            "hello": [("version", 0), ("version", 1), ("version", 3), ("version", 2 ** 31),
                      ("version", 2 ** 31 - 1), ("who", ""), ("who", "w" * 129)],
            "step": [("step", -1), ("step", 2 ** 32), ("step", 2 ** 32 - 1),
                     ("state_index", 256), ("state_index", 255), ("state_index", -1),
                     ("action", ""), ("action", "teleport"), ("state", "x" * 129),
                     ("reward", -1e308)],
            "observation": [("bits", 64), ("bits", -1), ("bits", 63), ("observation", "O99"),
                            ("observation", ""), ("state", "S99"), ("step", 2 ** 32)],
            "decision": [("decision_ms", -1.0), ("action", ""), ("rule", "r" * 129)],
            "action": [("action", "rFly"), ("action", ""), ("decision_ms", -0.001),
                       ("step", 2 ** 32)],
            "reset": [("episode", -1), ("episode", 2 ** 32), ("reason", ""),
                      ("reason", "r" * 1025), ("task_index", 0), ("human_model", ""),
                      ("drift", 1.5)],
            "task_end": [("task_index", 0), ("steps", -1), ("duration", -1.0),
                         ("utility", 1e309), ("outcome", ""), ("warnings", 2 ** 32)],
            "task_report": [("policy", ""), ("selector", "s" * 129), ("signature", [64]),
                            ("signature", [-1]), ("type_belief", [0.5, 0.6]),
                            ("total_disc_reward", 1e309)],
            "next_state": [("state", 256), ("state", 255), ("state", -1), ("state", 8)],
            "configure": [("reason", ""), ("reason", "r" * 1025)],
            "reaction": [("step", -1), ("state", ""), ("state_index", 256), ("rule", "r" * 129),
                         ("reward", 1e309)],
            "ack": [("step", -1), ("of", ""), ("result", "r" * 1025), ("result", ""),
                    ("episode", 2 ** 32), ("end_reason", "")],
            "error": [("message", ""), ("message", "m" * 1025), ("code", ""),
                      ("in_reply_to", "i" * 129), ("step", -1)],
        }.get(t if isinstance(t, str) else "", [("step", -1)])
        key, value = r.choice(options)
        o.set(key, value)
        return f"{key} = {dumps(value)[:30]}"

    def _m_extra_fields(self, o: Obj) -> str:
        r = self.rng
        name = r.choice(("x", "", " ", "n" * 129, "a\u0000b", "\u00e9t\u00e9", "__proto__",
                         "extra", "x.y", "1", "\U0001f600", "\u2028"))
        value = r.choice((1, "v", None, [1, [2, [3]]], {"a": {"b": {"c": None}}}, Raw("NaN"),
                          Raw("[1e999]"), Raw('{"n":-Infinity}'), 2 ** 70, True, "\u0085",
                          Raw('"\\ud800"'), [Raw("1e999")]))
        o.append((name, value))
        return f"extra field {dumps(name)[:20]} = {dumps(value)[:30]}"

    _MUTATIONS = ("missing_field", "wrong_type", "huge_number", "special_number", "surrogate",
                  "control_chars", "long_string", "deep_nesting", "duplicate_key",
                  "unknown_type", "envelope", "belief", "field_range", "extra_fields")

    def _mutate(self, o: Obj, mutation: str) -> str:
        return getattr(self, "_m_" + mutation)(o)

    # -- the kinds ---------------------------------------------------------------------------

    def _mutation_kind(self, mutation: str) -> Frame:
        o = self.message()
        note = f"{o.get('type')}: "
        note += self._mutate(o, mutation)
        return self._text_frame(mutation, note, self._encode(o))

    def _k_missing_field(self) -> Frame:
        return self._mutation_kind("missing_field")

    def _k_wrong_type(self) -> Frame:
        return self._mutation_kind("wrong_type")

    def _k_huge_number(self) -> Frame:
        return self._mutation_kind("huge_number")

    def _k_special_number(self) -> Frame:
        return self._mutation_kind("special_number")

    def _k_surrogate(self) -> Frame:
        return self._mutation_kind("surrogate")

    def _k_control_chars(self) -> Frame:
        return self._mutation_kind("control_chars")

    def _k_long_string(self) -> Frame:
        return self._mutation_kind("long_string")

    def _k_deep_nesting(self) -> Frame:
        return self._mutation_kind("deep_nesting")

    def _k_duplicate_key(self) -> Frame:
        return self._mutation_kind("duplicate_key")

    def _k_unknown_type(self) -> Frame:
        return self._mutation_kind("unknown_type")

    def _k_envelope(self) -> Frame:
        return self._mutation_kind("envelope")

    def _k_belief(self) -> Frame:
        return self._mutation_kind("belief")

    def _k_field_range(self) -> Frame:
        return self._mutation_kind("field_range")

    def _k_extra_fields(self) -> Frame:
        return self._mutation_kind("extra_fields")

    def _k_mutated(self) -> Frame:
        r = self.rng
        o = self.message()
        msg_type = o.get("type")
        notes = [self._mutate(o, r.choice(self._MUTATIONS)) for _ in range(r.randint(1, 3))]
        return self._text_frame("mutated", f"{msg_type}: " + "; ".join(notes), self._encode(o))

    def _k_binary_random(self) -> Frame:
        r = self.rng
        n = r.choice((0, 1, 2, 16, 100, 1000, r.randrange(4096)))
        data = bytes(r.getrandbits(8) for _ in range(n))
        return Frame("binary_random", f"{n} random bytes", data, True)

    def _k_binary_message(self) -> Frame:
        o = self.message()
        return Frame("binary_message", f"a valid {o.get('type')} as a binary frame",
                     self._encode(o).encode("utf-8"), True)

    def _k_text_random(self) -> Frame:
        n = self.rng.choice((1, 10, 100, 1000))
        return self._text_frame("text_random", f"{n} random characters",
                                self._random_unicode(n))

    def _k_text_noise(self) -> Frame:
        r = self.rng
        n = r.choice((1, 5, 30, 200, 2000))
        alphabet = '{}[]":,.-+eE0123456789 \t\n\\/utfnlrsaxy"type""error"'
        text = "".join(r.choice(alphabet) for _ in range(n))
        return self._text_frame("text_noise", f"{n} characters of JSON-ish noise", text)

    def _k_empty(self) -> Frame:
        text = self.rng.choice(("", " ", "\n", "\t\r\n ", "\ufeff", "{}", "null", "[]",
                                "\ufeff{}", '\ufeff{"type":"reset"}', "{ }", "\u00a0{}"))
        return self._text_frame("empty", f"{text!r}", text)

    def _k_json_truncated(self) -> Frame:
        r = self.rng
        text = self._encode(self.message())
        cut = r.randrange(0, max(1, len(text) - 1))
        return self._text_frame("json_truncated", f"cut at {cut} of {len(text)}", text[:cut])

    def _k_json_corrupted(self) -> Frame:
        r = self.rng
        chars = list(self._encode(self.message()))
        edits = r.randint(1, 4)
        done = []
        for _ in range(edits):
            at = r.randrange(len(chars)) if chars else 0
            op = r.randrange(4)
            if op == 0 and chars:
                chars[at] = r.choice('{}[]":,\\ 0aZ\x00\u00ff')
                done.append(f"flip@{at}")
            elif op == 1 and chars:
                del chars[at]
                done.append(f"drop@{at}")
            elif op == 2:
                chars.insert(at, r.choice('{}[]":,\\ 0aZ\x01'))
                done.append(f"insert@{at}")
            else:
                chars[at:at] = chars[at:at + r.randint(1, 8)]
                done.append(f"repeat@{at}")
        return self._text_frame("json_corrupted", " ".join(done), "".join(chars))

    def _k_json_not_object(self) -> Frame:
        text = self.rng.choice(_NOT_OBJECTS)
        return self._text_frame("json_not_object", text[:30], text)

    def _k_hello_unproven(self) -> Frame:
        r = self.rng
        o = Obj([("type", "hello"), ("who", self._name(_WHO)), ("version", 2)])
        pick = r.randrange(9)
        if pick == 0:
            note = "no nonce, no auth"
        elif pick == 1:
            o += [("nonce", self._hex(32))]
            note = "a nonce, no auth"
        elif pick == 2:
            o += [("auth", self._hex(64))]
            note = "an auth, no nonce"
        elif pick == 3:
            o += [("nonce", self._hex(32)), ("auth", self._hex(64))]
            note = "a wrong proof"
        elif pick == 4:
            o += [("nonce", self._hex(32).upper()), ("auth", self._hex(64))]
            note = "an uppercase nonce"
        elif pick == 5:
            o += [("nonce", self._hex(r.choice((0, 31, 129)))), ("auth", self._hex(64))]
            note = "a nonce of a wrong length"
        elif pick == 6:
            o += [("nonce", self._hex(32)), ("auth", self._hex(r.choice((0, 63, 65, 128))))]
            note = "an auth of a wrong length"
        elif pick == 7:
            o += [("nonce", "g" * 32), ("auth", "z" * 64)]
            note = "not hex"
        else:
            o += [("nonce", self._hex(32)), ("auth", None)]
            note = "auth null"
        return self._text_frame("hello_unproven", note, self._encode(o))

    def _k_error_malformed(self) -> Frame:
        r = self.rng
        o = self.message("error")
        pick = r.randrange(12)
        if pick < 6:
            mutation = r.choice(("missing_field", "wrong_type", "huge_number", "special_number",
                                 "surrogate", "control_chars", "long_string", "duplicate_key",
                                 "envelope", "field_range", "extra_fields", "deep_nesting"))
            # Every field but the type is fair game: it stays an error.
            fields = Obj(o[1:]) if len(o) > 1 else Obj([("message", "m")])
            fields.append(("type", "error"))
            note = self._mutate(fields, mutation)
            fields.drop("type")
            text = self._encode(Obj([("type", "error")] + list(fields)))
        elif pick == 6:
            text = self._encode(o)
            kept = _ERROR_TYPE.search(text).end()  # still says it is an error
            text = text[:r.randrange(kept, len(text))]
            note = "truncated"
        elif pick == 7:
            text = '{ "type" : "error" , ' + r.choice(('"message":', '"message": }', '}', ''))
            note = "spaced and broken"
        elif pick == 8:
            text = '{"type":"error","message":"' + "e" * r.choice((10, 2000)) + '",' \
                   '"type":"error"}'
            note = "type twice"
        elif pick == 9:
            text = '{"type":"error"}'
            note = "no message"
        elif pick == 10:
            text = '[{"type":"error","message":"in an array"}]'
            note = "in an array"
        else:
            text = '{"type":"error","message":"x","step":' + "7" * 5000 + "}"
            note = "a 5000-digit step"
        return self._text_frame("error_malformed", f"error: {note}", text)

    def _k_valid(self) -> Frame:
        o = self.message()
        return self._text_frame("valid", f"a valid {o.get('type')}", self._encode(o))

    def _k_fragmented(self) -> Frame:
        r = self.rng
        if r.random() < 0.3:
            o = self.message()
            note = f"a valid {o.get('type')}"
        else:
            o = self.message()
            note = f"{o.get('type')}: " + self._mutate(o, r.choice(self._MUTATIONS))
        text = self._encode(o)
        parts = r.randint(2, 6)
        return self._text_frame("fragmented", f"{note}, in {parts} fragments", text, parts)

    def _k_oversized_message(self) -> Frame:
        r = self.rng
        top = min(FRAME_LIMIT_BYTES, self.max_frame_bytes)
        target = r.randrange(MESSAGE_LIMIT_BYTES + 1, top + 1)
        o = self.message(r.choice(MESSAGE_TYPES))
        how = r.randrange(3)
        if how == 0:
            o.append(("padding", ""))
            base = len(self._encode_compact(o).encode("utf-8"))
            o.set("padding", "p" * max(0, target - base))
            text = self._encode_compact(o)
            note = "a long extra field"
        elif how == 1:
            text = self._encode_compact(o)
            text = text[:-1] + " " * max(0, target - len(text.encode("utf-8"))) + "}"
            note = "whitespace padding"
        else:
            o.append(("big", []))
            base = len(self._encode_compact(o).encode("utf-8"))
            o.set("big", Raw("[" + ",".join("1" * max(0, (target - base) // 2)) + "]"))
            text = self._encode_compact(o)
            note = "a long array"
        return self._text_frame("oversized_message", f"{o.get('type')}, {note}", text)

    def _encode_compact(self, o: Any) -> str:
        return dumps(o, style=0, ascii_only=True)

    def _k_oversized_frame(self) -> Frame:
        r = self.rng
        target = r.randrange(FRAME_LIMIT_BYTES + 1, self.max_frame_bytes + 1)
        pick = r.randrange(3)
        if pick == 0:
            head = '{"type":"step","step":1,"action":"idle","state":"tired","x":"'
            text = head + "a" * (target - len(head) - 2) + '"}'
            return self._text_frame("oversized_frame", f"a step of {target} bytes", text)
        if pick == 1:
            data = bytes(r.getrandbits(8) for _ in range(256)) * (target // 256 + 1)
            return Frame("oversized_frame", f"{target} binary bytes", data[:target], True)
        head = '{"type":"error","message":"'
        text = head + "e" * (target - len(head) - 2) + '"}'
        return self._text_frame("oversized_frame", f"an error of {target} bytes", text)

    def _k_invalid_utf8(self) -> Frame:
        r = self.rng
        bad = r.choice((b"\xff", b"\xc0\xaf", b"\xed\xa0\x80", b"\xf8\x88\x80\x80\x80",
                        b"\xe2\x82", b"\x80"))
        text = self._encode(self.message()).encode("utf-8")
        at = r.randrange(len(text) + 1)
        return Frame("invalid_utf8", f"bytes {bad!r} at {at}", text[:at] + bad + text[at:],
                     False)


def _utf8(data: bytes) -> bool:
    try:
        data.decode("utf-8")
        return True
    except UnicodeDecodeError:
        return False


def generate(seed: Union[int, str], count: int, *, max_frame_bytes: int = MAX_FRAME_BYTES,
             max_total_bytes: int = DEFAULT_MAX_TOTAL_BYTES) -> List[Frame]:
    """``count`` frames of seed ``seed`` (see the module docstring)."""
    return FrameGenerator(seed, max_frame_bytes=max_frame_bytes,
                          max_total_bytes=max_total_bytes).frames(count)


def fragment_sizes(frame: Frame) -> List[int]:
    """The byte sizes of a frame's fragments: ``fragments`` near-equal parts (an empty last
    one when the payload is shorter than the number of fragments)."""
    n = max(1, frame.fragments)
    size = frame.size
    step = max(1, -(-size // n))
    sizes = [min(step, max(0, size - i * step)) for i in range(n)]
    return sizes


def main(argv: Optional[List[str]] = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", default="1")
    parser.add_argument("--count", type=int, default=40)
    args = parser.parse_args(argv)
    seed: Union[int, str] = int(args.seed) if args.seed.isdigit() else args.seed
    frames = generate(seed, args.count)
    for i, f in enumerate(frames):
        print(f"{i:5d} {f.kind:18s} {'bin' if f.binary else 'txt'} x{f.fragments} "
              f"{f.size:7d}  {f.note[:60]}\n      {f.preview(100)}")
    print(f"{len(frames)} frames, {sum(f.size for f in frames)} bytes")


if __name__ == "__main__":
    main()
