"""Warm stacks (issue #39): a worker keeps its stack up and hands it cell after cell. A cell
played on a stack that other cells played on before it (other humans, other robots, other
seeds) writes the rows the same cell writes on a stack of its own (``--fresh-stacks``), for
episode cells and for sequence cells. Every field is compared but those that measure the
wall clock (``wall_seconds``, ``mean_decision_ms``).

These tests start real stacks (roscore, roslaunch, the world, both solver processes).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

from ros_hrc.experiment.cli import main as hrc_experiment
from ros_hrc.experiment.sequence_rows import SequenceStore
from ros_hrc.experiment.store import ResultsStore

#: What the wall clock sets, and so differs between any two runs.
WALL_FIELDS = ("wall_seconds", "mean_decision_ms")


def without_wall(row) -> dict:
    return {k: v for k, v in dataclasses.asdict(row).items() if k not in WALL_FIELDS}


def rows_of(rows, **wanted) -> list:
    """The rows whose fields have the values ``wanted``, wall-clock fields left out, in order."""
    picked = [without_wall(r) for r in rows
              if all(getattr(r, k) == v for k, v in wanted.items())]
    return sorted(picked, key=lambda r: sorted(r.items()))


def warm_stack_lines(log_dir: Path, cell: str) -> list:
    return [line for line in (log_dir / f"{cell}.worker.log").read_text().splitlines()
            if "on the warm stack of" in line]


EPISODE_GRID = ["--seeds", "3,4", "--episodes", "2", "--step-limit", "10", "--no-plots"]


def test_an_episode_cell_after_others_on_a_warm_stack_writes_the_rows_of_a_fresh_stack(
        tmp_path):
    warm, fresh = tmp_path / "warm", tmp_path / "fresh"
    # One worker: every cell on one stack, in the queue's order: the four human-alone cells,
    # then the eight robot cells; distracted/pomdp/seed 4 is the last of twelve.
    assert hrc_experiment(["--human-models", "expert,distracted", "--policies",
                           "reactive,pomdp", "--jobs", "1", "--out", str(warm),
                           *EPISODE_GRID]) == 0
    assert hrc_experiment(["--human-models", "distracted", "--policies", "pomdp",
                           "--seeds", "4", "--jobs", "1", "--fresh-stacks",
                           "--out", str(fresh), *EPISODE_GRID[2:]]) == 0
    lines = warm_stack_lines(warm / "logs", "distracted-pomdp-seed4")
    assert lines and "(cell 12;" in lines[-1], lines
    assert not (fresh / "logs" / "distracted-pomdp-seed4.worker.log").read_text().count(
        "on the warm stack of")
    cell = dict(human_model="distracted", robot_policy="pomdp", seed=4)
    for rows in ("episodes", "steps"):
        played_warm = rows_of(getattr(ResultsStore(warm), rows)(), **cell)
        played_fresh = rows_of(getattr(ResultsStore(fresh), rows)(), **cell)
        assert played_warm and played_warm == played_fresh, rows
    alone = dict(human_model="distracted", robot_policy="no_robot", seed=4)
    assert rows_of(ResultsStore(warm / "alone").episodes(), **alone) == \
        rows_of(ResultsStore(fresh / "alone").episodes(), **alone)


#: Sixteen tasks a cell: enough that a task's duration, measured on a world whose clock ran
#: through the cells before, would show the clock's rounding if it were not taken out
#: (``ros_hrc.tasks.utility.sim_span``; before, 34 of 80 such tasks differed in the last bits).
SEQUENCE_GRID = ["--sequence", "8", "--episodes", "2", "--seeds", "5", "--no-plots"]


def test_a_sequence_cell_after_others_on_a_warm_stack_writes_the_rows_of_a_fresh_stack(
        tmp_path):
    warm, fresh = tmp_path / "warm", tmp_path / "fresh"
    # The cell after another human's with the same selector: whatever the selector or the
    # human's process kept of the cell before would show (the episode test above changes the
    # robot between cells).
    assert hrc_experiment(["--human-models", "tired,expert", "--selectors", "bpr",
                           "--jobs", "1", "--out", str(warm), *SEQUENCE_GRID]) == 0
    assert hrc_experiment(["--human-models", "expert", "--selectors", "bpr", "--jobs", "1",
                           "--fresh-stacks", "--out", str(fresh), *SEQUENCE_GRID]) == 0
    played = [p.name for p in (warm / "logs").glob("*.worker.log")
              if warm_stack_lines(warm / "logs", p.name[:-len(".worker.log")])]
    assert len(played) == 1, played     # two cells, one stack: the second was handed it
    cell = dict(schedule="expert", selector="bpr", seed=5)
    for rows in ("sequences", "tasks"):
        played_warm = rows_of(getattr(SequenceStore(warm), rows)(), **cell)
        played_fresh = rows_of(getattr(SequenceStore(fresh), rows)(), **cell)
        assert played_warm and played_warm == played_fresh, rows


def test_a_refused_cell_fails_alone_and_a_stack_that_dies_is_replaced(tmp_path, capsys):
    """A cell whose settings are refused (a human model that is not there) fails with the
    reason and leaves the warm stack as it was: the next cell plays on it. A warm stack
    that dies mid-run (its roslaunch killed) is replaced: the cell's episodes run again on
    a new stack, and the run says so in one line."""
    import psutil
    import pytest
    from ros_hrc.experiment.pool import CellRefused, StackWorker, Stopper, play_cell
    from ros_hrc.experiment.stack import CellSpec

    logs = tmp_path / "logs"
    log = (tmp_path / "worker.log").open("a")
    worker = StackWorker(Stopper())
    played = []

    def cell(seed: int, **more) -> CellSpec:
        return CellSpec("expert", "reactive", seed, [0, 1], step_limit=10, log_dir=str(logs),
                        **more)
    try:
        worker.play(cell(1), lambda row, steps: played.append(row), log)
        with pytest.raises(CellRefused, match="gone.pomdpx"):
            worker.play(cell(2, human_model_file=str(tmp_path / "gone.pomdpx")),
                        lambda row, steps: played.append(row), log)
        worker.play(cell(3), lambda row, steps: played.append(row), log)
        log.flush()
        assert "expert-reactive-seed3: on the warm stack of expert-reactive-seed1 (cell 2;" in \
            (tmp_path / "worker.log").read_text()
        assert [(r.seed, r.episode) for r in played] == [(1, 0), (1, 1), (3, 0), (3, 1)]

        roslaunch = [p for p in psutil.Process(worker.proc.pid).children(recursive=True)
                     if "roslaunch" in " ".join(p.cmdline())]
        assert roslaunch
        roslaunch[0].kill()
        play_cell(worker, cell(4), lambda row, steps: played.append(row), log, "test")
        assert [(r.seed, r.episode) for r in played][-2:] == [(4, 0), (4, 1)]
        said = [line for line in capsys.readouterr().err.splitlines()
                if "still missing run again on a new stack" in line]
        assert len(said) == 1 and "cell expert-reactive-seed4: " in said[0], said
    finally:
        worker.close()
        log.close()
