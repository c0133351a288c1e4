"""A caption's lines wrapped to a width in characters, for PyBullet's window and RViz's text.

One way to wrap, for both places a caption is shown: at word boundaries, a word longer than
the width broken, the words and their order kept. A continued line is indented two spaces
deeper than the line it continues, so a wrapped line still reads as one.
"""
from __future__ import annotations

import textwrap
from typing import List, Sequence

#: How much deeper a continued line is indented than the line it continues.
CONTINUATION_INDENT = "  "


def wrap_lines(lines: Sequence[str], columns: int) -> List[str]:
    """``lines`` wrapped so that no line is longer than ``columns`` characters.

    A line's own indent (``"  -> cannot grasp ..."``) is kept on its first piece; the pieces
    after it are indented :data:`CONTINUATION_INDENT` deeper. A line holding a newline is
    two lines (PyBullet draws no newline); an empty line stays one empty line; tabs are
    spaces. ``columns`` must leave room for some text after the indents (at least 8).
    """
    if columns < 8:
        raise ValueError(f"wrap_lines: columns must be at least 8, got {columns}")
    out: List[str] = []
    for line in (piece for line in lines for piece in str(line).split("\n")):
        text = line.rstrip()
        indent = text[:len(text) - len(text.lstrip(" "))]
        deeper = (indent + CONTINUATION_INDENT)[:columns // 2]   # always room for text
        out.extend(textwrap.wrap(text, width=columns, subsequent_indent=deeper,
                                 break_long_words=True, break_on_hyphens=False) or [""])
    return out
