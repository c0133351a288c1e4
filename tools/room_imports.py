#!/usr/bin/env python3
"""Writes the table of which room of ros_hrc imports which, from the package's own imports
(grimp, the graph import-linter checks), into docs/architecture.md between its two markers.

    python tools/room_imports.py           rewrite the table in docs/architecture.md
    python tools/room_imports.py --check   exit 1 when the committed table is not today's

A room is a direct child of ros_hrc (a package such as ``pomdp`` or a module such as
``settings``); the floors are read from .importlinter's layers contract, top floor first, so the
table reads as the contract does. test/integration/test_architecture.py runs --check.
"""
import argparse
import configparser
import sys
from pathlib import Path
from typing import Dict, List, Set

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
from generated_files import MarkersMissing, between_markers, write_or_check  # noqa: E402

DOC = ROOT / "docs" / "architecture.md"
BEGIN = "<!-- room imports: begin (tools/room_imports.py writes this table) -->"
END = "<!-- room imports: end -->"


def floors(config: Path = ROOT / ".importlinter") -> List[List[str]]:
    """The floors of the layers contract, top first, each a list of rooms."""
    parser = configparser.ConfigParser()
    parser.read(config)
    layers = parser["importlinter:contract:floors"]["layers"]
    return [[room.strip() for room in line.split("|")] for line in layers.split("\n")
            if line.strip()]


def room_imports(src: Path = ROOT / "src") -> Dict[str, Set[str]]:
    """For each room, the other rooms its modules import (directly)."""
    sys.path.insert(0, str(src))
    import grimp   # the venv's; imported here so --help needs nothing
    graph = grimp.build_graph("ros_hrc")
    out: Dict[str, Set[str]] = {}
    for module in graph.modules:
        parts = module.split(".")
        if len(parts) < 2:
            continue
        room = parts[1]
        for imported in graph.find_modules_directly_imported_by(module):
            other = imported.split(".")
            if len(other) > 1 and other[0] == "ros_hrc" and other[1] != room:
                out.setdefault(room, set()).add(other[1])
    return out


def table() -> str:
    """The markdown table: one row per room, top floor first, and the rooms it imports."""
    imports = room_imports()
    rows = ["| floor | room | imports |", "|---|---|---|"]
    stack = floors()
    for level, rooms in enumerate(stack):
        number = len(stack) - level
        for room in rooms:
            used = sorted(imports.get(room, ()))
            rows.append(f"| {number} | `{room}` | {', '.join(f'`{u}`' for u in used) or '—'} |")
    return "\n".join(rows)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="exit 1 when docs/architecture.md's table is not today's")
    args = parser.parse_args(argv)
    try:
        text = between_markers(DOC.read_text(), BEGIN, END, table().split("\n"), DOC)
    except MarkersMissing as exc:
        print(f"room_imports: {exc}", file=sys.stderr)
        return 2
    return write_or_check({DOC: text}, args.check, "room_imports",
                          lambda path: f"{path}: the room imports table is not today's: run "
                                       "python tools/room_imports.py")

if __name__ == "__main__":
    raise SystemExit(main())
