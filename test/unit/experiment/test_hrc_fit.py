"""hrc_fit around the stacks: what it counts from recorded episodes, and what it refuses before
any stack starts. (The fit itself, recovering known tables from synthetic experience, is
test/unit/pomdp/test_fit.py; the stack's episodes are test/rostest's.)"""
import json

import numpy as np
import pytest

from ros_hrc.experiment import fit
from ros_hrc.experiment.rows import EpisodeRow, StepRow
from ros_hrc.models import load_robot_model
from ros_hrc.pomdp.typed import TypeLayout


def episode(number, end_reason="success", succeeded_by="robot", steps=3, human="beginner"):
    success = end_reason == "success"
    return EpisodeRow(human_model=human, robot_policy="explore", seed=0, episode=number,
                      success=int(success), succeeded_by=succeeded_by if success else "none",
                      end_reason=end_reason, steps=steps, sim_seconds=1.0,
                      robot_discounted_reward=0.0, intrusive_actions=0, warnings=0,
                      zero_probability_observations=0, mean_decision_ms=0.1, wall_seconds=1.0)


def step(number, index, state, action, observation, human="beginner"):
    return StepRow(human, "explore", 0, number, index, "idle", "evaluating", state, action,
                   observation, 0.5, int(state in ("S2", "S3", "S4", "S5")), 0)


@pytest.fixture(scope="module")
def robot():
    return load_robot_model("robot")


def idx(model, kind, name):
    return model.index(kind, name)


def test_an_episode_counts_from_the_start_state_and_ends_in_success(robot):
    steps = [step(0, 0, "S0", "rGrasp_obj", "O35"), step(0, 1, "S2", "rIdle", "O35"),
             step(0, 2, "S3", "rGrasp_obj", "O35")]
    counts = fit.count_experience(robot, [episode(0)], reversed(steps))   # any order
    T, O = counts.transitions, counts.observations
    s, a, o = (lambda n: idx(robot, "state", n)), (lambda n: idx(robot, "action", n)), \
        (lambda n: idx(robot, "observation", n))
    # the robot process's first belief update: rIdle from the start state S0
    assert T[a("rIdle"), s("S0"), s("S0")] == 1 and O[a("rIdle"), s("S0"), o("O35")] == 1
    assert T[a("rGrasp_obj"), s("S0"), s("S2")] == 1 and O[a("rGrasp_obj"), s("S2"), o("O35")] == 1
    assert T[a("rIdle"), s("S2"), s("S3")] == 1 and O[a("rIdle"), s("S3"), o("O35")] == 1
    assert T[a("rGrasp_obj"), s("S3"), s("S1")] == 1          # the grasp that ended it
    assert counts.n_transitions == 4 and counts.n_observations_counted == 3


@pytest.mark.parametrize("reason", ["object_left_belt", "step_limit"])
def test_an_episode_that_fails_adds_no_last_transition(robot, reason):
    steps = [step(1, 0, "S0", "rIdle", "O35"), step(1, 1, "S3", "rPoint_obj", "O0")]
    counts = fit.count_experience(robot, [episode(1, reason, steps=2)], steps)
    assert counts.n_transitions == 2 and counts.n_observations_counted == 2
    assert counts.transitions[idx(robot, "action", "rPoint_obj")].sum() == 0


def test_counts_fit_the_prior_and_keep_its_rewards(robot):
    steps = [step(e, 0, "S3", "rGrasp_obj", "O0") for e in range(40)]
    counts = fit.count_experience(robot, [episode(e, steps=1) for e in range(40)], steps)
    fitted = fit.fit_model(robot, counts, strength=5)
    a, s3, s1 = idx(robot, "action", "rGrasp_obj"), idx(robot, "state", "S3"), \
        idx(robot, "state", "S1")
    # 40 grasps from S3, all successful, against the prior's 0.6 with 5 pseudo-counts
    assert fitted.dense_T[a][s3, s1] == pytest.approx((5 * 0.6 + 40) / 45)
    assert all(np.array_equal(f.toarray(), p.toarray()) for f, p in zip(fitted.R, robot.R))


def test_bad_arguments_are_refused_before_any_stack(tmp_path, capsys):
    assert fit.main(["--out", str(tmp_path / "x.pomdpx"), "--runs", str(tmp_path)]) == 2
    assert "Cassandra .pomdp" in capsys.readouterr().err
    assert fit.main(["--prior", "nonesuch", "--runs", str(tmp_path)]) == 2
    assert "--prior: no robot model named 'nonesuch'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        fit.build_parser().parse_args(["--strength", "-1"])
    assert "must be a number >= 0" in capsys.readouterr().err


def test_runs_of_another_configuration_are_refused(tmp_path, capsys):
    (tmp_path / fit.CONFIG_FILE).write_text(json.dumps({"human_models": ["tired"], "seed": 3,
                                                         "step_limit": 15, "policy": "explore"}))
    out = tmp_path / "fitted.pomdp"
    assert fit.main(["--runs", str(tmp_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "holds the episodes of another configuration" in err and not out.exists()


def test_file_arguments_are_made_absolute_for_the_stacks(tmp_path, monkeypatch):
    """Before: a relative --prior or --human-models reached the stack's processes, which run in
    $ROS_HOME, as typed, and each cell waited 600 s."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[3] / "models"
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "prior.pomdp").write_text((root / "robot" / "robot.pomdp").read_text())
    (tmp_path / "mine" / "h.pomdpx").write_text((root / "human" / "tired.pomdpx").read_text())
    monkeypatch.chdir(tmp_path)
    args = fit.build_parser().parse_args(["--prior", "mine/prior.pomdp", "--human-models",
                                          "mine/h.pomdpx,expert", "--runs", "runs", "--out",
                                          "out/fitted.pomdp", "--episodes", str(10**9)])
    (tmp_path / "out").mkdir()
    fit.check_arguments(args)
    assert (args.prior, args.runs, args.out) == (str(tmp_path / "mine" / "prior.pomdp"),
                                                 str(tmp_path / "runs"),
                                                 str(tmp_path / "out" / "fitted.pomdp"))
    cells = fit.plan_cells(args, {("expert", "explore", 0, 3)})
    assert [c.human_model for c in cells] == ["mine/h.pomdpx", "expert"]
    assert cells[0].human_model_file == str(tmp_path / "mine" / "h.pomdpx")
    assert cells[1].episodes.spans == ((0, 3), (4, 10**9))          # planned lazily
    assert all(Path(c.robot_model).is_absolute() and Path(c.log_dir).is_absolute()
               for c in cells)


def test_an_out_that_is_a_fifo_is_refused_before_any_stack(tmp_path, capsys):
    import os
    fifo = tmp_path / "fitted.pomdp"
    os.mkfifo(fifo)
    assert fit.main(["--runs", str(tmp_path / "runs"), "--out", str(fifo)]) == 2
    assert capsys.readouterr().err == (f"hrc_fit: --out {fifo}: is a FIFO, not a regular file; "
                                       "it is never replaced (write to a file)\n")
    assert not (tmp_path / "runs").exists()


def test_a_fabric_episode_that_succeeds_ends_in_fabric_s_success_state():
    """hrc_fit --task fabric: the first step starts from fabric's idle action and a success
    ends in GlobalSuccess (the seed's S1 is no fabric state: it was refused before)."""
    from ros_hrc import tasks
    from ros_hrc.model_files import resolve_model
    from ros_hrc.pomdp.io import load_model
    fabric = tasks.get("fabric")
    model = load_model(str(resolve_model("base", "robot", fabric.model_dirs["robot"])))
    key = dict(human_model="distracted_collaborative", robot_policy="explore", seed=0,
               episode=0)
    row = EpisodeRow(**key, success=1, succeeded_by="robot", end_reason="success", steps=1,
                     sim_seconds=3.0, robot_discounted_reward=0.0, intrusive_actions=0,
                     warnings=0, zero_probability_observations=0, mean_decision_ms=1.0,
                     wall_seconds=1.0)
    step = StepRow(**key, step=0, human_action="idle", human_state="TaskHuman",
                   robot_state="NeedsHelp", robot_action="grasp", observation="O35",
                   belief_needs_help=0.5, needs_help=1, zero_probability=0)
    counts = fit.count_experience(model, [row], [step])
    assert counts.n_transitions == 2     # TaskHuman -idle-> NeedsHelp -grasp-> GlobalSuccess
    assert fit.labels_fingerprint(fabric) != fit.labels_fingerprint(tasks.get("seed"))


# ------------------------------------------------------------------ --types: one model per human

def two_humans_recorded(runs):
    """Two episodes each of beginner and tired in ``runs``, as the stacks would have left
    them: beginner's robot grasps from S3 and succeeds, tired's is where the human walked
    away (S3, O0) and the belt ends the episode."""
    from ros_hrc.experiment.store import ResultsStore
    store = ResultsStore(runs)
    for e in range(2):
        store.add(episode(e, steps=1), [step(e, 0, "S3", "rGrasp_obj", "O7")])
        store.add(episode(e, "object_left_belt", steps=2, human="tired"),
                  [step(e, 0, "S0", "rIdle", "O35", human="tired"),
                   step(e, 1, "S3", "rPoint_obj", "O0", human="tired")])


def test_types_fits_each_human_model_on_its_own_episodes_and_composes_them(robot):
    beginner = [step(e, 0, "S3", "rGrasp_obj", "O7") for e in range(40)]
    tired = [step(e, 0, "S3", "rGrasp_obj", "O0", human="tired") for e in range(40)]
    episodes = [episode(e, steps=1) for e in range(40)] + \
        [episode(e, "step_limit", steps=1, human="tired") for e in range(40)]
    experience = fit.count_types(robot, ["beginner", "tired"], episodes, tired + beginner)
    assert list(experience) == ["beginner", "tired"]
    assert [(e.episodes, e.steps) for e in experience.values()] == [(40, 40), (40, 40)]
    model = fit.fit_types(robot, experience, 5, name="types")
    layout = TypeLayout.of(model)
    assert layout.types == ("beginner", "tired") and list(layout.states) == robot.states
    assert layout.type_marginal(model.initial_belief) == pytest.approx([0.5, 0.5])
    grasp, s3 = idx(robot, "action", "rGrasp_obj"), idx(robot, "state", "S3")
    S, T = robot.n_states, model.dense_T[grasp]
    # beginner's grasps from S3 all succeeded; tired's episodes failed, so his S3 row is the
    # prior's (nothing says where the grasp led)
    assert T[s3, idx(robot, "state", "S1")] == pytest.approx((5 * 0.6 + 40) / 45)
    assert T[S + s3, S:] == pytest.approx(robot.dense_T[grasp][s3])
    # what each type shows in S3 after the robot's first rIdle: its own observations
    O = model.dense_O[idx(robot, "action", "rIdle")]
    o7, o0 = idx(robot, "observation", "O7"), idx(robot, "observation", "O0")
    assert O[s3, o7] > 0.8 > O[S + s3, o7] and O[S + s3, o0] > 0.8
    for name, share in experience.items():     # each type's block is its own fit, alone
        alone = fit.fit_model(robot, share.counts, 5)
        b = layout.types.index(name) * S
        for a in range(robot.n_actions):
            assert model.dense_T[a][b:b + S, b:b + S] == pytest.approx(alone.dense_T[a])
            assert model.dense_O[a][b:b + S] == pytest.approx(alone.dense_O[a])


def test_types_from_recorded_runs_writes_a_model_hrc_experiment_holds_out(tmp_path, capsys):
    """No stack runs: every episode is already in --runs (the pooled fit's, reused)."""
    from ros_hrc.experiment.cli import build_parser as grid_parser, validate_grid
    from ros_hrc.experiment.grid import GridError
    from ros_hrc.experiment.provenance import read_fitted_on
    runs, out = tmp_path / "runs", tmp_path / "types.pomdp"
    two_humans_recorded(runs)
    words = ["--human-models", "beginner,tired", "--episodes", "2", "--runs", str(runs)]
    assert fit.main(words + ["--out", str(tmp_path / "pooled.pomdp")]) == 0
    assert fit.main(["--types", *words, "--out", str(out)]) == 0   # the same runs serve
    printed = capsys.readouterr().out
    assert "0 to run" in printed and "type tired: 4 transitions, 4 observations" in printed
    model = load_robot_model(str(out))
    assert model.n_states == 2 * 7 and model.states[-1] == "S6__tired"
    header = [line for line in out.read_text().splitlines() if line.startswith("#")]
    assert header[0].startswith("# A robot model of 2 human types, fitted to the world by "
                                "hrc_fit --types")
    assert "# types: beginner, tired" in header
    assert "# experience of type beginner: 2 episodes, 2 steps; 4 transitions, " \
           "2 observations" in header
    assert [f.human_model for f in read_fitted_on(out)] == ["beginner", "tired"]
    evaluate = ["--robot-model", str(out), "--human-models", "tired", "--policies", "pomdp",
                "--episodes", "4", "--out", str(tmp_path / "study")]
    with pytest.raises(GridError, match="fitted on human model tired, seed 0, episodes 0-1"):
        validate_grid(grid_parser().parse_args(evaluate + ["--seeds", "0"]))
    validate_grid(grid_parser().parse_args(evaluate + ["--seeds", "1"]))     # held out


def test_types_refuses_human_models_that_name_one_type_twice(tmp_path, capsys):
    from pathlib import Path
    tired = Path(__file__).resolve().parents[3] / "models" / "human" / "tired.pomdpx"
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "tired.pomdpx").write_text(tired.read_text())
    code = fit.main(["--types", "--human-models", f"tired,{tmp_path / 'mine' / 'tired.pomdpx'}",
                     "--runs", str(tmp_path / "runs"), "--out", str(tmp_path / "t.pomdp")])
    assert code == 2
    assert capsys.readouterr().err == (
        f"hrc_fit: --human-models: tired and {tmp_path / 'mine' / 'tired.pomdpx'} are both "
        "type tired (--types names each type by its scenario name or file stem)\n")
    assert not (tmp_path / "runs").exists()


def test_types_writes_into_the_tasks_robot_models_by_default():
    from ros_hrc.model_files import MODELS_DIR
    for words, out, runs in (([], "robot/robot_fitted.pomdp", "results/fit"),
                             (["--types"], "robot/robot_types.pomdp", "results/fit"),
                             (["--types", "--task", "fabric"], "fabric/robot/robot_types.pomdp",
                              "results/fit_fabric")):
        args = fit.build_parser().parse_args(words)
        fit.check_arguments(args)
        assert args.out == str(MODELS_DIR / out), words
        assert args.runs.endswith(runs), words
    # the pooled fit's episodes are --types' too: one configuration
    pooled, types = (fit.build_parser().parse_args(w) for w in ([], ["--types"]))
    for args in (pooled, types):
        fit.check_arguments(args)
    assert fit.configuration(types) == fit.configuration(pooled)


def test_utility_rewards_replace_the_priors_and_keep_t_and_o(robot):
    """--rewards utility: the fitted T and O, the task's utility as rewards, priced at the
    episodes' mean seconds a step."""
    from ros_hrc import tasks
    from ros_hrc.tasks.utility import utility_rewards
    episodes = [episode(0, steps=2), episode(1, steps=6)]       # 1.0 s each: 0.25 s a step
    assert fit.seconds_per_step(episodes) == pytest.approx(0.25)
    seed = tasks.get("seed")
    priced = fit.with_utility_rewards(robot, seed, 0.25)
    assert all(np.array_equal(p.toarray(), r.toarray()) for p, r in zip(priced.T, robot.T))
    assert all(np.array_equal(p.toarray(), r.toarray()) for p, r in zip(priced.O, robot.O))
    assert np.allclose(np.array([r.toarray() for r in priced.R]),
                       np.array(utility_rewards(seed, 0.25)))


def test_utility_rewards_are_refused_for_a_model_of_types(tmp_path, capsys):
    assert fit.main(["--types", "--rewards", "utility", "--runs", str(tmp_path),
                     "--out", str(tmp_path / "t.pomdp")]) == 2
    assert "--rewards utility: a model of human types keeps the prior's rewards" in \
        capsys.readouterr().err
