"""hrc_perturb_humans: humans of our own around the task's types (the study's part (c))."""
import dataclasses
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ros_hrc import tasks
from ros_hrc.experiment.grid import task_humans
from ros_hrc.experiment import perturbed_humans
from ros_hrc.experiment.perturbed_humans import perturb_rows
from ros_hrc.experiment.zoo import ZOO_HELD_OUT
from ros_hrc.models import load_human_model
from ros_hrc.pomdp.pomdpx_writer import save as save_pomdpx

from in_process import run_main

ROOT = Path(__file__).resolve().parents[3]
FABRIC_FLOOR = tasks.get("fabric").model_floor


def test_a_row_keeps_its_sum_and_its_floors_and_only_the_entries_above_them_move():
    row = np.array([0.01, 0.01, 0.09, 0.01, 0.26, 0.2, 0.21, 0.01, 0.18, 0.01, 0.01, 0.0])
    out = perturb_rows(row[None, :], 20.0, np.random.default_rng(1), FABRIC_FLOOR)[0]
    assert np.isclose(out.sum(), 1.0)
    floors = row == 0.01
    assert np.array_equal(out[floors], row[floors]) and out[-1] == 0.0
    assert (out[~floors & (row > 0)] > 0.01).all()     # never folded away with the floors
    assert not np.allclose(out, row)


def test_a_row_with_one_entry_above_its_floor_is_the_types_own():
    row = np.array([[0.9, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.0]])
    assert np.array_equal(perturb_rows(row, 20.0, np.random.default_rng(1), FABRIC_FLOOR), row)


def test_a_larger_concentration_stays_closer_to_the_type():
    row = np.array([[0.2, 0.09, 0.1, 0.54, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01, 0.0]])
    rng = np.random.default_rng(3)
    near = np.mean([abs(perturb_rows(row, 500.0, rng, FABRIC_FLOOR) - row).sum()
                    for _ in range(200)])
    far = np.mean([abs(perturb_rows(row, 5.0, rng, FABRIC_FLOOR) - row).sum()
                   for _ in range(200)])
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


def test_the_floor_is_the_tasks_not_the_rows_smallest_entry():
    # The seed has no floor: a row of two live entries, or three with a tie at the bottom,
    # is drawn whole (issue #40: these rows were left as the type's).
    for row in ([0.0, 0.3, 0.7, 0.0], [0.05, 0.0, 0.05, 0.9]):
        row = np.array([row])
        out = perturb_rows(row, 2.0, np.random.default_rng(4))
        assert (out[row > 0] != row[row > 0]).all() and (out[row == 0] == 0).all()
        assert np.isclose(out.sum(), 1.0)
    # In a task with floors, a row of FABRIC's without any (0.05 and 0.95) is drawn too.
    row = np.array([[0.0, 0.05, 0.95, 0.0]])
    assert not np.array_equal(perturb_rows(row, 2.0, np.random.default_rng(4), FABRIC_FLOOR), row)


def _tables(model):
    return np.array([t.toarray() for t in model.T])


def _perturbed_held_out(tmp_path, concentration):
    """The zoo's seven held-out humans perturbed at ``concentration`` (seed 6), as
    (name, type's tables, perturbed tables); and what the command printed."""
    out = tmp_path / f"c{concentration:g}"
    status, printed, err = run_main(perturbed_humans.main, [
        "--task", "seed", "--concentration", f"{concentration:g}", "--seed", "6",
        "--out", str(out), "--human-models", ",".join(ZOO_HELD_OUT)])
    assert status == 0, err
    humans = [(name, _tables(load_human_model(name, "seed")),
               _tables(load_human_model(str(out / f"{name}.pomdpx"), "seed")))
              for name in ZOO_HELD_OUT]
    return humans, printed


def test_every_held_out_seed_human_moves_and_a_larger_concentration_moves_them_less(tmp_path):
    far, printed = _perturbed_held_out(tmp_path, 2.0)
    near, _ = _perturbed_held_out(tmp_path, 20.0)
    for name, original, perturbed in far:
        change = abs(perturbed - original)
        assert change.max() > 0.05, name
        assert np.allclose(perturbed.sum(axis=2), 1.0), name
        assert (perturbed[original == 0] == 0).all(), name      # impossible stays impossible
        assert (perturbed[original > 0] > 0).all(), name        # possible stays possible
        stochastic = (original > 0).sum(axis=2) >= 2
        assert (change.max(axis=2)[stochastic] > 0).all(), name  # every such row moved
        assert (change.max(axis=2)[~stochastic] == 0).all(), name
        line = next(line for line in printed.splitlines() if f"/{name}.pomdpx:" in line)
        assert f"largest change of a T entry {change.max():.3f}" in line
        assert f"rows moved {stochastic.sum()} of the {stochastic.sum()} that can move" in line

    def mean_change(humans):
        return np.mean([abs(p - o)[o > 0].mean() for _, o, p in humans])
    assert mean_change(near) < mean_change(far)


def test_fabric_keeps_its_floors_so_its_draw_folds_the_same_entries(tmp_path):
    name = "expert_nontired_collaborative"
    status, _, err = run_main(perturbed_humans.main, [
        "--task", "fabric", "--concentration", "2", "--seed", "3", "--human-models", name,
        "--out", str(tmp_path)])
    assert status == 0, err
    original = _tables(load_human_model(name, "fabric"))
    perturbed = _tables(load_human_model(str(tmp_path / f"{name}.pomdpx"), "fabric"))
    floors = original == FABRIC_FLOOR
    assert floors.sum() > 0 and (perturbed[floors] == FABRIC_FLOOR).all()
    drawn = (original > 0) & ~floors
    assert (perturbed[drawn] > FABRIC_FLOOR).all()       # never folded away with the floors
    assert (perturbed[original == 0] == 0).all() and np.allclose(perturbed.sum(axis=2), 1.0)
    assert not np.array_equal(perturbed, original)


def test_a_human_none_of_whose_rows_can_move_is_refused_and_nothing_written(tmp_path):
    expert = load_human_model("expert", "seed")
    still = dataclasses.replace(expert, T=[sp.identity(len(expert.states), format="csr")
                                           for _ in expert.T])
    save_pomdpx(still, tmp_path / "stands_still.pomdpx")
    status, _, err = run_main(perturbed_humans.main, [
        "--task", "seed", "--human-models", f"expert,{tmp_path / 'stands_still.pomdpx'}",
        "--out", str(tmp_path / "humans")])
    assert status == 2 and len(err.splitlines()) == 1, err
    assert "stands_still: none of its rows can move" in err
    assert not (tmp_path / "humans").exists()
