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
