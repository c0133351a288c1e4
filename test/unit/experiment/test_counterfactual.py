"""The study made sound (issue #21): every robot episode against the same human stream alone,
the paired statistics of the summary, the held-out rule for fitted models, the tuned reactive
baseline, and the counting of wasted actions and actions against a warning. No ROS master."""
import argparse
import math
import re
from pathlib import Path
from types import SimpleNamespace

import pytest

from ros_hrc.experiment import fit, paired
from ros_hrc.experiment.cli import DEFAULT_EPISODES, build_parser, main, validate_grid
from ros_hrc.experiment.grid import GridError, plan_alone_cells, plan_cells
from ros_hrc.experiment.recording import AloneEpisodes, PairedRecorder
from ros_hrc.experiment.episode import (against_warning, pair, pair_alone, robot_policy,
                                        score_episode, step_rows, wasted_actions)
from ros_hrc.experiment.provenance import FittedStreams, file_sha256, read_fitted_on
from ros_hrc.experiment.stack import launch_arguments
from ros_hrc.experiment.statistics import POOLED, best_reactive, markdown, summarize
from ros_hrc.experiment.rows import EpisodeRow
from ros_hrc.experiment.store import ResultsStore
from ros_hrc.model_files import resolve_model
from ros_hrc.pomdp.io import load_model

ROOT = Path(__file__).resolve().parents[3]
STATES = ["S0", "S1", "S2", "S3", "S4", "S5", "S6"]


@pytest.fixture(scope="module")
def robot_model():
    return load_model(str(resolve_model("robot", "robot")))


def step(n, robot_action="rIdle", bits=35, holder="none", human_action="idle", sim_time=None,
         robot_state="S0"):
    return SimpleNamespace(
        step=n, human_action=human_action, human_state="evaluating", observation_bits=bits,
        robot_observation=f"O{bits}", robot_state=robot_state, robot_action=robot_action,
        belief_states=STATES, belief=[1.0, 0, 0, 0, 0, 0, 0], decision_ms=1.0,
        sim_time=10.0 + 2 * n if sim_time is None else sim_time, object_holder=holder,
        object_left_belt=False, surprise=False)


def row(policy, number, who, time=None, alone=None, human="beginner", seed=1, in_sample=0):
    """A paired row: ``who`` succeeded (human / robot / none) at ``time``; ``alone`` is
    (success, time) of the human alone on the same stream."""
    success = who != "none"
    unpaired = EpisodeRow(human_model=human, robot_policy=policy, seed=seed, episode=number,
                          success=int(success), succeeded_by=who,
                          end_reason="success" if success else "step_limit", steps=5,
                          sim_seconds=time if success else 15.0, robot_discounted_reward=0.0,
                          intrusive_actions=0, warnings=0, zero_probability_observations=0,
                          mean_decision_ms=1.0, wall_seconds=1.0)
    alone_success, alone_time = alone
    by_herself = EpisodeRow(human_model=human, robot_policy="no_robot", seed=seed,
                            episode=number, success=int(alone_success),
                            succeeded_by="human" if alone_success else "none",
                            end_reason="success" if alone_success else "step_limit", steps=5,
                            sim_seconds=alone_time if alone_success else 15.0,
                            robot_discounted_reward=0.0, intrusive_actions=0, warnings=0,
                            zero_probability_observations=0, mean_decision_ms=1.0,
                            wall_seconds=1.0)
    return pair(unpaired, pair_alone(by_herself), in_sample=bool(in_sample))


# ------------------------------------------------------------------ the counterfactual pair

def test_a_robot_that_takes_the_object_from_a_human_who_succeeds_alone_pre_empts(
        robot_model, tmp_path):
    # Alone, the human grasps the object at step 3 (16 s); with the robot it grasps first.
    alone_steps = [step(0), step(1), step(2), step(3, human_action="graspAttempt",
                                                   holder="human", bits=11)]
    robot_steps = [step(0), step(1, robot_action="rGrasp_obj", holder="robot")]
    key_alone, key_robot = ("beginner", "no_robot", 1, 4), ("beginner", "pomdp", 1, 4)
    alone = pair_alone(score_episode(key_alone, alone_steps, "success", 9.0, robot_model, 1.0))
    unpaired = score_episode(key_robot, robot_steps, "success", 9.0, robot_model, 1.0)
    assert unpaired.outcome == "unpaired"
    paired_row = pair(unpaired, alone)
    assert (paired_row.alone_success, paired_row.outcome) == (1, "pre_empted")
    assert paired_row.time_to_success == pytest.approx(12.0 - 9.0)
    assert paired_row.alone_time_to_success == pytest.approx(16.0 - 9.0)
    assert paired_row.time_gain == pytest.approx(4.0)       # the robot made it 4 s sooner
    assert alone.outcome == "both_succeed" and alone.time_gain == 0.0

    store = ResultsStore(tmp_path)
    store.add(paired_row, step_rows(key_robot, robot_steps))
    back = ResultsStore(tmp_path).episodes()[0]
    assert back == paired_row
    assert (back.outcome, back.alone_success, back.time_gain) == ("pre_empted", 1, 4.0)


def test_each_counterfactual_outcome_and_its_times():
    assert row("pomdp", 0, "robot", 5.0, (0, None)).outcome == "rescued"
    assert row("pomdp", 0, "human", 5.0, (1, 6.0)).outcome == "both_succeed"
    assert row("pomdp", 0, "none", None, (1, 6.0)).outcome == "hindered"
    failed = row("pomdp", 0, "none", None, (0, None))
    assert failed.outcome == "both_fail"
    assert math.isnan(failed.time_to_success) and math.isnan(failed.time_gain)
    rescued = row("pomdp", 0, "robot", 5.0, (0, None))
    assert math.isnan(rescued.time_gain) and math.isnan(rescued.alone_time_to_success)


def test_a_row_whose_outcome_contradicts_its_pair_is_refused():
    cells = row("pomdp", 0, "robot", 5.0, (1, 6.0)).as_dict()
    cells["outcome"] = "both_succeed"
    with pytest.raises(ValueError, match="'outcome'"):
        EpisodeRow.from_dict(cells)
    with pytest.raises(ValueError, match="not the human alone"):
        pair(row("pomdp", 0, "robot", 5.0, (1, 6.0)), pair_alone(
            row("no_robot", 1, "human", 6.0, (1, 6.0))))


def test_a_results_directory_of_another_version_is_refused_in_one_line(tmp_path, capsys):
    old = ("human_model,robot_policy,seed,episode,success,succeeded_by,end_reason,steps,"
           "sim_seconds,robot_discounted_reward,intrusive_actions,warnings,"
           "zero_probability_observations,mean_decision_ms,wall_seconds\n")
    out = tmp_path / "old"
    out.mkdir()
    (out / "episodes.csv").write_text(old)
    code = main(["--human-models", "expert", "--policies", "reactive", "--seeds", "1",
                 "--episodes", "1", "--out", str(out)])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1
    assert err[0].startswith(f"hrc_experiment: {out / 'episodes.csv'}:1: written with other "
                             "columns (missing time_to_success, alone_success")
    assert (out / "episodes.csv").read_text() == old


# ------------------------------------------------------------------ wasted, against a warning

def test_wasted_actions_are_refused_grasps_and_points_at_a_human_away():
    steps = [step(0, robot_action="rGrasp_obj"),                           # refused: wasted
             step(1, human_action="walkAway", robot_action="rPoint_obj"),  # he is away: wasted
             step(2, human_action="idle", robot_action="rPoint_obj"),      # still away: wasted
             step(3, human_action="graspAttempt", robot_action="rPoint_obj"),   # back: not
             step(4, robot_action="rStop_all"),
             step(5, robot_action="rGrasp_obj", holder="robot")]           # got it: not
    assert wasted_actions(steps) == 3


def test_actions_against_a_warning_count_until_the_human_acts_on_the_object_again():
    steps = [step(0, robot_action="rGrasp_obj", bits=35),        # no warning yet
             step(1, robot_action="rPoint_obj", bits=19),        # warned: against
             step(2, robot_action="rStop_all", bits=19),
             step(3, robot_action="rGrasp_obj", bits=35),        # idle after it: still against
             step(4, robot_action="rPoint_obj", bits=7),         # a grasp attempt lifts it
             step(5, robot_action="rGrasp_obj", bits=3)]
    assert against_warning(steps) == 2


# -------------------------------------------------------------------------- the statistics

def stream_rows():
    """12 streams of one human: the pomdp robot, two reactive budgets, known patterns."""
    alone = [(1, 8.0)] * 4 + [(0, None)] * 8
    pomdp = ["robot"] * 10 + ["none"] * 2            # pre-empts 4, rescues 6
    fast = ["human"] * 4 + ["robot"] * 2 + ["none"] * 6       # reactive@2: 6 successes
    slow = ["human"] * 4 + ["robot"] * 2 + ["none"] * 6       # reactive@5: the same, slower
    rows = []
    for i in range(12):
        rows.append(row("pomdp", i, pomdp[i], 5.0 + i % 3, alone[i]))
        rows.append(row("reactive@2", i, fast[i], 7.0, alone[i]))
        rows.append(row("reactive@5", i, slow[i], 9.0, alone[i]))
    return rows


def test_the_best_reactive_budget_is_the_most_successful_then_least_pre_empting_then_fastest():
    rows = stream_rows()
    assert best_reactive(rows) == "reactive@2"         # same success and pre-emptions, faster
    worse = [r for r in rows if r.robot_policy != "reactive@2"] + [
        row("reactive@2", i, "none", None, (1, 8.0) if i < 4 else (0, None)) for i in range(12)]
    assert best_reactive(worse) == "reactive@5"
    tie = [row("reactive@3", 0, "human", 7.0, (1, 8.0)), row("reactive@1", 0, "human", 7.0,
                                                            (1, 8.0))]
    assert best_reactive(tie) == "reactive@1"           # all equal: the smallest budget
    assert best_reactive([row("pomdp", 0, "human", 7.0, (1, 8.0))]) is None


def test_the_summary_s_paired_tests_are_those_of_paired_py():
    rows = stream_rows()
    summary = {(e["human_model"], e["robot_policy"]): e for e in summarize(rows)}
    e = summary[("beginner", "pomdp")]
    assert e["best_reactive"] == "reactive@2"
    pomdp = sorted((r for r in rows if r.robot_policy == "pomdp"), key=lambda r: r.episode)
    best = sorted((r for r in rows if r.robot_policy == "reactive@2"), key=lambda r: r.episode)
    success = paired.mcnemar_exact([r.success for r in best], [r.success for r in pomdp])
    pre = paired.mcnemar_exact([r.outcome == "pre_empted" for r in best],
                               [r.outcome == "pre_empted" for r in pomdp])
    both = [(b.time_to_success, p.time_to_success) for b, p in zip(best, pomdp)
            if b.success and p.success]
    # A gain: reactive@2's time minus pomdp's (positive: pomdp succeeded sooner).
    times = paired.wilcoxon_paired([p for _, p in both], [b for b, _ in both])
    assert (e["vs_reactive_policy"], e["vs_reactive_pairs"]) == ("reactive@2", 12)
    assert e["vs_reactive_success_diff"] == pytest.approx(4 / 12)
    assert e["vs_reactive_success_p"] == success.p_value
    assert e["vs_reactive_pre_empted_diff"] == pytest.approx(4 / 12)
    assert e["vs_reactive_pre_empted_p"] == pre.p_value
    assert e["vs_reactive_time_pairs"] == len(both) == 6
    assert e["vs_reactive_time_gain_median"] == times.median_difference
    assert e["vs_reactive_time_p"] == times.p_value
    # The human's own success: reactive@2 leaves the first four to him, the pomdp robot
    # takes every object it gets.
    own = paired.mcnemar_exact([r.succeeded_by == "human" for r in best],
                               [r.succeeded_by == "human" for r in pomdp])
    assert e["vs_reactive_own_success_diff"] == pytest.approx(-4 / 12)
    assert e["vs_reactive_own_success_p"] == own.p_value
    assert e["vs_alone_own_success_diff"] == pytest.approx(-4 / 12)
    assert "Δ own success" in markdown(summarize(rows))
    # Against the human alone, from each row's own counterfactual columns.
    alone = paired.mcnemar_exact([r.alone_success for r in pomdp], [r.success for r in pomdp])
    assert e["vs_alone_success_p"] == alone.p_value
    assert e["vs_alone_success_diff"] == pytest.approx(6 / 12)
    assert e["vs_alone_pre_empted_p"] == paired.mcnemar_exact(
        [0] * 12, [r.outcome == "pre_empted" for r in pomdp]).p_value
    # Counts and intervals.
    assert (e["pre_empted"], e["rescued"], e["both_fail"]) == (4, 6, 2)
    assert (e["pre_empted_rate"], e["pre_empted_low"], e["pre_empted_high"]) == \
        paired.wilson(4, 12)
    assert (e["success_rate"], e["success_low"], e["success_high"]) == paired.wilson(10, 12)
    assert summary[("beginner", "reactive@2")]["vs_reactive_policy"] == ""   # itself
    assert summary[("beginner", "reactive@5")]["vs_reactive_policy"] == "reactive@2"


def test_the_pool_takes_the_held_out_streams_of_every_human():
    rows = stream_rows() + [row("pomdp", i, "robot", 5.0, (0, None), human="tired")
                            for i in range(3)] + \
        [row("pomdp", i, "robot", 5.0, (0, None), human="tired", seed=0, in_sample=1)
         for i in range(2)] + \
        [row("reactive@5", i, "none", None, (0, None), human="tired") for i in range(3)]
    pooled = {e["robot_policy"]: e for e in summarize(rows) if e["human_model"] == POOLED}
    assert pooled["pomdp"]["n"] == 12 + 3 and pooled["pomdp"]["in_sample"] == 0
    assert pooled["pomdp"]["best_reactive"] == "reactive@2"     # over all humans
    assert pooled["pomdp"]["vs_reactive_pairs"] == 12            # tired has no reactive@2


def test_the_default_episodes_detect_a_15_point_difference():
    assert DEFAULT_EPISODES == paired.episodes_to_detect(0.15, loss=0.05, alpha=0.05,
                                                         power=0.8) == 92


# ------------------------------------------------------------------ held-out discipline

def fitted_model(tmp_path, human="expert", seed=0, episodes=(0, 100)):
    """The shipped robot model with the header hrc_fit writes for ``human``."""
    human_file = resolve_model(human, "human")
    args = argparse.Namespace(human_models=[human], human_files={human: str(human_file)},
                              seed=seed, episodes=episodes[1])
    lines = fit.fitted_on_lines(args)
    path = tmp_path / "fitted.pomdp"
    path.write_text("".join(f"# {line}\n" for line in ["fitted by a test", *lines]) +
                    (ROOT / "models" / "robot" / "robot.pomdp").read_text())
    return path


def test_hrc_fit_writes_the_streams_it_fitted_on_into_the_header(tmp_path):
    path = fitted_model(tmp_path, "expert", seed=3, episodes=(0, 40))
    assert read_fitted_on(path) == [FittedStreams(
        "expert", file_sha256(resolve_model("expert", "human")), 3, (0, 40))]
    assert load_model(str(path)).states == STATES      # still a model


def grid(tmp_path, *extra):
    return build_parser().parse_args([
        "--robot-model", str(fitted_model(tmp_path)), "--human-models", "expert,tired",
        "--policies", "pomdp,reactive", "--episodes", "4", "--out", str(tmp_path / "out"),
        *extra])


def test_a_fitted_model_is_not_evaluated_on_the_streams_it_was_fitted_on(tmp_path, capsys):
    with pytest.raises(GridError, match=r"--policies pomdp: its robot model .*fitted.pomdp was "
                                        r"fitted on human model expert, seed 0, episodes 0-3"):
        validate_grid(grid(tmp_path, "--seeds", "0,1"))
    validate_grid(grid(tmp_path, "--seeds", "1,2"))         # other seeds: held out
    code = main(["--robot-model", str(fitted_model(tmp_path)), "--human-models", "expert",
                 "--policies", "pomdp", "--seeds", "0", "--out", str(tmp_path / "o2")])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and "--allow-in-sample" in err[0]
    assert not (tmp_path / "o2").exists()


def test_allow_in_sample_runs_them_marked(tmp_path):
    args = grid(tmp_path, "--seeds", "0,1", "--allow-in-sample")
    validate_grid(args)
    assert args.in_sample == {("pomdp", "expert", 0): {0, 1, 2, 3}}   # reactive ignores T, O
    store = ResultsStore(tmp_path / "out")
    recorder = PairedRecorder(store, AloneEpisodes(store, tmp_path / "out", False),
                              args.in_sample)
    for seed in (0, 1):
        alone = row("no_robot", 2, "human", 8.0, (1, 8.0), human="expert", seed=seed)
        recorder.add(alone, [])
        unpaired = EpisodeRow.from_dict({**row("pomdp", 2, "robot", 5.0, (1, 8.0),
                                               human="expert", seed=seed).as_dict(),
                                         "alone_success": "0", "alone_time_to_success": "nan",
                                         "outcome": "unpaired", "time_gain": "nan"})
        recorder.add(unpaired, [])
    marks = {r.seed: (r.in_sample, r.outcome) for r in store.episodes()}
    assert marks == {0: (1, "pre_empted"), 1: (0, "pre_empted")}


# ------------------------------------------------------------------ the human alone, cached

def test_the_human_alone_runs_once_per_stream_and_is_reused_on_resume(tmp_path):
    out = tmp_path / "out"
    args = build_parser().parse_args([
        "--human-models", "expert,tired", "--policies", "pomdp,reactive",
        "--reactive-budgets", "1..3", "--seeds", "1", "--episodes", "3", "--out", str(out)])
    validate_grid(args)
    assert args.policies == ["pomdp", "reactive", "reactive@1", "reactive@2", "reactive@3"]
    store = ResultsStore(out)
    alone = AloneEpisodes(store, out, grid_has_alone=False)
    cells = plan_alone_cells(args, alone)
    # One no_robot cell per (human model, seed), however many robot policies there are.
    assert [(c.human_model, c.robot_policy, list(c.episodes)) for c in cells] == [
        ("expert", "no_robot", [0, 1, 2]), ("tired", "no_robot", [0, 1, 2])]
    assert all(Path(c.log_dir) == out / "alone" / "logs" for c in cells)
    recorder = PairedRecorder(store, alone)
    for human in ("expert", "tired"):
        for e in range(3):
            recorder.add(row("no_robot", e, "human", 8.0, (1, 8.0), human=human), [])
    assert store.episodes() == []                       # not the grid's rows
    # A resumed run (a new process) finds them and runs no human-alone episode again.
    again = AloneEpisodes(ResultsStore(out), out, grid_has_alone=False)
    assert plan_alone_cells(args, again) == []
    assert len(again.rows) == 6
    # Every robot cell's episodes have their pair; a stream without one is left for later.
    robot_cells = plan_cells(args, set())
    assert {c.robot_policy for c in robot_cells} == set(args.policies)
    cell = robot_cells[0]
    assert PairedRecorder(store, again).gate(cell) == cell
    del again.rows[(cell.human_model, cell.seed, 1)]
    assert list(PairedRecorder(store, again).gate(cell).episodes) == [0, 2]
    # With no_robot in the grid, its episodes already run are taken, not run again.
    with_alone = build_parser().parse_args([
        "--human-models", "expert,tired", "--policies", "pomdp,no_robot", "--seeds", "1",
        "--episodes", "3", "--out", str(out)])
    validate_grid(with_alone)
    store = ResultsStore(out)
    grid_alone = AloneEpisodes(store, out, grid_has_alone=True)
    assert grid_alone.adopt_into_grid(with_alone) == 6
    assert plan_alone_cells(with_alone, grid_alone) == []
    assert [c.robot_policy for c in plan_cells(with_alone, store.done())] == ["pomdp", "pomdp"]


def test_a_budget_sweep_names_its_policies_and_launches_each_budget(tmp_path):
    args = build_parser().parse_args(["--human-models", "expert", "--policies", "pomdp",
                                      "--reactive-budgets", "2,5", "--seeds", "1",
                                      "--episodes", "1", "--out", str(tmp_path)])
    validate_grid(args)
    cells = {c.robot_policy: c for c in plan_cells(args, set())}
    assert set(cells) == {"pomdp", "reactive@2", "reactive@5"}
    words = launch_arguments(cells["reactive@5"], {"master": 1, "pomdp": 2, "robot": 3,
                                                   "human": 4})
    assert "planner:=reactive" in words and "reactive_budget:=5" in words
    assert robot_policy("reactive@5").reactive_budget == 5
    with pytest.raises(KeyError):
        robot_policy("reactive@0")
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--reactive-budgets", "0..3"])


def test_q_values_adjust_each_test_over_the_summary_by_benjamini_hochberg():
    """Against values worked by hand: p = 0.01, 0.04, 0.03 of one family give BH q-values
    min over the larger ranks of p·m/rank: 0.03, 0.04, 0.04."""
    from ros_hrc.experiment.statistics import adjust_for_many_tests
    summary = [{"vs_reactive_success_p": p, "vs_reactive_pre_empted_p": math.nan,
                "vs_reactive_time_p": 0.5, "vs_alone_success_p": 0.2,
                "vs_alone_pre_empted_p": 1.0, "vs_alone_time_p": math.nan}
               for p in (0.01, 0.04, 0.03)]
    adjust_for_many_tests(summary)
    assert [e["vs_reactive_success_q"] for e in summary] == pytest.approx([0.03, 0.04, 0.04])
    assert all(math.isnan(e["vs_reactive_pre_empted_q"]) for e in summary)
    assert [e["vs_reactive_time_q"] for e in summary] == pytest.approx([0.5] * 3)
    assert [e["vs_alone_pre_empted_q"] for e in summary] == pytest.approx([1.0] * 3)


def test_the_summary_gives_every_comparison_its_q_value():
    summary = summarize(stream_rows())
    compared = [e for e in summary if e["vs_reactive_policy"]]
    assert compared
    for e in compared:
        assert e["vs_reactive_success_q"] >= e["vs_reactive_success_p"]
    assert re.search(r"\| +q +\|", markdown(summary))


def test_a_time_against_the_human_alone_has_one_sign_in_every_table():
    """Issue #41: the outcomes table gave the time gain as alone - robot (-1.35) and the
    comparisons as robot - alone (+1.35) for the same pairs. Both are now the gain (the
    other's time minus the policy's), and the summary's first line says so."""
    summary = summarize(stream_rows())
    compared = [e for e in summary if e["vs_alone_time_pairs"]]
    assert compared
    for e in compared:
        assert e["time_gain_pairs"] == e["vs_alone_time_pairs"]
        assert e["time_gain_median"] == pytest.approx(e["vs_alone_time_gain_median"])
    assert markdown(summary).startswith("Time gain: the other's time to success minus the "
                                        "robot policy's")
