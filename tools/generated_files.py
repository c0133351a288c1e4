"""What the repository's generators share (tools/make_settings_files.py, tools/room_imports.py):
a block of a committed file written anew between two marker lines, and writing the files that
differ, or, with ``--check``, naming them and exiting 1 (a unit test runs each check)."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Callable, List, Mapping


class MarkersMissing(ValueError):
    """A file lacks the marker lines of its written block (or has them out of order)."""


def between_markers(text: str, begin: str, end: str, body: List[str], where: Path) -> str:
    """``text`` with the lines between the lines ``begin`` and ``end`` (surrounding white space
    aside; the marker lines themselves kept) replaced by ``body``."""
    lines = text.split("\n")
    stripped = [line.strip() for line in lines]
    try:
        first = stripped.index(begin)
        last = stripped.index(end, first)
    except ValueError:
        raise MarkersMissing(f"{where}: no lines {begin!r} ... {end!r} to write "
                             "between") from None
    return "\n".join(lines[:first + 1] + body + lines[last:])


def write_or_check(files: Mapping[Path, str], check: bool, program: str,
                   stale_line: Callable[[Path], str]) -> int:
    """Write each of ``files`` (path -> text) whose text differs, saying so; with ``check``
    write nothing and name each on stderr (``stale_line``). The exit status: 1 when a checked
    file differs, else 0."""
    stale = [path for path, text in files.items()
             if not path.exists() or path.read_text(encoding="utf-8") != text]
    if check:
        for path in stale:
            print(f"{program}: {stale_line(path)}", file=sys.stderr)
        return 1 if stale else 0
    for path in stale:
        path.write_text(files[path], encoding="utf-8")
        print(f"{program}: wrote {path}")
    return 0
