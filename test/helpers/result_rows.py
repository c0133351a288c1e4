"""The rows of a study's CSV files, for tests that set two runs side by side
(test_cluster.py, test_grid.py)."""
import csv
from pathlib import Path

#: Columns that measure this machine's speed, not the episode.
TIMED_COLUMNS = frozenset({"mean_decision_ms", "wall_seconds"})


def rows_of(path: Path, drop=frozenset()) -> list:
    """The rows of a CSV file as dicts, without the ``drop`` columns, in the file's order."""
    with open(path, newline="") as f:
        return [{k: v for k, v in row.items() if k not in drop} for row in csv.DictReader(f)]
