"""hrc_perturb_humans: humans of our own around the task's types (the study's part (c))."""
from pathlib import Path

import numpy as np

from ros_hrc import tasks
from ros_hrc.experiment.grid import task_humans
from ros_hrc.experiment import perturbed_humans
from ros_hrc.experiment.perturbed_humans import perturb_rows
from ros_hrc.models import load_human_model

from in_process import run_main

ROOT = Path(__file__).resolve().parents[3]


def test_a_row_keeps_its_sum_and_its_floors_and_only_the_entries_above_them_move():
    row = np.array([0.01, 0.01, 0.09, 0.01, 0.26, 0.2, 0.21, 0.01, 0.18, 0.01, 0.01, 0.0])
    out = perturb_rows(row[None, :], 20.0, np.random.default_rng(1))[0]
    assert np.isclose(out.sum(), 1.0)
    floors = row == 0.01
    assert np.array_equal(out[floors], row[floors]) and out[-1] == 0.0
    assert (out[~floors & (row > 0)] > 0.01).all()     # never folded away with the floors
    assert not np.allclose(out, row)


def test_a_row_with_one_entry_above_its_floor_is_the_types_own():
    row = np.array([[0.9, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.0]])
    assert np.array_equal(perturb_rows(row, 20.0, np.random.default_rng(1)), row)


def test_a_larger_concentration_stays_closer_to_the_type():
    row = np.array([[0.2, 0.09, 0.1, 0.54, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.0]])
    rng = np.random.default_rng(3)
    near = np.mean([abs(perturb_rows(row, 500.0, rng) - row).sum() for _ in range(200)])
    far = np.mean([abs(perturb_rows(row, 5.0, rng) - row).sum() for _ in range(200)])
    assert near < far / 3


def test_the_command_writes_each_type_under_its_own_name_and_the_task_loads_them(tmp_path,
                                                                                 monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, _, err = run_main(perturbed_humans.main, ["--task", "fabric", "--seed", "5",
                                                      "--out", "humans"])
    assert status == 0, err
    task = tasks.get("fabric")
    for name in task_humans(task):
        written = load_human_model(str(tmp_path / "humans" / f"{name}.pomdpx"), task)
        original = load_human_model(name, task)
        assert written.states == original.states and written.actions == original.actions
        assert any(not np.allclose(a.toarray(), b.toarray())
                   for a, b in zip(written.T, original.T))


def test_a_bad_concentration_or_type_is_one_line_and_nothing_written(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for extra, said in ((["--concentration", "0"], "--concentration: must be > 0"),
                        (["--human-models", "nobody"], "--human-models: ")):
        status, _, err = run_main(perturbed_humans.main,
                                  ["--task", "fabric", "--out", "humans"] + extra)
        assert status == 2 and len(err.splitlines()) == 1, err
        assert said in err
        assert not (tmp_path / "humans").exists()
