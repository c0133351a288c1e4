"""What each field of a message may hold, and the checker that holds a message to it.

Every message validates itself when it is built (:mod:`ros_hrc.link.messages`) through a
:class:`Checker`: it normalises each field (numbers to ``float``, arrays to tuples) and refuses
a wrong one with a :class:`~ros_hrc.link.refusals.MessageError` whose reason is one line
naming the message type, the field and what is wrong, e.g. ``step message: field "epoch" must
be in 0..4294967295, got -1``.

Why a checker of our own and not a validation library (pydantic 2.14 was tried on these
types): each of these one-line reasons would have to be rebuilt from the library's generic
errors ("Input should be a valid integer", one bound at a time, no position of a control
character; a ninth positional argument is a ValidationError, not a TypeError), and the checks
no library has (a belief summing to one within a tolerance, a name per probability, extra
fields that must be finite, an extra field clashing with a named one) would stay written here
anyway: the code would not get shorter, and every process would import 140 ms more.
"""
from __future__ import annotations

import json
import math
import re
from typing import Any, Dict, List, Mapping, Optional, Tuple

from ros_hrc.link.refusals import MessageError

#: A belief must sum to one within this; it tolerates beliefs printed with 6 significant
#: digits by a foreign (e.g. C++) solver, and still catches an unnormalised one.
BELIEF_TOLERANCE = 1e-4
#: Bit patterns of an observation: the seed's six bits (DESIGN §4) and a seventh, 64 (the
#: object left the belt), that a task may observe (``fabric``: the authors' "failure" bit).
MAX_BITS = 127
#: Largest ``epoch`` / ``id`` / ``reply_to``: 2**53 - 1, the largest integer every JSON reader
#: (a double) holds exactly.
MAX_ENVELOPE_INT = 2 ** 53 - 1
#: Largest ``epoch``, ``step``, ``episode``: each reaches a ``uint32`` of a ROS message
#: (``/hrc/status``), so a larger one is refused here,
#: before anything acts on it.
MAX_UINT32 = 2 ** 32 - 1
#: Largest ``state_index`` and ``next_state.state``: a ``uint8`` of ``/hrc/status``.
MAX_STATE_INDEX = 255
#: The largest signature code of a task report: one step's six human observables, a bit each.
MAX_SIGNATURE_CODE = 63
#: Largest protocol ``version`` a hello may name.
MAX_VERSION = 2 ** 31 - 1
#: Longest name (``who``, an action, a state, an observation, ``of``, ``code``, ``rule``, ...),
#: in characters; the seed's longest is 15.
MAX_NAME_CHARS = 128
#: Longest free text (``reason``, ``result``, ``message``), in characters.
MAX_TEXT_CHARS = 1024
#: A hello's ``nonce``: 32 to 128 lowercase hex digits; its ``auth``: exactly 64.
NONCE_HEX_RANGE = (32, 128)
AUTH_HEX_CHARS = 64

#: Error texts quote at most this much of an offending value, so a reply stays small.
PREVIEW_CHARS = 40
#: Control characters (C0, DEL, C1): no text field may hold one, so nothing a peer sends can
#: break a log line in two or drive a terminal.
CONTROL_CHARACTERS = re.compile("[\x00-\x1f\x7f-\x9f]")
_LOWER_HEX = re.compile("[0-9a-f]*")


def kind_of(value: Any) -> str:
    """The JSON name of a value's type, for error texts."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "string"
    if isinstance(value, (list, tuple)):
        return "array"
    if isinstance(value, dict):
        return "object"
    return type(value).__name__


def preview(value: Any) -> str:
    """A value as JSON, cut short after :data:`PREVIEW_CHARS` characters, for error texts."""
    try:
        text = json.dumps(value, ensure_ascii=False)
    except (TypeError, ValueError):
        try:
            text = repr(value)
        except ValueError:  # an int too long for str()
            text = f"<{kind_of(value)}>"
    return text if len(text) <= PREVIEW_CHARS else text[:PREVIEW_CHARS] + "..."


def is_count(value: Any, maximum: Optional[int] = None) -> bool:
    """A JSON integer >= 0 (and <= ``maximum``): not a bool, not a float."""
    return (isinstance(value, int) and not isinstance(value, bool) and value >= 0
            and (maximum is None or value <= maximum))


class Checker:
    """Validates and normalises one message's fields; every complaint names the type and field."""

    def __init__(self, msg_type: str) -> None:
        self.msg_type = msg_type

    def fail(self, name: str, problem: str) -> MessageError:
        return MessageError(f'{self.msg_type} message: field "{name}" {problem}', self.msg_type)

    def _got(self, value: Any) -> str:
        return f"got {kind_of(value)} {preview(value)}"

    def integer(self, name: str, value: Any, minimum: int = 0,
                maximum: Optional[int] = None) -> int:
        # bool is an int in Python but not in JSON: true is not a step number.
        if not isinstance(value, int) or isinstance(value, bool):
            raise self.fail(name, f"must be an integer, {self._got(value)}")
        if value < minimum or (maximum is not None and value > maximum):
            bounds = f"in {minimum}..{maximum}" if maximum is not None else f">= {minimum}"
            raise self.fail(name, f"must be {bounds}, got {preview(value)}")
        return value

    def number(self, name: str, value: Any, minimum: Optional[float] = None) -> float:
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise self.fail(name, f"must be a number, {self._got(value)}")
        try:
            value = float(value)
        except OverflowError:  # an integer too large for a double
            raise self.fail(name, "must be finite, got a number too large") from None
        if not math.isfinite(value):
            raise self.fail(name, f"must be finite, got {value}")
        if minimum is not None and value < minimum:
            raise self.fail(name, f"must be >= {minimum}, got {value}")
        return value

    def _string(self, name: str, value: Any, limit: int) -> str:
        if not isinstance(value, str):
            raise self.fail(name, f"must be a string, {self._got(value)}")
        if len(value) > limit:
            raise self.fail(name, f"must be at most {limit} characters, has {len(value)}")
        bad = CONTROL_CHARACTERS.search(value)
        if bad:
            raise self.fail(name, f"must not hold control characters, has U+{ord(bad.group()):04X} "
                                  f"at character {bad.start()}")
        return value

    def text(self, name: str, value: Any) -> str:
        """A name: not empty, at most :data:`MAX_NAME_CHARS`, no control characters."""
        value = self._string(name, value, MAX_NAME_CHARS)
        if not value:
            raise self.fail(name, "must not be empty")
        return value

    def prose(self, name: str, value: Any) -> str:
        """Free text for people: not empty, at most :data:`MAX_TEXT_CHARS`, no control
        characters."""
        value = self._string(name, value, MAX_TEXT_CHARS)
        if not value:
            raise self.fail(name, "must not be empty")
        return value

    def any_text(self, name: str, value: Any) -> str:
        """Free text that may be empty."""
        return self._string(name, value, MAX_TEXT_CHARS)

    def hex_text(self, name: str, value: Any, lengths: Tuple[int, int]) -> str:
        """Lowercase hex digits, between ``lengths[0]`` and ``lengths[1]`` of them."""
        if not isinstance(value, str):
            raise self.fail(name, f"must be a string, {self._got(value)}")
        low, high = lengths
        if not (low <= len(value) <= high) or not _LOWER_HEX.fullmatch(value):
            size = f"{low}" if low == high else f"{low} to {high}"
            raise self.fail(name, f"must be {size} lowercase hex digits")
        return value

    def flag(self, name: str, value: Any) -> bool:
        if not isinstance(value, bool):
            raise self.fail(name, f"must be true or false, {self._got(value)}")
        return value

    def _probability_sum(self, name: str, total: float) -> None:
        if abs(total - 1.0) > BELIEF_TOLERANCE:
            raise self.fail(name, f"must sum to 1 (within {BELIEF_TOLERANCE:g}), "
                                  f"sums to {total:.9g}")

    def belief_list(self, name: str, value: Any) -> Tuple[float, ...]:
        if not isinstance(value, (list, tuple)):
            raise self.fail(name, f"must be an array of probabilities, {self._got(value)}")
        if not value:
            raise self.fail(name, "must not be empty")
        probs = tuple(self.probability(f"{name}[{i}]", p) for i, p in enumerate(value))
        self._probability_sum(name, math.fsum(probs))
        return probs

    def belief_map(self, name: str, value: Any) -> Dict[str, float]:
        if not isinstance(value, Mapping):
            raise self.fail(name, f"must be an object {{state: probability}}, {self._got(value)}")
        if not value:
            raise self.fail(name, "must not be empty")
        probs: Dict[str, float] = {}
        for key, p in value.items():
            if not isinstance(key, str) or not key:
                raise self.fail(name, "must have non-empty state names as keys, "
                                      f"got {preview(key)}")
            self.text(f"{name} key", key)
            probs[key] = self.probability(f"{name}.{key}", p)
        self._probability_sum(name, math.fsum(probs.values()))
        return probs

    def probability(self, name: str, value: Any) -> float:
        value = self.number(name, value)
        if value < 0:
            raise self.fail(name, f"must not be negative, got {value}")
        if value > 1.0 + BELIEF_TOLERANCE:   # and so a sum can never overflow
            raise self.fail(name, f"must be at most 1, got {value:.9g}")
        return value

    def names(self, name: str, value: Any) -> Tuple[str, ...]:
        if not isinstance(value, (list, tuple)):
            raise self.fail(name, f"must be an array of strings, {self._got(value)}")
        items = tuple(self.text(f"{name}[{i}]", v) for i, v in enumerate(value))
        if len(set(items)) != len(items):
            raise self.fail(name, "must not repeat a name")
        return items

    def codes(self, name: str, value: Any, maximum: int) -> Tuple[int, ...]:
        """An array of integers from 0 to ``maximum`` (e.g. a task's signature codes)."""
        if not isinstance(value, (list, tuple)):
            raise self.fail(name, f"must be an array of integers, {self._got(value)}")
        return tuple(self.integer(f"{name}[{i}]", v, maximum=maximum)
                     for i, v in enumerate(value))

    def belief_names(self, belief: Optional[Tuple[float, ...]], value: Any) -> Tuple[str, ...]:
        """``belief_states``: names for the probabilities of ``belief``, same length."""
        names = self.names("belief_states", value)
        if belief is None:
            raise self.fail("belief_states", "is given without a belief")
        if len(names) != len(belief):
            raise self.fail("belief_states", f"has {len(names)} names for "
                                             f"{len(belief)} probabilities")
        return names

    def _together(self, names_field: str, names: Any, values_field: str, values: Any) -> None:
        """Two parallel arrays are given together or not at all."""
        if names is None or values is None:
            given, missing = ((names_field, values_field) if values is None
                              else (values_field, names_field))
            raise self.fail(given, f"is given without {missing}")

    def named_numbers(self, names_field: str, names: Any, values_field: str,
                      values: Any) -> Tuple[Tuple[str, ...], Tuple[float, ...]]:
        """Two parallel arrays, given together: distinct names and one finite number each
        (e.g. a decision's ``action_names`` and ``action_values``)."""
        self._together(names_field, names, values_field, values)
        checked = self.names(names_field, names)
        if not isinstance(values, (list, tuple)):
            raise self.fail(values_field, f"must be an array of numbers, {self._got(values)}")
        if len(values) != len(checked):
            raise self.fail(values_field, f"has {len(values)} numbers for {len(checked)} "
                                          f"{names_field}")
        return checked, tuple(self.number(f"{values_field}[{i}]", v)
                              for i, v in enumerate(values))

    def named_belief(self, names_field: str, names: Any, belief_field: str,
                     belief: Any) -> Tuple[Tuple[str, ...], Tuple[float, ...]]:
        """Two parallel arrays, given together: distinct names and a belief over them (e.g.
        ``type_names`` and ``type_belief``, a belief over the human types)."""
        self._together(names_field, names, belief_field, belief)
        probabilities = self.belief_list(belief_field, belief)
        checked = self.names(names_field, names)
        if len(checked) != len(probabilities):
            raise self.fail(names_field, f"has {len(checked)} names for {len(probabilities)} "
                                         "probabilities")
        return checked, probabilities


def check_extra(check: Checker, extra: Mapping[str, Any]) -> None:
    """Fields this version does not know are sent on as they came, so each must be one that
    can be sent: names are names, and every number in them is finite (``1e999`` reads as
    infinity)."""
    stack: List[Tuple[str, Any]] = []
    for key, value in extra.items():
        check.text("extra field name", key)
        stack.append((key, value))
    while stack:
        name, value = stack.pop()
        if isinstance(value, float) and not math.isfinite(value):
            raise check.fail(name, f"must be finite, got {value}")
        if isinstance(value, dict):
            stack.extend((f"{name}.{k}", v) for k, v in value.items())
        elif isinstance(value, (list, tuple)):
            stack.extend((f"{name}[{i}]", v) for i, v in enumerate(value))
