"""The results: rows and their CSV form, the store an interrupted run resumes from and its lock
(store.py), confidence intervals against hand-computed values and the summary (statistics.py),
and the plots (plots.py)."""
import csv
import math
import os
import warnings

import pytest

from ros_hrc.experiment.plots import plot_belief, plot_outcomes, plot_success, plot_time_gain
from ros_hrc.experiment.statistics import (POOLED, SUMMARY_COLUMNS, format_ci, mean_ci,
                                           proportion_ci, summarize, write_summary)
from ros_hrc.experiment.rows import EPISODE_COLUMNS, STEP_COLUMNS, EpisodeRow, StepRow
from ros_hrc.experiment.store import ResultsStore, ResultsWarning
from result_rows import episode, steps_of

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def read_lines(path):
    with open(path, encoding="utf-8") as f:
        return f.read().splitlines()


# ------------------------------------------------------------------------------------ rows

def test_columns_are_in_the_agreed_order_and_match_the_dataclasses():
    assert EPISODE_COLUMNS == (
        "human_model", "robot_policy", "seed", "episode", "success", "succeeded_by",
        "end_reason", "steps", "sim_seconds", "time_to_success", "alone_success",
        "alone_time_to_success", "outcome", "time_gain", "wasted_actions", "against_warning",
        "in_sample", "points", "warnings_after_help", "robot_discounted_reward",
        "intrusive_actions", "warnings",
        "zero_probability_observations", "mean_decision_ms", "wall_seconds")
    assert STEP_COLUMNS == (
        "human_model", "robot_policy", "seed", "episode", "step", "human_action",
        "human_state", "robot_state", "robot_action", "observation", "belief_needs_help",
        "needs_help", "zero_probability")
    assert tuple(episode().as_dict()) == EPISODE_COLUMNS
    assert tuple(steps_of(episode())[0].as_dict()) == STEP_COLUMNS


def test_rows_round_trip_through_their_csv_cells():
    row = episode(sim_seconds=0.1 + 0.2, mean_decision_ms=math.nan)
    cells = row.as_dict()
    assert all(isinstance(v, str) for v in cells.values())
    back = EpisodeRow.from_dict(cells)
    assert back.sim_seconds == 0.1 + 0.2          # full precision survives
    assert math.isnan(back.mean_decision_ms)
    assert back.as_dict() == cells
    step = StepRow("a,b", "p", 1, 2, 3, "graspAttempt", "failed_to_grasp", "S2", "rPoint_obj",
                   "O35", 0.625, 1, 0)
    assert StepRow.from_dict(step.as_dict()) == step


@pytest.mark.parametrize("column,value", [("seed", "x"), ("steps", "3.5"), ("sim_seconds", "")])
def test_from_dict_names_the_bad_column_and_value(column, value):
    cells = episode().as_dict()
    cells[column] = value
    with pytest.raises(ValueError) as e:
        EpisodeRow.from_dict(cells)
    assert repr(column) in str(e.value) and repr(value) in str(e.value)


def test_rows_refuse_values_outside_their_domain():
    with pytest.raises(ValueError, match="succeeded_by"):
        episode(succeeded_by="nobody")
    with pytest.raises(ValueError, match="end_reason"):
        episode(outcome="object_left_belt", end_reason="timeout")
    with pytest.raises(ValueError, match="contradicts"):
        episode(outcome="human", end_reason="step_limit")
    with pytest.raises(ValueError, match="seed"):
        episode(seed="3")                          # constructors do not parse strings
    with pytest.raises(ValueError, match="line breaks"):
        episode(human="two\nlines")
    with pytest.raises(ValueError, match="belief_needs_help"):
        StepRow("h", "p", 0, 0, 0, "idle", "s", "S0", "rIdle", "O0", 1.5, 0, 0)
    with pytest.raises(ValueError, match="missing column"):
        EpisodeRow.from_dict({"human_model": "h"})


# ----------------------------------------------------------------------------------- store

def test_a_new_store_writes_the_headers(tmp_path):
    store = ResultsStore(tmp_path / "run")
    assert read_lines(store.episodes_path) == [",".join(EPISODE_COLUMNS)]
    assert read_lines(store.steps_path) == [",".join(STEP_COLUMNS)]
    assert store.done() == set() and store.episodes() == [] and store.steps() == []


def test_added_episodes_are_on_disk_and_seen_by_a_new_store(tmp_path):
    store = ResultsStore(tmp_path)
    a, b = episode(number=0), episode(number=1, outcome="step_limit")
    store.add(a, steps_of(a))
    store.add(b, steps_of(b, needs=(0,), beliefs=(0.5,)))
    assert len(read_lines(store.episodes_path)) == 3   # written at once, not at close
    again = ResultsStore(tmp_path)
    assert again.done() == {a.key, b.key}
    assert again.episodes() == [a, b]
    assert again.steps() == steps_of(a) + steps_of(b, needs=(0,), beliefs=(0.5,))


def test_add_refuses_a_recorded_episode_and_foreign_steps(tmp_path):
    store = ResultsStore(tmp_path)
    a = episode()
    store.add(a, steps_of(a))
    with pytest.raises(ValueError, match="already recorded"):
        store.add(a, [])
    with pytest.raises(ValueError, match="belongs to episode"):
        store.add(episode(number=5), steps_of(a))
    assert ResultsStore(tmp_path).steps() == steps_of(a)   # nothing of the refused adds


def test_resume_after_a_kill_in_the_middle_of_a_line(tmp_path):
    store = ResultsStore(tmp_path)
    a, b = episode(number=0), episode(number=1)
    store.add(a, steps_of(a))
    # Killed while writing b: its steps are complete, its episode row is cut short.
    with open(store.steps_path, "a", encoding="utf-8") as f:
        f.write("\n".join(",".join(s.as_dict().values()) for s in steps_of(b)) + "\n")
        f.write("careful,pomdp,0,1,2,idle")                  # and a partial step row too
    with open(store.episodes_path, "a", encoding="utf-8") as f:
        f.write(",".join(b.as_dict().values())[:20])
    with pytest.warns(ResultsWarning) as record:
        resumed = ResultsStore(tmp_path)
    messages = " ".join(str(w.message) for w in record)
    assert "partially written" in messages and "unfinished episode" in messages
    assert resumed.done() == {a.key}
    assert resumed.episodes() == [a] and resumed.steps() == steps_of(a)
    resumed.add(b, steps_of(b))                              # the rerun appends cleanly
    assert ResultsStore(tmp_path).steps() == steps_of(a) + steps_of(b)


def test_a_partial_header_is_replaced_by_a_whole_one(tmp_path):
    (tmp_path / "episodes.csv").write_text("human_model,robot_pol")
    with pytest.warns(ResultsWarning):
        store = ResultsStore(tmp_path)
    assert read_lines(store.episodes_path) == [",".join(EPISODE_COLUMNS)]


def test_a_file_with_another_header_is_refused_with_file_and_line(tmp_path):
    (tmp_path / "steps.csv").write_text("human_model,robot_policy,seed\n")
    with pytest.raises(ValueError) as e:
        ResultsStore(tmp_path)
    assert f"{tmp_path / 'steps.csv'}:1:" in str(e.value)
    assert (tmp_path / "steps.csv").read_text() == "human_model,robot_policy,seed\n"  # untouched


def test_a_bad_row_is_refused_with_file_line_and_column(tmp_path):
    store = ResultsStore(tmp_path)
    store.add(episode(number=0))
    cells = episode(number=1).as_dict()
    cells["warnings"] = "many"
    with open(store.episodes_path, "a", encoding="utf-8", newline="") as f:
        csv.writer(f, lineterminator="\n").writerow(cells.values())
    with pytest.raises(ValueError) as e:
        ResultsStore(tmp_path)
    message = str(e.value)
    assert f"{store.episodes_path}:3:" in message and "'warnings'" in message and "many" in message


# ------------------------------------------------------------------------------ statistics

def test_mean_ci_is_scipys_bootstrap_percentile_interval():
    import numpy as np
    from scipy import stats

    values = [1, 2, 3, 4, 5]
    mean, low, high = mean_ci(values)
    again = stats.bootstrap((np.array(values, float),), np.mean, n_resamples=9999,
                            method="percentile", rng=np.random.default_rng(0))
    assert mean == 3
    assert (low, high) == pytest.approx(tuple(again.confidence_interval), abs=1e-12)
    assert mean_ci(values) == (mean, low, high)       # the same every time: a fixed seed
    m90, l90, h90 = mean_ci(values, confidence=0.90)
    assert low < l90 < m90 < h90 < high


def test_an_interval_of_counts_or_durations_never_leaves_their_range():
    """Issue #41: Student's t gave `Steps 3.5 [-2.9, 9.9]` and `Sim time 4.80 [-10.45, 20.05]`
    (two episodes each): negative steps and seconds."""
    for values in ([1, 6], [0.0, 9.6], [0, 0, 0, 1, 14]):
        mean, low, high = mean_ci(values)
        assert min(values) <= low <= mean <= high <= max(values), (values, low, high)


def test_mean_ci_edge_cases():
    assert all(math.isnan(v) for v in mean_ci([]))
    mean, low, high = mean_ci([4.0])
    assert mean == 4.0 and math.isnan(low) and math.isnan(high)   # one value: no spread known
    assert mean_ci([2, 2, 2]) == (2, 2, 2)
    with pytest.raises(ValueError):
        mean_ci([1.0, math.nan])
    with pytest.raises(ValueError):
        mean_ci([1, 2], confidence=1.0)


def test_proportion_ci_is_the_wilson_interval():
    p, low, high = proportion_ci(8, 10)
    assert p == 0.8
    assert low == pytest.approx(0.4902, abs=1e-4) and high == pytest.approx(0.9433, abs=1e-4)
    from scipy.stats import binomtest
    for k, n in [(0, 10), (10, 10), (3, 7), (1, 1), (17, 40)]:
        expected = binomtest(k, n).proportion_ci(0.95, method="wilson")
        _, low, high = proportion_ci(k, n)
        assert (low, high) == pytest.approx((expected.low, expected.high), abs=1e-12)
    assert proportion_ci(0, 10)[1] == 0.0 and proportion_ci(10, 10)[2] == 1.0
    assert all(math.isnan(v) for v in proportion_ci(0, 0))
    with pytest.raises(ValueError):
        proportion_ci(11, 10)


def grid_rows():
    rows = []
    for human in ("careful", "distracted"):
        for policy in ("pomdp", "reactive"):
            for number, outcome in enumerate(("human", "robot", "object_left_belt", "human")):
                rows.append(episode(human, policy, 7, number, outcome, steps=10 + number,
                                    mean_decision_ms=math.nan if policy == "reactive" else 2.0))
    return rows


def test_summarize_groups_in_order_of_first_appearance_and_counts():
    rows = grid_rows()
    rows.insert(0, rows.pop(5))                 # ("careful", "reactive") now appears first
    summary = summarize(rows)
    assert [(s["human_model"], s["robot_policy"]) for s in summary] == [
        ("careful", "reactive"), ("careful", "pomdp"), ("distracted", "pomdp"),
        ("distracted", "reactive"), (POOLED, "reactive"), (POOLED, "pomdp")]
    s = summary[1]
    assert set(s) == set(SUMMARY_COLUMNS)
    assert (s["n"], s["successes"], s["human_successes"], s["robot_successes"]) == (4, 3, 2, 1)
    assert (s["object_left_belt"], s["step_limit"]) == (1, 0)
    assert (s["success_rate"], s["success_low"], s["success_high"]) == proportion_ci(3, 4)
    assert (s["steps_mean"], s["steps_low"], s["steps_high"]) == mean_ci([10, 11, 12, 13])
    assert s["reward_mean"] == -3.25 and s["mean_decision_ms"] == 2.0
    assert math.isnan(summary[0]["mean_decision_ms"])   # no timed decisions at all


def cells(line):
    """A Markdown table row's cells, without tabulate's padding."""
    return [cell.strip() for cell in line.strip().strip("|").split("|")]


def test_write_summary_writes_a_csv_and_a_paper_ready_table(tmp_path):
    summary = summarize(grid_rows() + [episode("lone", "pomdp")])
    csv_path, md_path = write_summary(summary, tmp_path / "s.csv", tmp_path / "out" / "s.md")
    with open(csv_path, encoding="utf-8") as f:
        table = list(csv.DictReader(f))
    assert tuple(table[0]) == SUMMARY_COLUMNS and len(table) == 5 + 2   # + 2 pooled
    assert float(table[0]["success_low"]) == summary[0]["success_low"]
    md = read_lines(md_path)
    assert md[0].startswith("Time gain: the other's time to success minus the robot policy's")
    assert md[2] == "## Outcomes against the human alone"
    assert cells(md[4])[:3] == ["Human model", "Robot policy", "n"]
    assert md[5].startswith("|:---") and md[5].endswith("--:|")   # names left, numbers right
    assert cells(md[6])[:4] == ["careful", "pomdp", "4", format_ci(*proportion_ci(3, 4))]
    assert cells(md[10])[:4] == ["lone", "pomdp", "1", "1.00 [0.21, 1.00]"]
    assert any(cells(line)[:3] == ["lone", "pomdp", "12.0 [n/a]"] for line in md)  # one ep.
    assert format_ci(0.85, 0.71, 0.93) == "0.85 [0.71, 0.93]"


# ----------------------------------------------------------------------------------- plots

def assert_png(path):
    with open(path, "rb") as f:
        data = f.read()
    assert data[:8] == PNG_SIGNATURE and len(data) > 10_000


def test_plot_outcomes_writes_a_png(tmp_path):
    summary = summarize(grid_rows() + [episode("lone", "pomdp")])   # a missing pair, an n=1
    path = plot_outcomes(summary, tmp_path / "plots" / "outcomes.png")
    assert path == str(tmp_path / "plots" / "outcomes.png")
    assert_png(path)
    with pytest.raises(ValueError):
        plot_outcomes([], tmp_path / "empty.png")


def test_plot_success_writes_a_png_with_a_missing_pair_and_an_n_of_1(tmp_path):
    summary = summarize(grid_rows() + [episode("lone", "pomdp")])
    path = plot_success(summary, tmp_path / "plots" / "success.png")
    assert path == str(tmp_path / "plots" / "success.png")
    assert_png(path)
    with pytest.raises(ValueError):
        plot_success([], tmp_path / "empty.png")


def test_plot_belief_writes_a_png_and_picks_an_episode_with_need(tmp_path):
    calm = episode(number=0)
    rows = steps_of(calm, needs=(0, 0), beliefs=(0.1, 0.2))
    for policy, beliefs in (("pomdp", (0.2, 0.6, 0.9, 0.4)), ("reactive", (0.0, 0.0, 1.0, 1.0))):
        rows += steps_of(episode(policy=policy, number=1), beliefs=beliefs)
    with warnings.catch_warnings():
        warnings.simplefilter("error")               # the two runs agree on the truth
        assert_png(plot_belief(rows, tmp_path / "belief.png"))
    assert_png(plot_belief(rows, tmp_path / "calm.png", episode=calm.key))
    with pytest.raises(ValueError, match="no step rows"):
        plot_belief(rows, tmp_path / "x.png", episode=("careful", "pomdp", 0, 9))


def test_plot_belief_warns_when_runs_disagree_on_the_truth(tmp_path):
    rows = steps_of(episode(policy="pomdp"), needs=(0, 1, 1, 0))
    rows += steps_of(episode(policy="reactive"), needs=(0, 0, 1, 1))
    with pytest.warns(ResultsWarning, match="disagree"):
        assert_png(plot_belief(rows, tmp_path / "b.png"))


def drawn_figures(monkeypatch):
    """The figures the plots save, kept (each is saved as before)."""
    from ros_hrc.experiment import plots

    figures, save = [], plots._save
    monkeypatch.setattr(plots, "_save", lambda fig, path: (figures.append(fig), save(fig, path))[1])
    return figures


def inside(fig, artist):
    box, frame = artist.get_window_extent(), fig.bbox
    return frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1


def test_a_plot_s_title_fits_its_figure_of_one_panel(tmp_path, monkeypatch):
    """Issue #41: outcomes.png and time_gain.png of one or two human models cut their titles
    at both edges."""
    figures = drawn_figures(monkeypatch)
    rows = [r for r in grid_rows() if r.human_model == "careful"]
    plot_outcomes(summarize(rows), tmp_path / "outcomes.png")
    plot_time_gain(rows, tmp_path / "time_gain.png")
    for fig in figures:
        fig.canvas.draw()
        assert inside(fig, fig._suptitle), fig._suptitle.get_text()


def test_policies_of_the_same_belief_each_show_in_the_belief_plot(tmp_path, monkeypatch):
    """Issue #41: in belief.png one policy's line hid another's (the same beliefs step by
    step): each line has its own dash and marker, the first drawn widest."""
    figures = drawn_figures(monkeypatch)
    rows = []
    for policy in ("no_robot", "reactive", "pomdp"):
        rows += steps_of(episode(policy=policy, number=1), beliefs=(0.1, 1.0, 1.0, 1.0))
    plot_belief(rows, tmp_path / "belief.png")
    lines = [line for line in figures[0].axes[0].get_lines() if len(line.get_xdata())]
    assert len(lines) == 3
    assert len({(str(line.get_linestyle()), line.get_marker()) for line in lines}) == 3
    widths = [line.get_linewidth() for line in lines]
    assert widths == sorted(widths, reverse=True) and widths[0] > widths[-1]
    assert all(line.get_markerfacecolor() == "none" for line in lines)


# ------------------------------------------------------------------ files that cannot be used

def test_a_binary_results_file_is_refused_by_name_and_left_as_it_is(tmp_path):
    """Before: refused without naming the file, after being cut back to its last newline."""
    binary = b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00\x01\x00 not a csv"
    (tmp_path / "episodes.csv").write_bytes(binary)
    with pytest.raises(ValueError) as info:
        ResultsStore(tmp_path)
    assert str(info.value).startswith(f"{tmp_path / 'episodes.csv'}: not a results CSV: "
                                      "binary data")
    assert (tmp_path / "episodes.csv").read_bytes() == binary


def test_nothing_is_repaired_when_the_other_file_is_refused(tmp_path):
    """A partial last line of episodes.csv is cut only once steps.csv is known to be good."""
    store = ResultsStore(tmp_path)
    store.add(episode(number=0), steps_of(episode(number=0)))
    partial = (tmp_path / "episodes.csv").read_bytes() + b"careful,pomdp,0,1,1,hu"
    (tmp_path / "episodes.csv").write_bytes(partial)
    (tmp_path / "steps.csv").write_bytes(b"\xff\xfe" + "human_model".encode("utf-16-le"))
    with pytest.raises(ValueError, match=f"^{tmp_path / 'steps.csv'}: not a results CSV"):
        ResultsStore(tmp_path)
    assert (tmp_path / "episodes.csv").read_bytes() == partial


def test_the_experiment_refuses_a_binary_results_file_in_one_line(tmp_path, capsys):
    from ros_hrc.experiment.cli import main
    (tmp_path / "episodes.csv").write_bytes(b"\x00\x01\x02binary\nmore")
    assert main(["--human-models", "tired", "--policies", "no_robot", "--seeds", "0",
                 "--episodes", "1", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err == (f"hrc_experiment: {tmp_path / 'episodes.csv'}: not a results CSV: binary "
                   "data (a NUL byte at byte 0); left as it is\n")
    assert (tmp_path / "episodes.csv").read_bytes() == b"\x00\x01\x02binary\nmore"


def test_a_summary_that_cannot_be_written_leaves_the_previous_one(tmp_path, monkeypatch):
    """Before: the summary was opened for writing in place: a full disk left it cut short."""
    import errno
    from ros_hrc.pomdp import output
    rows = [episode(number=n) for n in range(3)]
    csv_path, md_path = write_summary(summarize(rows), tmp_path / "s.csv", tmp_path / "s.md")
    before = (open(csv_path).read(), open(md_path).read())

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(output.os, "fsync", full)
    with pytest.raises(OSError) as info:
        write_summary(summarize(rows[:1]), csv_path, md_path)
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(csv_path)
    assert (open(csv_path).read(), open(md_path).read()) == before
    assert sorted(os.listdir(tmp_path)) == ["s.csv", "s.md"], "no temporary file left"
