"""tools/learning_study.py: the learning study's paired comparisons, read from two runs'
tasks.csv, are the tests scipy gives on the tasks both robots played, and a small p-value is
printed as a figure a claim can quote, not as a bound."""
import csv
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from ros_hrc.experiment.sequence_rows import TaskRow

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def learning_study():
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import learning_study
    finally:
        sys.path.remove(str(ROOT / "tools"))
    return learning_study


def write_run(folder: Path, selector: str, outcomes):
    """A run's tasks.csv: 30-task sequences, ``outcomes`` their (success, utility) per task."""
    folder.mkdir()
    with open(folder / "tasks.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=TaskRow.COLUMNS)
        w.writeheader()
        for i, (success, utility) in enumerate(outcomes):
            episode, task = divmod(i, 30)
            w.writerow(TaskRow(
                schedule="tired", selector=selector, seed=2, episode=episode,
                task_index=task + 1, human_model="tired", true_type="tired", policy="p",
                success=int(success), utility=utility,
                outcome="success" if success else "fail",
                who_succeeded="human" if success else "", belief_argmax="",
                estimation_correct=0, warnings=0, preemptions=0, steps=5, duration=9.0,
                total_disc_reward=0.0,
                end_reason="success" if success else "object_left_belt",
                task_episode=i).as_dict())


def test_two_runs_are_paired_by_stream_and_tested_as_scipy_tests_them(learning_study, tmp_path):
    rng = np.random.default_rng(3)
    theirs = [(True, float(u)) for u in rng.uniform(0.6, 0.9, 60)]
    # the learner: better on most tasks, failing four that the baseline succeeded on
    mine = [(i % 15 != 0, u + (0.05 if i % 15 else -1.2)) for i, (_, u) in enumerate(theirs)]
    write_run(tmp_path / "baseline", "fixed:reactive@9", theirs)
    write_run(tmp_path / "learner", "pomdp_learning", mine)
    rows = learning_study.load([str(tmp_path / "learner"), str(tmp_path / "baseline")])
    got = learning_study.compare([r for r in rows if r.selector == "pomdp_learning"],
                                 [r for r in rows if r.selector == "fixed:reactive@9"])
    assert got["pairs"] == 60
    assert got["utility_diff"] == pytest.approx(np.mean([m[1] - t[1]
                                                         for m, t in zip(mine, theirs)]))
    # McNemar's exact test: 4 discordant pairs, all one way
    assert got["success_p"] == pytest.approx(stats.binomtest(0, 4, 0.5).pvalue)
    assert got["utility_p"] == pytest.approx(
        stats.wilcoxon([t[1] for t in theirs], [m[1] for m in mine]).pvalue)


def test_a_small_p_value_is_printed_as_its_figure(learning_study):
    assert learning_study.fmt_p(1.2e-16) == "1e-16"
    assert learning_study.fmt_p(0.0024) == "0.002"
    assert learning_study.fmt_p(float("nan")) == "-"
