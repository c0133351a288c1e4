"""The study's documents against the code: the committed summaries have the tables and columns
today's summary code writes, and the studies' speed is written once, in one place, measured.

Before: docs/study/summary.md was written by an older summary (no "own success" columns), and
docs/experiments.md (about 100 episodes/min, an hour and a half) and the README (619/min,
14.6 minutes) gave two speeds for the same ``make experiment``."""
import re
from pathlib import Path

import pytest

from ros_hrc.experiment.statistics import markdown

ROOT = Path(__file__).resolve().parents[3]
STUDY = ROOT / "docs" / "study"
EXPERIMENTS = ROOT / "docs" / "experiments.md"
README = ROOT / "README.md"
SPEED_SECTION = "### How long a study takes"
#: A study's speed, as the run prints it (``617.5 episodes/min``).
SPEED = re.compile(r"\d[\d,.]*\s+episodes/min")


def tables(text: str) -> dict:
    """Each ``## section``'s table header (its column names), in the order written."""
    found, section = {}, None
    lines = text.splitlines()
    for line, following in zip(lines, lines[1:] + [""]):
        if line.startswith("## "):
            section = line[3:].strip()
        elif line.startswith("|") and following.startswith("|--") and section is not None:
            found.setdefault(section, [cell.strip() for cell in line.strip("|").split("|")])
    return found


@pytest.mark.parametrize("name", ["summary.md", "fabric_summary.md"])
def test_a_committed_study_summary_has_the_tables_and_columns_the_summary_code_writes(name):
    written = tables(markdown([]))       # today's code, whatever the rows: its headers
    assert written, "the summary code writes no table"
    committed = tables((STUDY / name).read_text(encoding="utf-8"))
    for section, columns in written.items():
        assert section in committed, f"{name}: no section '## {section}' (regenerate it)"
        assert committed[section] == columns, (
            f"{name}, '## {section}': columns {committed[section]}, the code writes {columns}: "
            "regenerate the study's summary with today's code (make experiment)")


def section(text: str, heading: str) -> str:
    """The text of the section under ``heading`` (up to the next heading of its level or
    higher)."""
    start = text.index(heading)
    level = heading.split()[0]
    rest = text[start + len(heading):]
    ends = [m.start() for m in re.finditer(rf"^#{{1,{len(level)}}} ", rest, re.MULTILINE)]
    return rest[:ends[0]] if ends else rest


def test_the_studies_speed_is_written_once_in_one_place_with_the_command_that_measures_it():
    experiments = EXPERIMENTS.read_text(encoding="utf-8")
    readme = README.read_text(encoding="utf-8")
    assert SPEED.findall(readme) == [], "the README gives a speed: link to docs/experiments.md"
    assert "docs/experiments.md#how-long-a-study-takes" in readme
    speeds = section(experiments, SPEED_SECTION)
    outside = experiments.replace(speeds, "")
    assert SPEED.findall(outside) == [], "a speed outside docs/experiments.md's one place"
    # Its tables: the episode studies', then the sequence studies' (issue #30); each row
    # a run's measured figure (per minute, and times real time).
    blocks = re.findall(r"(?:^\|.*\n)+", speeds, re.MULTILINE)
    tables_rows = [block.splitlines()[2:] for block in blocks]
    assert len(tables_rows) == 2, "the episode studies' table and the sequence studies'"
    commands = [row.split("|")[2].strip() for row in tables_rows[0]]
    assert commands == ["`make experiment`", '`make experiment ARGS="--task fabric"`']
    for row in tables_rows[0] + tables_rows[1]:
        assert re.search(r"\|\s*\d+\s*\|\s*×\d+\s*\|$", row), f"no measured figure: {row}"
