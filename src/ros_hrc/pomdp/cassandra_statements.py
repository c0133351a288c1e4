"""Cassandra ``.pomdp`` text as statements (:mod:`ros_hrc.pomdp.cassandra_reader` reads them).

A statement is a keyword and a colon (``start include:`` and ``start exclude:`` too), the
header fields of ``T``, ``O`` and ``R`` separated by colons, then its data: every token up to
the next statement. ``#`` starts a comment; data may run across lines, and each token keeps
its line for the messages.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, List, Tuple

#: The words that begin a statement (followed by ':').
KEYWORDS = frozenset({"discount", "values", "states", "actions", "observations", "start",
                      "T", "O", "R"})


@dataclass
class Statement:
    """One statement: its keyword, line, header fields and data tokens with their lines."""

    keyword: str
    line: int
    fields: List[str] = field(default_factory=list)   # T/O/R: action, states, observation
    data: List[str] = field(default_factory=list)
    data_lines: List[int] = field(default_factory=list)
    mode: str = ""                                     # start: "", "include" or "exclude"

    @property
    def header(self) -> str:
        """The statement as the messages name it (``T: a : s``, ``start include:``)."""
        if self.keyword in ("T", "O", "R"):
            return f"{self.keyword}: " + " : ".join(self.fields)
        return f"start {self.mode}:" if self.mode else f"{self.keyword}:"


def tokenise(text: str) -> Tuple[List[str], List[int]]:
    """The text's tokens (':' one of them, comments dropped) and the line of each."""
    tokens: List[str] = []
    lines: List[int] = []
    for number, line in enumerate(text.splitlines(), 1):
        if "#" in line:
            line = line.split("#", 1)[0]
        words = line.replace(":", " : ").split()
        if words:
            tokens.extend(words)
            lines.extend([number] * len(words))
    return tokens, lines


def parse_statements(tokens: List[str], lines: List[int],
                     fail: Callable[[int, str], None]) -> List[Statement]:
    """The tokens cut into statements; ``fail(line, message)`` raises at the first token that
    starts none, a header missing a field or a stray ':'."""
    n = len(tokens)
    # Where a statement may begin: a keyword followed by ':' (or 'start include|exclude').
    # A header field that happens to look like one is skipped below, as fields are read in order.
    starts = [j for j in range(n - 1) if tokens[j] in KEYWORDS and
              (tokens[j + 1] == ":" or
               (tokens[j] == "start" and tokens[j + 1] in ("include", "exclude")))]
    starts.append(n)
    out: List[Statement] = []
    i = 0
    k = 0                                   # index into starts
    while i < n:
        if starts[k] != i:
            fail(lines[i], f"expected a statement (discount, values, states, actions, "
                           f"observations, start, T, O or R), found {tokens[i]!r}")
        st = Statement(tokens[i], lines[i])
        if st.keyword == "start" and tokens[i + 1] in ("include", "exclude"):
            st.mode = tokens[i + 1]
            i += 2
            if i >= n or tokens[i] != ":":
                fail(st.line, f"expected ':' after 'start {st.mode}'")
            i += 1
        else:
            i += 2
        if st.keyword in ("T", "O", "R"):
            # Header fields are read one by one, so a name that is also a keyword still works.
            most = 4 if st.keyword == "R" else 3
            while True:
                if i >= n or tokens[i] == ":":
                    fail(st.line, f"{st.header}: a field is missing")
                st.fields.append(tokens[i])
                i += 1
                if len(st.fields) == most or i >= n or tokens[i] != ":":
                    break
                i += 1
        while starts[k] < i:
            k += 1
        j = starts[k]
        data = tokens[i:j]
        if ":" in data:
            fail(lines[i + data.index(":")], f"unexpected ':' in '{st.header}' (too many fields?)")
        st.data, st.data_lines = data, lines[i:j]
        out.append(st)
        i = j
    return out
