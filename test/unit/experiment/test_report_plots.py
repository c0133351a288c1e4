"""hrc_experiment's report with plots that have nothing to show, and the plots' colours."""
from ros_hrc.experiment.cli import report
from ros_hrc.experiment.plots import NothingToPlot, _policy_colours, plot_time_gain
from ros_hrc.experiment.rows import EpisodeRow, StepRow
from ros_hrc.experiment.store import ResultsStore


def alone_episode(number: int) -> EpisodeRow:
    return EpisodeRow(human_model="tired", robot_policy="no_robot", seed=0, episode=number,
                      success=1, succeeded_by="human", end_reason="success", steps=3,
                      sim_seconds=6.5, robot_discounted_reward=0.0, intrusive_actions=0,
                      warnings=0, zero_probability_observations=0, mean_decision_ms=0.0,
                      wall_seconds=1.0)


def test_a_grid_of_the_human_alone_leaves_the_time_plot_out_with_a_line(tmp_path, capsys):
    # `hrc_experiment --policies no_robot` once ended in a traceback here, after writing
    # its results (plot_time_gain: no robot episodes, nothing to plot), and exited 1.
    store = ResultsStore(tmp_path)
    for number in range(2):
        row = alone_episode(number)
        store.add(row, [StepRow(row.human_model, row.robot_policy, row.seed, row.episode, 0,
                                "idle", "evaluating", "S0", "rIdle", "O3", 0.0, 0, 0)])
    report(store, tmp_path, plots=True)
    out = capsys.readouterr().out
    assert "hrc_experiment: time_gain.png left out: no robot episodes, nothing to plot" in out
    assert not (tmp_path / "time_gain.png").exists()
    for written in ("outcomes.png", "success.png", "belief.png", "summary.md"):
        assert (tmp_path / written).exists() and written in out


def test_nothing_to_plot_is_still_a_value_error():
    try:
        plot_time_gain([alone_episode(0)], "unused.png")
    except NothingToPlot as why:
        assert isinstance(why, ValueError)
    else:
        raise AssertionError("plot_time_gain drew a plot without a robot")


def test_every_policy_of_the_study_has_a_colour_of_its_own():
    # The study compares 14 policies (reactive@1..10, three POMDP robots, the human alone);
    # a ten-colour map gave two robots one colour.
    study = [f"reactive@{n}" for n in range(1, 11)] + ["pomdp", "pomdp_fitted",
                                                       "pomdp_considerate", "no_robot"]
    for policies in (study[:3], study, [f"p{i}" for i in range(25)]):
        colours = _policy_colours(policies)
        assert len(set(colours.values())) == len(policies)


def test_the_terminal_gets_the_headline_and_the_list_of_every_file_written(tmp_path, capsys):
    """Issue #41: the whole 150-line, 200-column summary went to the terminal, and run.json
    (written before the report) was in no list of what was written."""
    store = ResultsStore(tmp_path)
    for number in range(2):
        row = alone_episode(number)
        store.add(row, [StepRow(row.human_model, row.robot_policy, row.seed, row.episode, 0,
                                "idle", "evaluating", "S0", "rIdle", "O3", 0.0, 0, 0)])
    (tmp_path / "run.json").write_text("{}\n")     # as finish_run writes it first
    (tmp_path / "logs").mkdir()
    report(store, tmp_path, plots=True, written_before=[tmp_path / "run.json"])
    out = capsys.readouterr().out
    assert "## Paired comparisons" not in out and "Zero-probability" not in out
    assert max(len(line) for line in out.splitlines() if not line.startswith(
        "hrc_experiment:")) <= 100
    assert f"the whole summary (paired tests, best reactive budget, other measures): " \
           f"{tmp_path / 'summary.md'}" in out
    listed = [line for line in out.splitlines() if line.startswith("hrc_experiment: written")]
    assert listed == [f"hrc_experiment: written in {tmp_path}: episodes.csv, steps.csv, "
                      "run.json, summary.csv, summary.md, outcomes.png, success.png, "
                      "belief.png, logs/ (each stack's log)"]


def test_counts_of_one_are_singular():
    """Issue #41: "x 1 seeds", "in 1 steps"."""
    from dataclasses import replace

    from ros_hrc.command_line import counted

    assert alone_episode(0).progress_text() == "tired/no_robot seed 0: success in 3 steps"
    assert replace(alone_episode(0), steps=1).progress_text().endswith("success in 1 step")
    assert (counted(1, "seed"), counted(2, "seed")) == ("1 seed", "2 seeds")
    assert counted(2, "robot policy", "robot policies") == "2 robot policies"
