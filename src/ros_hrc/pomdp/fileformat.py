"""What the two model-file formats (Cassandra ``.pomdp``, POMDPX) share: numbers, names, checks.

Only the format modules (the readers and writers of ``cassandra`` and ``pomdpx``, and ``io``)
import this; solvers never do.
"""
from __future__ import annotations

import math
import os
import re
import stat
from pathlib import Path
from typing import Dict, Iterator, List, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp

from ros_hrc.errors import ModelError, ModelFormatError
from ros_hrc.pomdp import memory
from ros_hrc.pomdp.model import PROBABILITY_TOLERANCE, Model

__all__ = ["PROBABILITY_TOLERANCE", "FULL_REWARD_STATES", "MATRIX_LIMIT", "format_number",
           "name_lookup", "resolve_token", "check_writable_names", "check_writable_model_names",
           "CASSANDRA_NAME", "CASSANDRA_NAME_RULE", "POMDPX_NAME", "POMDPX_NAME_RULE",
           "default_names", "joint_names", "is_identity", "read_file", "decode_text", "strip_bom",
           "check_set_size", "first_non_number", "discount_problem", "model_name",
           "validated", "written_as_matrix", "stored_entries"]

#: A byte-order mark some editors (Notepad) put at the start of UTF-8 text; it is not content.
BOM = "\ufeff"

#: Up to this many states R(s, a, s') is kept wherever the file gives it (a human typing an
#: unlikely next state still gets the file's reward). Above it, R is kept only where
#: T(s'|s,a) > 0 -- elsewhere it can never be earned -- so a reward that depends on s alone
#: does not become a dense S x S table (RockSample_7_8: 12,800 states).
FULL_REWARD_STATES = 2000

#: What ``loads`` calls text that came from no file, in error messages.
STRING_SOURCE = "<string>"

#: Tables up to this many rows and columns are written as matrices (readable); larger ones
#: entry by entry.
MATRIX_LIMIT = 32


def format_number(x: float) -> str:
    """The shortest text that reads back as exactly ``x`` (integers without a decimal point).

    Both writers use it, so a model written and read again has bit-identical tables.
    """
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write the non-finite number {x}")
    if x == int(x) and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def first_non_number(words: Sequence[str]) -> Optional[int]:
    """The index of the first word ``float`` does not read, for the message naming it once
    numpy has refused a table of them; None when it reads them all."""
    for i, word in enumerate(words):
        try:
            float(word)
        except ValueError:
            return i
    return None


def discount_problem(discount: float) -> Optional[str]:
    """Why a file's discount is refused, or None when it is in [0, 1)."""
    if not 0.0 <= discount < 1.0:
        return f"discount {format_number(discount)} is outside [0, 1)"
    return None


def name_lookup(names: Sequence[str]) -> Dict[str, int]:
    """Name -> index for one list of states, actions, observations or variable values."""
    return {name: i for i, name in enumerate(names)}


#: Digits a count or an index in a model file may have: no table has 10**18 entries, and
#: Python refuses to convert a number of more than 4300 digits (a traceback).
MAX_DIGITS = 18


def is_number_text(text: str) -> bool:
    """Whether ``text`` is a count or an index this reader converts: decimal digits, at most
    :data:`MAX_DIGITS` of them."""
    return text.isdecimal() and len(text) <= MAX_DIGITS


def shown_token(text: str, most: int = 40) -> str:
    """``text`` for a one-line message: a long one cut, with its length."""
    return text if len(text) <= most else f"{text[:most]}... ({len(text)} characters)"


def resolve_token(token: str, lookup: Dict[str, int], size: int) -> Optional[int]:
    """A name or a 0-based index -> index; None when it is neither.

    Names win over indices, so a model whose names are numbers (``states: 1 0``) still reads
    as written.
    """
    index = lookup.get(token)
    if index is not None:
        return index
    if is_number_text(token):
        index = int(token)
        if index < size:
            return index
    return None


#: A name in Cassandra's ``.pomdp`` grammar (its lexer's STRING): a letter, then letters,
#: digits, ``_`` or ``-``. SARSOP's ``pomdpsol`` refuses any other character ("Illegal
#: character @ in input"), though this package's reader is more lenient.
CASSANDRA_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]*")
CASSANDRA_NAME_RULE = "a letter, then letters, digits, '_' or '-'"

#: A value's name in POMDPX: a ``<ValueEnum>`` lists names separated by white space, and an
#: ``<Instance>`` reserves ``*`` and ``-`` alone as wildcards; ``<``, ``>`` and ``&`` are kept
#: out too, so the names read the same in every XML reader (SARSOP's, DESPOT's) unescaped.
POMDPX_NAME = re.compile(r"(?![*-]\Z)[^\s<>&]+")
POMDPX_NAME_RULE = "no white space, '<', '>' or '&', and not '*' or '-' alone"


def check_writable_names(kind: str, names: Sequence[str], rule: "re.Pattern[str]",
                         rule_text: str, source: str) -> None:
    """Refuse names a writer cannot put in a file of its format (``rule``, described by
    ``rule_text``) and read back unchanged."""
    seen = set()
    for name in names:
        if not rule.fullmatch(name):
            raise ModelFormatError(source, None,
                                   f"the {kind} name {name!r} cannot be written in this format "
                                   f"(a name is {rule_text})")
        if name in seen:
            raise ModelFormatError(source, None, f"the {kind} name {name!r} appears twice")
        seen.add(name)


def check_writable_model_names(model: Model, rule: "re.Pattern[str]", rule_text: str) -> None:
    """Refuse a model whose state, action or observation names a writer cannot put in a file
    of its format (names outside ``rule``) and read back unchanged."""
    source = model.source or model.name or "<model>"
    for kind, names in (("state", model.states), ("action", model.actions),
                        ("observation", model.observations)):
        check_writable_names(kind, names, rule, rule_text, source)


def default_names(prefix: str, count: int) -> List[str]:
    """Names for a set given only by its size: s0 s1 ..., a0 ..., o0 ... (as POMDPX NumValues)."""
    return [f"{prefix}{i}" for i in range(count)]


def joint_names(value_lists: Sequence[Sequence[str]], separator: str = "_") -> List[str]:
    """Names of a product space, first list most significant: ``[[a, b], [x, y]]`` ->
    ``a_x a_y b_x b_y``. A single list keeps its own names."""
    if len(value_lists) == 1:
        return list(value_lists[0])
    names = [""]
    for values in value_lists:
        names = [f"{prefix}{separator}{v}" if prefix else str(v)
                 for prefix in names for v in values]
    return names


def is_identity(matrix) -> bool:
    """True when a square sparse matrix is exactly the identity."""
    n, m = matrix.shape
    if n != m:
        return False
    coo = matrix.tocoo()
    keep = coo.data != 0
    rows, cols, data = coo.row[keep], coo.col[keep], coo.data[keep]
    return rows.size == n and bool(np.all(rows == cols)) and bool(np.all(data == 1.0)) \
        and np.unique(rows).size == n


def read_file(path: str, memory_limit: Optional[int] = None) -> bytes:
    """A model file's bytes; MemoryLimitError, before reading, when parsing a file that size
    would need more than ``memory_limit`` bytes. A device, a FIFO or a directory is refused
    before anything is read (a FIFO nobody writes would wait for ever)."""
    try:
        # O_NONBLOCK: opening a FIFO without a writer returns at once instead of waiting.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            os.close(fd)
            kind = "a directory" if stat.S_ISDIR(info.st_mode) else \
                "a character device" if stat.S_ISCHR(info.st_mode) else \
                "a FIFO" if stat.S_ISFIFO(info.st_mode) else "a special file"
            raise ModelFormatError(path, None, f"is {kind}, not a regular file: give a model "
                                               "file")
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb") as fh:
            if memory_limit is None:
                return fh.read()
            most = memory_limit // memory.PARSE_BYTES_PER_FILE_BYTE
            memory.require(info.st_size * memory.PARSE_BYTES_PER_FILE_BYTE, memory_limit,
                           path, f"reading this {info.st_size}-byte file")
            data = fh.read(most + 1)
            if len(data) > most:
                raise memory.MemoryLimitError(path, "reading this stream (not a regular file)",
                                              len(data) * memory.PARSE_BYTES_PER_FILE_BYTE,
                                              memory_limit)
            return data
    except OSError as exc:
        raise ModelFormatError(path, None, f"cannot read the file: {exc.strerror or exc}") from None


def strip_bom(text: str) -> str:
    """``text`` without a leading byte-order mark."""
    return text[1:] if text.startswith(BOM) else text


def decode_text(data: bytes, source: str) -> str:
    """A text model file's bytes as text: UTF-8 (a leading byte-order mark dropped; bytes that
    are not UTF-8 become U+FFFD, which the parser then names). UTF-16 and UTF-32 are refused
    in one line rather than read as garbage."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise ModelFormatError(source, "1", "the file is UTF-16 or UTF-32 text (it starts with "
                                            "that byte-order mark); save it as UTF-8")
    return strip_bom(data.decode("utf-8", errors="replace"))


def check_set_size(kind: str, count: int, memory_limit: Optional[int], source: str,
                   where: Optional[str]) -> None:
    """Refuse a count of states, actions or observations whose names alone would not fit in
    ``memory_limit`` (``states: 99999999999`` must not allocate before it is refused)."""
    if memory_limit is not None and count * memory.BYTES_PER_NAME > memory_limit:
        raise memory.MemoryLimitError(f"{source}:{where}" if where else source,
                                      f"{count} {kind}", count * memory.BYTES_PER_NAME,
                                      memory_limit)


def model_name(source: str) -> str:
    """The name of a model read from ``source``: the file's stem ("model" for text)."""
    return Path(source).stem if source != STRING_SOURCE else "model"


def validated(model: Model, source: str) -> Model:
    """``model`` once it passes ``Model.validate``; its complaint as a ModelFormatError naming
    ``source`` otherwise."""
    try:
        model.validate()
    except ModelError as exc:
        raise ModelFormatError(source, None, str(exc)) from None
    return model


def written_as_matrix(matrix) -> bool:
    """Whether a writer puts this table down as a matrix (at most MATRIX_LIMIT rows and
    columns) rather than entry by entry."""
    n, m = matrix.shape
    return n <= MATRIX_LIMIT and m <= MATRIX_LIMIT


def stored_entries(matrix) -> Iterator[Tuple[int, int, float]]:
    """(row, column, value) of every entry a sparse table stores, explicit zeros included, row
    by row and by column within a row."""
    m = sp.csr_matrix(matrix)
    m.sort_indices()
    for r in range(m.shape[0]):
        for k in range(m.indptr[r], m.indptr[r + 1]):
            yield r, int(m.indices[k]), m.data[k]
