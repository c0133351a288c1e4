"""POMDPX's XML (:mod:`ros_hrc.pomdp.pomdpx`): parsed safely, with each element's line.

The XML is parsed with :mod:`defusedxml`: a document that declares entities (the "billion
laughs") or refers to external ones is refused, never expanded. Malformed XML is reported at
expat's line, in words where expat only says "invalid token": a comment opened inside another
one, ``--`` inside a comment.
"""
from __future__ import annotations

import re
from typing import Optional, Union

from defusedxml import DefusedXmlException
from defusedxml.ElementTree import DefusedXMLParser, ParseError

from ros_hrc.errors import ModelFormatError

#: What the writer puts in ``<Description>`` for a ``values: cost`` model (rewards are still
#: written as rewards = -cost) and the reader looks for, so the flag survives a round trip.
COST_MARK = "[values: cost]"


class _LineNumberingParser(DefusedXMLParser):
    """defusedxml's parser, recording each element's line (``elem.line``) for messages."""

    def _start(self, *args):
        elem = super()._start(*args)
        elem.line = self.parser.CurrentLineNumber
        return elem


def parse_xml(text: Union[str, bytes], source: str):
    """The document's root element, each element with its line (``elem.line``); unsafe or
    malformed XML raises ModelFormatError at its line."""
    parser = _LineNumberingParser()
    try:
        parser.feed(text)
        return parser.close()
    except DefusedXmlException as exc:
        line = parser.parser.CurrentLineNumber
        raise ModelFormatError(source, str(line), f"unsafe XML refused ({type(exc).__name__}): "
                                                  "entity declarations and external references "
                                                  "are not allowed") from None
    except ParseError as exc:
        position = getattr(exc, "position", None)
        line = position[0] if position else None
        what = re.sub(r": line \d+, column \d+$", "", str(exc))
        hint = _xml_error_hint(text, *position) if position else None
        raise ModelFormatError(source, str(line) if line else None,
                               f"malformed XML: {hint or what}") from None


def _xml_error_hint(text: Union[str, bytes], line: int, column: int) -> Optional[str]:
    """What is wrong at expat's error position, in words, for the mistakes expat only calls an
    "invalid token": a comment opened inside another one (XML comments do not nest; SARSOP's
    reader accepts them) and ``--`` inside a comment. None when it is something else."""
    if isinstance(text, bytes):
        text = text.decode("utf-8", errors="replace")
    lines = text.split("\n")
    if not 1 <= line <= len(lines):
        return None
    offset = sum(len(l) + 1 for l in lines[:line - 1]) + column
    # expat stops right after the "--" it refuses.
    if text[max(0, offset - 2):offset] != "--":
        return None
    opened = text.rfind("<!--", 0, offset - 2)
    if opened < 0 or text.find("-->", opened + 4, offset - 2) >= 0:
        return None                 # not inside a comment
    opened_line = text.count("\n", 0, opened) + 1
    if text[max(0, offset - 4):offset] == "<!--":
        return (f"a comment is opened inside another comment (the one opened on line "
                f"{opened_line}): XML comments do not nest; close the first with '-->' "
                f"before opening another")
    return (f"'--' inside a comment (opened on line {opened_line}): XML does not allow two "
            f"hyphens in a row within a comment")


def local_name(tag: str) -> str:
    """A tag without its namespace."""
    return tag.rsplit("}", 1)[-1]


def children(elem, tag: Optional[str] = None) -> list:
    """``elem``'s child elements (comments left out), only those named ``tag`` if given."""
    return [c for c in elem if isinstance(c.tag, str) and (tag is None or local_name(c.tag) == tag)]
