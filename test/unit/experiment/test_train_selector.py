"""hrc_train_selector without a stack: which recorded tasks train the model, the model's
arithmetic through the selector model's own builder, and the refusals before any stack."""
import numpy as np
import pytest

from ros_hrc.agents.selector_model import from_tasks
from ros_hrc.experiment.sequence_rows import SequenceStore, TaskRow, sequence_row, task_episode
from ros_hrc.experiment.train_selector import (DEFAULT_SEEDS, build_parser, study_words,
                                               training_tasks)
from ros_hrc.experiment import train_selector
from ros_hrc.experiment.cli import DEFAULT_SEEDS as STUDY_SEEDS
from in_process import run_main


def task(human, policy, index, utility, signature, seed=4, selector=None, episode=0):
    success = int(utility > 0)
    return TaskRow(
        schedule=human, selector=selector or f"fixed:{policy}", seed=seed, episode=episode,
        task_index=index, human_model=human, true_type=human, policy=policy, success=success,
        utility=utility, outcome="success" if success else "fail",
        who_succeeded="robot" if success else "", belief_argmax="", estimation_correct=0,
        warnings=0, preemptions=0, steps=len(signature), duration=10.0, total_disc_reward=0.0,
        end_reason="success" if success else "object_left_belt",
        task_episode=task_episode(episode, index, 3), signature=" ".join(map(str, signature)))


def test_the_trainers_seeds_are_not_the_studys():
    assert set(DEFAULT_SEEDS.split(",")).isdisjoint(STUDY_SEEDS.split(","))


def test_the_model_is_the_mean_std_and_signature_counts_of_each_pairs_tasks(tmp_path):
    store = SequenceStore(tmp_path)
    played = {("a", "base"): [(0.9, [1, 1]), (0.5, [1, 3]), (0.1, [3])],
              ("a", "policy1"): [(-0.5, [2]), (-0.3, [2, 2]), (0.2, [5])],
              ("b", "base"): [(0.4, [7]), (0.6, [7]), (0.8, [7, 1])],
              ("b", "policy1"): [(0.0, [9]), (0.3, [9]), (0.6, [9])]}
    for (human, policy), tasks in played.items():
        rows = [task(human, policy, i, u, s) for i, (u, s) in enumerate(tasks, start=1)]
        store.add(sequence_row(rows, 1.0), rows)
    # Not training data: another selector's tasks, another seed's, a task past K.
    noise = [task("a", "base", 1, -1.0, [0], selector="bpr", episode=1),
             task("a", "base", 1, -1.0, [0], seed=2, episode=0)]
    store.add(sequence_row(noise[:1], 1.0), noise[:1])
    store.add(sequence_row(noise[1:], 1.0), noise[1:])
    chosen = training_tasks(SequenceStore(tmp_path).tasks(), ["a", "b"], ["base", "policy1"],
                            [4], tasks_per_pair=3)
    assert len(chosen) == 12 and all(t.utility != -1.0 for t in chosen)
    model = from_tasks(chosen, task="fabric", policies=["base", "policy1"], types=["a", "b"],
                       header={"how": "a test", "from": "hand-made tasks", "seeds": [4],
                               "command": "pytest", "date": "2026-11-27"})
    assert model.mean.ravel().tolist() == pytest.approx([0.5, -0.2, 0.6, 0.3])
    assert model.std[0, 0] == pytest.approx(np.std([0.9, 0.5, 0.1], ddof=1))
    assert model.tasks_per_pair.tolist() == [[3, 3], [3, 3]]
    # Type a with base showed code 1 three times and code 3 twice in its 5 steps.
    counts = model.signature[0, 0]
    assert counts[1] > counts[3] > counts[0]
    # Left out: a model of type b alone from the same runs.
    only_b = training_tasks(SequenceStore(tmp_path).tasks(), ["b"], ["base", "policy1"], [4], 3)
    assert {t.human_type for t in only_b} == {"b"} and len(only_b) == 6


def test_the_training_runs_are_a_sequence_study_of_fixed_policies_per_type():
    args = build_parser().parse_args(["--task", "fabric", "--tasks-per-pair", "7",
                                      "--human-models", "a,b"])
    args.runs = "/tmp/runs"
    words = study_words(args)
    assert words[words.index("--sequence") + 1] == "7"
    assert words[words.index("--selectors") + 1] == "fixed"
    assert words[words.index("--schedule") + 1] == "per-type"
    assert words[words.index("--episodes") + 1] == "1"
    assert words[words.index("--seeds") + 1] == DEFAULT_SEEDS


@pytest.mark.parametrize("args, line", [
    (["--tasks-per-pair", "0"], "hrc_train_selector: argument --tasks-per-pair: must be an "
                                "integer >= 1, got '0'"),
    (["--task", "fabric", "--leave-out", "nobody"],
     "hrc_train_selector: --leave-out: 'nobody' is not one of the types"),
])
def test_the_trainer_refuses_in_one_line_before_any_stack(tmp_path, monkeypatch, args, line):
    monkeypatch.chdir(tmp_path)
    status, _, err = run_main(train_selector.main, [*args, "--runs", str(tmp_path / "runs")])
    assert status == 2
    assert err.startswith(line), err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "runs").exists()


def test_the_seeds_selector_is_trained_on_the_zoos_fit_set_never_the_held_out_humans():
    from ros_hrc import tasks
    from ros_hrc.experiment.grid import task_humans, training_humans
    from ros_hrc.experiment.zoo import ZOO_FIT, ZOO_HELD_OUT
    assert training_humans(tasks.get("seed")) == list(ZOO_FIT)
    assert not set(training_humans(tasks.get("seed"))) & set(ZOO_HELD_OUT)
    # fabric's study is on its ten types: they are what the selector knows.
    assert training_humans(tasks.get("fabric")) == task_humans(tasks.get("fabric"))
