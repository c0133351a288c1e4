"""hrc_experiment --sequence without a stack: the command line's refusals, ``fixed``'s
expansion, the task rows made from /hrc/task_status records, the store's resume by whole
sequences, the episodes a cell's stack plays, and the summary's statistics on hand-made
tables (checked against scipy's own calls)."""
import math
import os
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from ros_hrc.experiment import cli
from ros_hrc.experiment.grid import GridError
from ros_hrc.experiment.sequence_rows import (SequenceStore, TaskRow, sequence_of,
                                              sequence_row, task_episode, task_row)
from ros_hrc.experiment.sequence_statistics import (best_fixed, identification,
                                                    learning_curve, paired_tests,
                                                    summarize_sequences)
from ros_hrc.experiment.sequences import expand_selectors, sequence_launch_args
from ros_hrc.experiment.statistics import mean_ci
from ros_hrc.experiment.stack import CellSpec, launch_settings
from ros_hrc.experiment.store import ResultsWarning
from in_process import run_main

PORTS = {"master": 11311, "pomdp": 7070, "human": 9090}


def run_cli(*args, cwd):
    """hrc_experiment's ``main`` on ``args`` in this process, run from ``cwd``: its exit
    status (``returncode``), ``stdout`` and ``stderr``."""
    here = os.getcwd()
    os.chdir(cwd)
    try:
        status, out, err = run_main(cli.main, args)
    finally:
        os.chdir(here)
    return SimpleNamespace(returncode=status, stdout=out, stderr=err)




@pytest.mark.parametrize("args, line", [
    (["--selectors", "bpr"], "hrc_experiment: --selectors needs --sequence L (a selector "
                             "chooses between the tasks of a sequence)"),
    (["--schedule", "fabric"], "hrc_experiment: --schedule needs --sequence L"),
    (["--sequence", "0"], "hrc_experiment: argument --sequence: must be an integer >= 1, "
                          "got '0'"),
    (["--sequence", "5", "--policies", "pomdp"], "hrc_experiment: --policies is for episodes"),
    (["--sequence", "5", "--reactive-budgets", "1..3"],
     "hrc_experiment: --reactive-budgets is for episodes"),
    (["--sequence", "5", "--selectors", "bpr,,random"],
     "hrc_experiment: argument --selectors: an empty item between commas"),
])
def test_the_command_line_refuses_in_one_line_before_anything_starts(tmp_path, args, line):
    out = tmp_path / "results"
    done = run_cli(*args, "--out", str(out), cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.startswith(line), done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert not out.exists()          # nothing was started, not even the results directory


POLICIES = ("base", "policy1", "policy3", "reactive")


def test_fixed_stands_for_every_library_policy_in_the_library_order():
    assert expand_selectors(["bpr", "fixed", "oracle"], POLICIES) == [
        "bpr", "fixed:base", "fixed:policy1", "fixed:policy3", "fixed:reactive", "oracle"]
    # A policy named twice (fixed and fixed:<policy>) runs once.
    assert expand_selectors(["fixed:policy3", "fixed"], POLICIES) == [
        "fixed:policy3", "fixed:base", "fixed:policy1", "fixed:reactive"]


def test_an_unknown_selector_or_library_policy_is_one_line_naming_the_known():
    with pytest.raises(GridError) as unknown:
        expand_selectors(["bpr", "ucb"], POLICIES)
    assert str(unknown.value) == ("--selectors: unknown selector 'ucb' (known: random, bpr, "
                                  "bpr-pi, bpr-fabric, bandit, oracle, or module:Class); also "
                                  "fixed, fixed:<policy>, pomdp_types, pomdp_ceiling, "
                                  "pomdp_pooled, pomdp_learning, pomdp_learning_mean")
    with pytest.raises(GridError) as near:
        expand_selectors(["bpr_pi"], POLICIES)
    assert "unknown selector 'bpr_pi'; did you mean bpr-pi? (known: " in str(near.value)


def test_the_help_lists_every_selector_the_study_takes(capsys):
    """--help's list of selectors is the one the study checks --selectors against: every
    selector of ours in the registry and the study's own robots, none missing, none that
    would be refused."""
    from ros_hrc import registry
    from ros_hrc.experiment.sequences import STUDY_ROBOTS

    with pytest.raises(SystemExit):
        cli.build_parser().parse_args(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    listed = text.split("selectors, comma-separated, of ", 1)[1]
    ours = listed.split(" (docs/selectors.md), ", 1)[0].split(", ")
    robots = listed.split(" (docs/selectors.md), ", 1)[1].split(" (docs/learning.md", 1)[0]
    names = ours + robots.split(", ")
    assert set(registry.BUILT_IN[registry.SELECTORS]) | set(STUDY_ROBOTS) == set(names)
    assert expand_selectors(names, POLICIES) == names
    with pytest.raises(GridError) as foreign:
        expand_selectors(["fixed:policy2"], POLICIES)
    assert str(foreign.value) == ("--selectors: fixed:policy2: no policy 'policy2' in the "
                                  "library (its policies: base, policy1, policy3, reactive)")


def test_the_type_inferring_robot_is_a_selector_its_stack_runs_as_the_one_fixed_robot():
    """pomdp_types in a sequence study: no library policy; the stack runs selector:=fixed on
    the model of human types, and its tasks' statuses (selector "fixed") are the cell's."""
    assert expand_selectors(["bpr", "pomdp_types"], POLICIES) == ["bpr", "pomdp_types"]
    args = SimpleNamespace(library="auto", sequence=30, selector_model="auto", task="seed")
    words = sequence_launch_args(args, "pomdp_types", "per-type")
    assert "selector:=fixed" in words and "tasks:=30" in words
    row = task_row(status(selector="fixed", policy="robot_types"), "tired", "pomdp_types", 2, 0)
    assert (row.selector, row.policy, row.belief_argmax) == ("pomdp_types", "robot_types",
                                                             "expert_tired")
    with pytest.raises(ValueError, match="the stack ran selector 'bpr'"):
        task_row(status(selector="bpr"), "tired", "pomdp_types", 2, 0)


def status(**fields):
    """A /hrc/task_status message's fields (ros_hrc/TaskStatus), as rospy hands them over:
    the signature (uint8[]) as bytes."""
    values = dict(task_index=2, tasks=5, episode=6, epoch=9, human_model="expert_tired",
                  true_type="expert_tired", selector="bpr", policy="policy3",
                  robot_model="/m/policy3.pomdpx", type_names=["novice", "expert_tired"],
                  type_belief=[0.25, 0.75], estimation_correct=True, outcome="success",
                  who_succeeded="robot", warnings=1, preemptions=0, steps=14, duration=21.5,
                  utility=0.63, total_disc_reward=4.2, end_reason="success",
                  signature=bytes([3, 3, 35, 7]), learnt_name="", learnt_value=0.0,
                  learnt_spread=0.0, against_warning=0)
    values.update(fields)
    return SimpleNamespace(**values)


def test_a_task_row_is_the_task_status_message_with_the_cells_names():
    # The stack names a human given as a file by its stem (test_sequence_coordinator.py).
    row = task_row(status(human_model="expert_tired"), "per-type-label", "bpr", 4, 1)
    assert row.key == ("per-type-label", "bpr", 4, 1)
    assert (row.task_index, row.task_episode, row.policy, row.true_type, row.human_model) == \
        (2, 6, "policy3", "expert_tired", "expert_tired")
    assert (row.success, row.outcome, row.who_succeeded, row.utility) == \
        (1, "success", "robot", 0.63)
    assert row.belief_argmax == "expert_tired" and row.estimation_correct == 1
    assert row.types == ("novice", "expert_tired")
    assert row.belief.tolist() == [0.25, 0.75]
    assert row.signature_codes == (3, 3, 35, 7)
    # Through the CSV and back, unchanged.
    assert TaskRow.from_dict(row.as_dict()) == row


def test_a_task_without_a_type_belief_has_no_argmax_and_a_failure_no_one_who_succeeded():
    row = task_row(status(type_names=[], type_belief=[], estimation_correct=False,
                          selector="fixed:base", policy="base", outcome="timeout",
                          who_succeeded="", end_reason="task_timeout", signature=[1, 2]),
                   "fabric", "fixed:base", 0, 0)
    assert (row.belief_argmax, row.success, row.signature_codes) == ("", 0, (1, 2))


def test_a_status_of_another_selector_than_the_cells_is_refused():
    with pytest.raises(ValueError, match="the stack ran selector 'random', the cell asked "
                                         "for 'bpr'"):
        task_row(status(selector="random"), "x", "bpr", 0, 0)


def test_each_task_of_each_sequence_has_an_episode_number_of_its_own():
    numbers = [task_episode(s, t, 4) for s in range(3) for t in range(1, 5)]
    assert numbers == list(range(12))
    assert all(sequence_of(task_episode(s, t, 4), 4) == (s, t)
               for s in range(3) for t in range(1, 5))
    with pytest.raises(ValueError):
        task_episode(0, 5, 4)


def test_a_sequence_cells_stack_plays_the_tasks_of_its_missing_sequences():
    spec = CellSpec(human_model="fabric", robot_policy="bpr", seed=3, episodes=[0, 2, 3],
                    sequence=5, extra_args=["task:=fabric", "tasks:=5", "selector:=bpr"])
    launched = launch_settings(spec, PORTS)
    # Sequences 0, 2 and 3 of 5 tasks: episodes 0-4 and 10-19.
    assert launched["episodes"] == "0-4,10-19"
    assert (launched["tasks"], launched["selector"], launched["seed"]) == ("5", "bpr", "3")
    assert CellSpec.from_json(spec.to_json()) == spec


def tasks_of_sequence(selector, seed, episode, utilities, schedule="expert", types=None,
                      argmax=None, true_types=None):
    """A hand-made sequence's task rows."""
    rows = []
    for index, utility in enumerate(utilities, start=1):
        success = int(utility > 0)
        true = (true_types or {}).get(index, schedule)
        names = types or []
        belief = [1.0 / len(names)] * len(names) if names else []
        rows.append(TaskRow(
            schedule=schedule, selector=selector, seed=seed, episode=episode,
            task_index=index, human_model=true, true_type=true, policy="base",
            success=success, utility=utility, outcome="success" if success else "fail",
            who_succeeded="human" if success else "", belief_argmax=(argmax or {}).get(index, ""),
            estimation_correct=0, warnings=index % 2, preemptions=0, steps=10, duration=20.0,
            total_disc_reward=0.0, end_reason="success" if success else "object_left_belt",
            task_episode=task_episode(episode, index, len(utilities)),
            type_names=" ".join(names), type_belief=" ".join(repr(b) for b in belief)))
    return rows


def test_a_sequence_cut_short_is_dropped_on_open_and_runs_again_whole(tmp_path):
    store = SequenceStore(tmp_path)
    whole = tasks_of_sequence("bpr", 0, 0, [0.5, -0.2, 0.8])
    store.add(sequence_row(whole, 12.0), whole)
    cut = tasks_of_sequence("bpr", 0, 1, [0.1, 0.2, 0.3])
    # Killed after two of the next sequence's task rows, before its sequence row.
    with open(store.steps_path, "a") as f:
        f.write("".join(",".join(r.as_dict().values()) + "\n" for r in cut[:2]))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        reopened = SequenceStore(tmp_path)
    assert reopened.done() == {("expert", "bpr", 0, 0)}
    assert [t.key for t in reopened.tasks()] == [("expert", "bpr", 0, 0)] * 3
    assert any(issubclass(w.category, ResultsWarning) for w in caught)
    row = reopened.sequences()[0]
    assert (row.tasks, row.successes, row.steps) == (3, 2, 30)
    assert row.mean_utility == pytest.approx((0.5 - 0.2 + 0.8) / 3)
    assert Path(tmp_path, "tasks.csv").read_text().splitlines()[0].startswith(
        "schedule,selector,seed,episode,task_index,human_model,true_type,policy,success,utility")


def test_the_learning_curve_is_per_task_index_over_the_sequences():
    rows = (tasks_of_sequence("bpr", 0, 0, [-0.5, 0.5, 0.9])
            + tasks_of_sequence("bpr", 0, 1, [0.5, 0.7, 0.8])
            + tasks_of_sequence("bpr", 1, 0, [-0.4, -0.3, 0.9]))
    curve = {e["task_index"]: e for e in learning_curve(rows)}
    assert [curve[i]["n"] for i in (1, 2, 3)] == [3, 3, 3]
    assert [curve[i]["success"] for i in (1, 2, 3)] == pytest.approx([1 / 3, 2 / 3, 1.0])
    first = [-0.5, 0.5, -0.4]
    assert curve[1]["utility"] == pytest.approx(np.mean(first))
    assert (curve[1]["utility_low"], curve[1]["utility_high"]) == mean_ci(first)[1:]
    wilson = stats.binomtest(1, 3).proportion_ci(method="wilson")
    assert (curve[1]["success_low"], curve[1]["success_high"]) == pytest.approx(
        (wilson.low, wilson.high))


def test_tasks_to_identify_count_from_each_blocks_start_to_where_the_argmax_stays_right():
    types = ["a", "b"]
    # Tasks 1-4 are type a, 5-8 type b (a switch after task 4).
    true_types = {i: ("a" if i <= 4 else "b") for i in range(1, 9)}
    argmax = {1: "b", 2: "a", 3: "b", 4: "a",      # a: right from task 4 on -> 4 tasks
              5: "a", 6: "b", 7: "b", 8: "b"}      # b: right from its 2nd task on -> 2
    rows = tasks_of_sequence("bpr", 0, 0, [0.5] * 8, schedule="ab", types=types,
                             argmax=argmax, true_types=true_types)
    blocks = identification(rows)
    assert [(b["true_type"], b["first_task"], b["tasks"], b["tasks_to_identify"])
            for b in blocks] == [("a", 1, 4, 4), ("b", 5, 4, 2)]
    # Never right at the block's end: not identified (NaN), whatever came before.
    argmax[8] = "a"
    rows = tasks_of_sequence("bpr", 0, 0, [0.5] * 8, schedule="ab", types=types,
                             argmax=argmax, true_types=true_types)
    assert math.isnan(identification(rows)[1]["tasks_to_identify"])
    # A selector without a type belief identifies nothing.
    assert identification(tasks_of_sequence("random", 0, 0, [0.5] * 3)) == []


def test_the_best_fixed_policy_in_hindsight_has_the_highest_mean_utility():
    rows = (tasks_of_sequence("fixed:base", 0, 0, [0.2, 0.4])
            + tasks_of_sequence("fixed:policy3", 0, 0, [0.5, 0.3])
            + tasks_of_sequence("bpr", 0, 0, [0.9, 0.9]))
    assert best_fixed(rows) == "fixed:policy3"
    assert best_fixed(tasks_of_sequence("bpr", 0, 0, [0.9])) is None


def test_the_paired_tests_pair_the_same_tasks_and_are_scipys():
    mine = [0.9, 0.8, -0.3, 0.7, 0.95, 0.6, 0.85, -0.1]
    theirs = [0.5, 0.6, -0.4, 0.75, 0.2, -0.5, 0.3, -0.2]
    rows = tasks_of_sequence("bpr", 0, 0, mine)
    base = tasks_of_sequence("fixed:base", 0, 0, theirs) + \
        tasks_of_sequence("fixed:base", 0, 1, [0.1])    # a task bpr did not play: no pair
    tests = paired_tests(rows, base, "vs_best_fixed")
    assert tests["vs_best_fixed_pairs"] == 8
    expected = stats.wilcoxon(np.subtract(mine, theirs), zero_method="wilcox")
    assert tests["vs_best_fixed_utility_p"] == pytest.approx(expected.pvalue)
    assert tests["vs_best_fixed_utility_diff"] == pytest.approx(
        np.median(np.subtract(mine, theirs)))
    # Success: only bpr succeeded on task 6 (0.6 against -0.5); McNemar on the discordant.
    only_bpr = sum(1 for a, b in zip(mine, theirs) if a > 0 >= b)
    only_base = sum(1 for a, b in zip(mine, theirs) if b > 0 >= a)
    assert tests["vs_best_fixed_success_p"] == pytest.approx(
        stats.binomtest(only_base, only_bpr + only_base).pvalue)


def test_the_summary_sets_every_selector_against_the_best_fixed_policy_and_the_oracle():
    # Each task's utility a little jittered: no two differences of a pair of selectors tie,
    # so SciPy's Wilcoxon takes its exact table at 12 pairs, not a permutation test of every
    # sign (about 2 s of CPU a call with ties).
    jitter = np.random.default_rng(0)
    rows, played = [], {}
    for seed in (0, 1):
        for human in ("expert", "novice"):
            for selector, utilities in (("fixed:base", [0.2, 0.3, 0.1]),
                                        ("fixed:policy3", [0.4, 0.5, 0.6]),
                                        ("oracle", [0.8, 0.7, 0.9]),
                                        ("bpr", [-0.2, 0.6, 0.8])):
                mine = list(utilities + jitter.uniform(0, 0.01, 3))
                played.setdefault(selector, []).extend(mine)
                rows += tasks_of_sequence(selector, seed, 0, mine, schedule=human)
    summary = summarize_sequences(rows, base="fixed:base")
    by = {(e["schedule"], e["selector"]): e for e in summary}
    assert {s for s, _ in by} == {"expert", "novice", "per-type (pooled)"}
    pooled = by[("per-type (pooled)", "bpr")]
    assert pooled["tasks"] == 12 and pooled["best_fixed"] == "fixed:policy3"
    assert pooled["vs_best_fixed_pairs"] == 12 and pooled["vs_oracle_pairs"] == 12
    assert pooled["utility"] == pytest.approx(np.mean(played["bpr"]))
    # Against the authors' base too: beating it is not beating the best fixed policy.
    assert pooled["vs_base_pairs"] == 12 and pooled["base"] == "fixed:base"
    assert pooled["vs_base_utility_mean_diff"] == pytest.approx(
        np.mean(played["bpr"]) - np.mean(played["fixed:base"]))
    assert pooled["vs_best_fixed_utility_mean_diff"] == pytest.approx(
        np.mean(played["bpr"]) - np.mean(played["fixed:policy3"]))
    assert by[("expert", "fixed:base")]["vs_base_pairs"] == 0
    # Nobody is compared with itself; every q is at least its p.
    assert by[("expert", "oracle")]["vs_oracle_pairs"] == 0
    assert math.isnan(by[("expert", "oracle")]["vs_oracle_utility_q"])
    for e in summary:
        for prefix in ("vs_best_fixed", "vs_oracle", "vs_base"):
            if e[f"{prefix}_pairs"]:
                assert e[f"{prefix}_utility_q"] >= e[f"{prefix}_utility_p"] - 1e-12


def test_humans_given_as_files_are_per_type_cells_and_pooled_as_such():
    # hrc_perturb_humans' DIR/<type>.pomdpx: the cell is labelled by the file, its tasks by
    # the type it was made from.
    from ros_hrc.experiment.sequence_statistics import per_type_schedules
    rows = []
    for name in ("expert", "novice"):
        label = f"/humans/{name}.pomdpx"
        for selector in ("bpr", "fixed:base"):
            rows += tasks_of_sequence(selector, 2, 0, [0.5, 0.6], schedule=label,
                                      true_types={1: name, 2: name})
    assert per_type_schedules(rows) == ["/humans/expert.pomdpx", "/humans/novice.pomdpx"]
    pooled = [e for e in summarize_sequences(rows) if e["schedule"] == "per-type (pooled)"]
    assert {e["selector"]: e["tasks"] for e in pooled} == {"bpr": 4, "fixed:base": 4}
    # A schedule of two types is not one type throughout.
    mixed = tasks_of_sequence("bpr", 2, 0, [0.5, 0.6], schedule="/h/expert.pomdpx",
                              true_types={1: "expert", 2: "novice"})
    assert per_type_schedules(mixed) == []


def test_a_sequence_study_defaults_to_five_sequences_of_the_issues_selectors_per_type():
    from ros_hrc.experiment.cli import build_parser, check_mode
    words = ["--sequence", "30", "--task", "fabric"]
    args = build_parser().parse_args(words)
    check_mode(args, words)
    assert (args.episodes, args.schedule, args.library, args.selector_model) == \
        (5, ["per-type"], "auto", "auto")
    assert args.selectors == ["bpr", "bandit", "random", "oracle", "fixed"]
    words = ["--sequence", "30", "--episodes", "7", "--selectors", "random"]
    args = build_parser().parse_args(words)
    check_mode(args, words)
    assert (args.episodes, args.selectors) == (7, ["random"])


def test_the_learning_curve_plot_draws_the_adaptive_selectors_and_the_best_fixed(tmp_path):
    from ros_hrc.experiment.plots import NothingToPlot, plot_learning_curves
    rows = []
    for seed in (0, 1, 2):
        rows += tasks_of_sequence("bpr", seed, 0, [-0.3, 0.4, 0.8, 0.9])
        rows += tasks_of_sequence("random", seed, 0, [0.1, -0.2, 0.3, 0.2])
        rows += tasks_of_sequence("fixed:base", seed, 0, [0.5, 0.4, 0.6, 0.5])
        rows += tasks_of_sequence("fixed:policy1", seed, 0, [-0.5, -0.4, -0.6, -0.5])
    curve = learning_curve(rows)
    path = plot_learning_curves(curve, tmp_path / "learning_curve.png",
                                {"expert": best_fixed(rows)})
    assert Path(path).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(NothingToPlot):
        plot_learning_curves([e for e in curve if e["selector"] == "fixed:policy1"],
                             tmp_path / "none.png", {"expert": "fixed:base"})


def write_fixture_model(path, seeds, max_trials=None):
    """A selector model for fabric's library, from hand-made training tasks (a fixture: the
    shipped model comes from hrc_train_selector)."""
    from ros_hrc import tasks
    from ros_hrc.agents.library import load_library
    from ros_hrc.agents.selector_model import TrainingTask, from_tasks, write_selector_model
    from ros_hrc.experiment.grid import task_humans
    task = tasks.get("fabric")
    policies = load_library("auto", task).names()
    types = task_humans(task)
    rows = [TrainingTask(t, p, 0.1 * i, (i % 64,)) for i, t in enumerate(types)
            for p in policies for _ in range(2)]
    write_selector_model(from_tasks(rows, task="fabric", policies=policies, types=types,
                                    header={"how": "fixture", "from": "a test",
                                            "seeds": seeds, "command": "pytest",
                                            "date": "2026-11-27",
                                            **({"max_trials": max_trials}
                                               if max_trials else {})}), path)


def refusal_of_a_study_with_model(tmp_path, selectors, *words, **model):
    """The stderr of a sequence study with a fixture selector model (``model``: its seeds,
    max_trials), refused before anything ran (exit status 2, no results folder)."""
    write_fixture_model(tmp_path / "model.json", **model)
    done = run_cli("--task", "fabric", "--sequence", "3", "--selectors", selectors,
                   "--selector-model", "model.json", *words, "--out",
                   str(tmp_path / "results"), cwd=tmp_path)
    assert done.returncode == 2
    assert not (tmp_path / "results").exists()
    return done.stderr


def test_a_selector_model_is_not_evaluated_on_the_seeds_it_was_trained_on(tmp_path):
    stderr = refusal_of_a_study_with_model(tmp_path, "bpr,random", "--seeds", "1,7",
                                           seeds=[2, 7])
    assert stderr == (f"hrc_experiment: --selectors bpr: their selector model "
                      f"{tmp_path / 'model.json'} was trained on seeds 7, which this "
                      "study would evaluate them on; choose other --seeds, or give "
                      "--allow-in-sample to run them anyway\n")


def test_with_allow_in_sample_the_trained_seeds_run_with_a_warning_line():
    from ros_hrc.experiment.sequences import check_trained_elsewhere
    args = SimpleNamespace(selectors=["bpr", "fixed:base"], seeds=[2, 3],
                           selector_model_file="/m/model.json", allow_in_sample=True)
    assert check_trained_elsewhere(args, [3, 4]) == [
        "warning: --selectors bpr: their selector model /m/model.json was trained on seeds 3, "
        "which this study would evaluate them on (--allow-in-sample)"]
    # Selectors that use no model are not held to it.
    args.selectors = ["random", "fixed:base"]
    args.allow_in_sample = False
    assert check_trained_elsewhere(args, [2]) == []


def test_the_study_plans_with_the_trials_its_selector_model_was_trained_with(tmp_path):
    from ros_hrc.experiment.cli import adopt_model_trials
    args = SimpleNamespace(max_trials=0, selector_model_file="/m/model.json")
    assert adopt_model_trials(args, 100) == [
        "DESPOT plans with 100 trials per decision, as the selector model /m/model.json was "
        "trained (--max-trials to choose)"]
    assert args.max_trials == 100
    assert adopt_model_trials(args, 100) == []          # asked for the same: nothing to say
    assert adopt_model_trials(SimpleNamespace(max_trials=300), None) == []   # header silent
    stderr = refusal_of_a_study_with_model(tmp_path, "bpr", "--max-trials", "500", seeds=[4],
                                           max_trials=100)
    assert stderr == (f"hrc_experiment: --max-trials 500: the selector model "
                      f"{tmp_path / 'model.json'} was trained with DESPOT at 100 trials "
                      "per decision, and its utilities are of the policies planned so; "
                      "give --max-trials 100, or retrain it with --max-trials 500\n")


def test_a_selector_that_needs_a_model_without_one_names_make_train_selector(tmp_path):
    done = run_cli("--task", "fabric", "--sequence", "3", "--selectors", "oracle",
                   "--selector-model", "auto", "--library", str(tmp_path / "lib"),
                   "--out", str(tmp_path / "results"), cwd=tmp_path)
    assert done.returncode == 2 and len(done.stderr.splitlines()) == 1
    assert "--library" in done.stderr      # no library there: said first
    manifest = Path(__file__).resolve().parents[3] / "models" / "fabric" / "library.toml"
    (tmp_path / "lib").mkdir()
    # The same library in a folder without a selector model (its models named absolutely).
    (tmp_path / "lib" / "library.toml").write_text(
        manifest.read_text().replace('model = "', f'model = "{manifest.parent}/'))
    done = run_cli("--task", "fabric", "--sequence", "3", "--selectors", "oracle",
                   "--library", str(tmp_path / "lib"), "--out", str(tmp_path / "results"),
                   cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr == (f"hrc_experiment: --selectors oracle: no selector model "
                           f"{tmp_path / 'lib' / 'selector_model.json'}; make train-selector "
                           "writes it, or give --selector-model\n")


def test_the_learning_robot_is_launched_as_itself_on_its_prior_and_its_figure_is_kept():
    """pomdp_learning in a sequence study: the stack runs selector:=pomdp_learning with the
    study's learning settings on the task's learning prior; each task's row keeps the learnt
    figure and its spread."""
    assert expand_selectors(["pomdp_learning", "fixed:base"], POLICIES) == [
        "pomdp_learning", "fixed:base"]
    args = SimpleNamespace(library="auto", sequence=30, selector_model="auto", task="seed",
                           learning_strength=3.0, learning_forgetting=None, learning_draws=4)
    words = sequence_launch_args(args, "pomdp_learning", "per-type")
    assert "selector:=pomdp_learning" in words
    assert "learning_strength:=3.0" in words and "learning_draws:=4" in words
    assert not any(w.startswith("learning_forgetting") for w in words)
    assert not any(w.startswith("learning_") for w in sequence_launch_args(args, "bpr",
                                                                          "per-type"))
    row = task_row(status(selector="pomdp_learning", type_names=[], type_belief=[],
                          learnt_name="P(recovers alone from S2 within 3 steps of rIdle)",
                          learnt_value=0.25, learnt_spread=0.125),
                   "tired", "pomdp_learning", 2, 0)
    assert row.learnt == (0.25, 0.125)
    assert task_row(status(), "tired", "bpr", 2, 0).learnt == ()


def test_the_ceiling_needs_a_model_of_its_human_fitted_on_other_seeds(tmp_path):
    """pomdp_ceiling: DIR/<human>.pomdp, fitted (its hrc-fitted-on lines) on that human and
    on none of the study's seeds; each way it is not is one line naming what to do."""
    from ros_hrc.experiment.provenance import FittedStreams, file_sha256
    from ros_hrc.experiment.sequences import ceiling_model
    from ros_hrc.models import model_path
    from ros_hrc import tasks as task_registry
    human_file = str(model_path("tired", "human", task_registry.get("seed")))
    args = SimpleNamespace(ceiling_models=None, seeds=[2], human_files={"tired": human_file},
                           task="seed")
    with pytest.raises(GridError, match="give --ceiling-models DIR"):
        ceiling_model(args, "tired")
    args.ceiling_models = str(tmp_path)
    with pytest.raises(GridError, match="no model fitted on human tired .* hrc_fit "
                                        "--human-models tired"):
        ceiling_model(args, "tired")

    def fitted_on(seed, sha):
        line = FittedStreams("tired", sha, seed, (0, 100)).line()
        (tmp_path / "tired.pomdp").write_text(f"# {line}\ndiscount: 0.9\n")

    fitted_on(1, "0" * 64)
    with pytest.raises(GridError, match="was not fitted on human tired"):
        ceiling_model(args, "tired")
    fitted_on(2, file_sha256(human_file))
    with pytest.raises(GridError, match="fitted on seed 2 of human tired, which this study "
                                        "evaluates"):
        ceiling_model(args, "tired")
    fitted_on(1, file_sha256(human_file))
    assert ceiling_model(args, "tired") == str(tmp_path / "tired.pomdp")
    # A human given as a file: its model is DIR/<the file's stem>.pomdp, as its rows' label.
    args.human_files = {human_file: human_file}
    assert ceiling_model(args, human_file) == str(tmp_path / "tired.pomdp")
