"""What the robot's planner does after typical observation sequences (``hrc_pomdp policy``).

The considerate model's sane cases are pinned (a warning stops the robot; repeated failed
grasps get the object fetched; a human who holds the object is left alone; a human who idles
is not taken from). The authors' model's table is recorded as it is, not as sane: it cannot
believe a warning that follows its own rIdle (its T has no way into S6 but its own grasp or
point), so it idles on a first warning, grasps on a human who only idles, and stops on a human
who is away. The search is bounded by trials, so the tables are the same on any machine."""
import json
from pathlib import Path

import pytest

from ros_hrc.models import load_robot_model
from ros_hrc.commands import pomdp as cli
from ros_hrc.agents.policy_table import (SEQUENCES, ObservationSequence, despot_config,
                                        format_table, policy_table)

ROOT = Path(__file__).resolve().parents[3]
ACTING = {"rGrasp_obj", "rPoint_obj"}


@pytest.fixture(scope="module")
def considerate():
    return {row.sequence.name: row for row in policy_table(load_robot_model("robot_considerate"))}


@pytest.fixture(scope="module")
def authors():
    return {row.sequence.name: row for row in policy_table(load_robot_model("robot"))}


@pytest.mark.parametrize("name", ["warning", "warning_unseen", "failed_then_warning"])
def test_a_warning_stops_the_considerate_robot(considerate, name):
    row = considerate[name]
    assert row.last_action in ("rStop_all", "rIdle")
    assert row.warned > 0.9 and not row.zero_probability


def test_the_considerate_robot_fetches_for_a_human_who_keeps_failing(considerate):
    row = considerate["failed_grasps"]
    assert "rGrasp_obj" in row.actions
    assert row.needs_help > 0.9
    assert row.actions[0] == "rIdle"          # one failure is not yet a need


def test_the_considerate_robot_leaves_a_human_who_holds_the_object_alone(considerate):
    assert considerate["holds_object"].last_action == "rIdle"
    assert considerate["holds_object"].needs_help == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("name", ["idle_once", "idle_streak"])
def test_the_considerate_robot_does_not_take_from_a_human_who_idles(considerate, name):
    assert not ACTING & set(considerate[name].actions)


def test_the_considerate_robot_never_calls_a_typical_observation_impossible(considerate):
    assert not [name for name, row in considerate.items() if row.zero_probability]


def test_the_authors_robot_as_it_is_recorded_not_endorsed(authors):
    """The authors' model (robot.pomdp), recorded: a warning after rIdle has probability 0 for
    it, so it idles on it with its belief elsewhere; it grasps from a human who only idles
    (S0, the +60 of rGrasp_obj in S3 pays for the chance); it answers a human who is away or
    looking away with rStop_all; after failed grasps and a warning it does stop."""
    assert authors["warning"].actions == ["rIdle"] and authors["warning"].zero_probability == ["O19"]
    assert authors["warning"].warned == 0.0
    assert "rGrasp_obj" in authors["idle_streak"].actions
    assert authors["human_away"].actions == ["rStop_all"] * 3
    assert authors["looks_away"].actions == ["rStop_all"] * 3
    assert authors["failed_then_warning"].last_action == "rStop_all"
    assert authors["holds_object"].last_action == "rIdle"


def test_the_table_is_the_same_at_four_times_the_trials():
    """The trials bound is large enough for the decisions to settle (so the table is what the
    planner does, not noise)."""
    model = load_robot_model("robot_considerate")
    few = [row.actions for row in policy_table(model)]
    many = [row.actions for row in policy_table(model, config=despot_config(1200))]
    assert few == many


def test_the_table_is_reproducible():
    model = load_robot_model("robot_considerate")
    assert format_table(policy_table(model)) == format_table(policy_table(model))


def test_a_sequence_of_an_unknown_observation_is_refused():
    model = load_robot_model("robot_considerate")
    with pytest.raises(ValueError, match="O4 is not one of the model's"):
        policy_table(model, [ObservationSequence("bad", ("O4",), "not an observation")])


def test_every_typical_sequence_is_named_once_and_uses_the_models_observations():
    model = load_robot_model("robot")
    names = [s.name for s in SEQUENCES]
    assert len(names) == len(set(names)) >= 8
    assert {o for s in SEQUENCES for o in s.observations} <= set(model.observations)


def test_hrc_pomdp_policy_prints_the_table(capsys):
    assert cli.run(["policy", "robot_considerate", "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    rows = {row["name"]: row for row in facts["rows"]}
    assert rows["warning"]["last_action"] == "rStop_all"
    assert facts["trials"] == 300 and facts["seed"] == 0
    assert cli.run(["policy", "robot_considerate"]) == 0
    assert "| warning | O19 | rStop_all |" in capsys.readouterr().out


def test_hrc_pomdp_policy_refuses_a_model_that_is_not_the_robots(capsys):
    human = str(ROOT / "models" / "human" / "expert.pomdpx")
    assert cli.run(["policy", human]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hrc_pomdp: ") and "not the task's states" in err
    assert len(err.splitlines()) == 1
    assert cli.run(["policy", "expert"]) == 2          # a name looks in models/robot/
    assert "no robot model named 'expert'" in capsys.readouterr().err


@pytest.fixture(scope="module")
def considerate_fitted():
    return {row.sequence.name: row
            for row in policy_table(load_robot_model("robot_considerate_fitted"))}


@pytest.mark.parametrize("name", ["warning", "warning_unseen", "failed_then_warning"])
def test_a_warning_stops_the_shipped_considerate_robot(considerate_fitted, name):
    """The model the study's pomdp_considerate runs (fitted on the zoo's fit set): after a
    warning it stops, whatever came before."""
    assert considerate_fitted[name].last_action == "rStop_all"


def test_the_shipped_considerate_robot_lets_a_human_who_keeps_trying_try(considerate_fitted):
    """A human who keeps attempting may still succeed himself (his success is worth 20 to
    this model, the robot's 6): the robot does not take over after failed grasps alone."""
    assert not ACTING & set(considerate_fitted["failed_grasps"].actions)


def test_the_shipped_considerate_robot_leaves_a_human_who_holds_the_object_alone(
        considerate_fitted):
    assert considerate_fitted["holds_object"].last_action == "rIdle"


def test_hrc_pomdp_policy_runs_the_users_own_sequences_and_shows_the_belief(capsys):
    """What a researcher asks of a model: what does it do after *this* history, and what
    does it then believe? Given sequences replace the typical ones."""
    assert cli.run(["policy", "robot_considerate_fitted", "--belief",
                    "--sequence", "two_failures=O7,O7", "--sequence", "warned=O19"]) == 0
    out = capsys.readouterr().out
    table = [line for line in out.splitlines() if line.startswith("| ")]
    assert table[0].endswith("| belief after the last |")
    assert [line.split(" | ")[0] for line in table[1:]] == ["| two_failures", "| warned"]
    assert cli.run(["policy", "robot_considerate_fitted", "--json",
                    "--sequence", "two_failures=O7 O7"]) == 0
    row, = json.loads(capsys.readouterr().out)["rows"]
    assert row["observations"] == ["O7", "O7"] and len(row["actions"]) == 2
    assert sum(row["belief"].values()) == pytest.approx(1.0)
    assert row["needs_help"] == pytest.approx(sum(row["belief"][s] for s in
                                                  ("S2", "S3", "S4", "S5")))


@pytest.mark.parametrize("words, what", [
    (["--sequence", "no_observations="], "expected NAME=OBS"),
    (["--sequence", "O7,O7"], "expected NAME=OBS"),
    (["--sequence", "typo=O7,O99"], "observation O99 is not one of the model's"),
])
def test_a_bad_sequence_of_ones_own_is_one_line_and_exit_2(capsys, words, what):
    assert cli.run(["policy", "robot_considerate_fitted"] + words) == 2
    err = capsys.readouterr().err
    assert what in err
    assert err.strip().splitlines()[-1].startswith("hrc_pomdp policy")


def test_a_warning_resets_the_shipped_considerate_robots_count_of_failures(capsys):
    """Recorded, not endorsed (README, "The study": why it loses on the persistent failer).
    Eight failed grasps in a row and the robot believes the human failed more than once (S3)
    and fetches; a warning between them sends its belief back towards a first failure (S2),
    after which fit-set humans mostly succeed alone, so it waits. Its seven states have no
    count of failures, and the fit set's only warner restarts fresh after warning."""
    rows = {row.sequence.name: row for row in policy_table(
        load_robot_model("robot_considerate_fitted"),
        [ObservationSequence("failed_grasps", ("O7",) * 8, ""),
         ObservationSequence("fails_warns_twice",
                             ("O7", "O7", "O19", "O7", "O7", "O19", "O7", "O7", "O7"), "")],
        config=despot_config(500))}
    assert "rGrasp_obj" in rows["failed_grasps"].actions
    assert rows["failed_grasps"].belief["S3"] > 0.8
    assert not ACTING & set(rows["fails_warns_twice"].actions)
    assert rows["fails_warns_twice"].belief["S2"] > 0.3
