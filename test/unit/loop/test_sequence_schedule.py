"""The sequence's schedule (ros_hrc.tasks.schedule), its settings and the one utility
(ros_hrc.tasks.utility): who plays task k, what is refused and how a task is scored."""
import pytest

from ros_hrc import settings, tasks
from ros_hrc.model_files import model_names
from ros_hrc.settings import SettingError
from ros_hrc.tasks.schedule import (FABRIC_HUMANS, MAX_TASKS, ScheduleError, TaskPlay,
                                     parse_schedule)
from ros_hrc.tasks.utility import TaskOutcome, task_utility

FABRIC_TYPES = model_names(tasks.get("fabric").model_dirs["human"])
SEED_TYPES = model_names(tasks.get("seed").model_dirs["human"])


def played(schedule, count):
    return [schedule.play(k) for k in range(1, count + 1)]


def test_inline_blocks_play_in_order_and_repeat():
    schedule = parse_schedule("tired*2,expert,walker*3", SEED_TYPES, "humanModel")
    assert [p.human_model for p in played(schedule, 8)] == [
        "tired", "tired", "expert", "walker", "walker", "walker", "tired", "tired"]
    assert schedule.length == 6
    assert all(p.true_type == p.human_model and not p.drift_to for p in played(schedule, 6))


def test_an_empty_schedule_is_the_launch_human_every_task():
    schedule = parse_schedule("", SEED_TYPES, "tired")
    assert {p.human_model for p in played(schedule, 5)} == {"tired"}


def test_a_drift_mixes_from_the_first_type_to_the_second_over_its_block():
    schedule = parse_schedule("expert>tired*5", SEED_TYPES, "humanModel")
    plays = played(schedule, 5)
    assert [p.drift for p in plays] == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert {(p.human_model, p.drift_to) for p in plays} == {("expert", "tired")}
    assert plays[1].true_type == "expert>tired@0.25"
    assert [p.nearest_type for p in plays] == ["expert", "expert", "expert", "tired", "tired"]


def test_fabric_names_their_ten_humans_in_their_order_thirty_tasks_each():
    schedule = parse_schedule("fabric", FABRIC_TYPES, "beginner_nontired_collaborative",
                              "fabric")
    assert schedule.length == 300
    assert schedule.play(1).human_model == "beginner_tired_noncollaborative"
    assert schedule.play(30).human_model == "beginner_tired_noncollaborative"
    assert schedule.play(31).human_model == "expert_nontired_noncollaborative"
    assert schedule.play(300).human_model == "expert_tired_noncollaborative"
    assert [schedule.play(30 * i + 1).human_model for i in range(10)] == list(FABRIC_HUMANS)


def test_fabric_on_the_seed_task_is_refused():
    with pytest.raises(ScheduleError, match="use it with task:=fabric"):
        parse_schedule("fabric", SEED_TYPES, "humanModel", "seed")


def test_an_unknown_type_is_named_with_the_known_ones():
    with pytest.raises(ScheduleError) as info:
        parse_schedule("tired*3,sleepy*2", SEED_TYPES, "humanModel")
    assert "unknown human type 'sleepy'; known: beginner, " in str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("text", ["tired*0", "tired*x", "*3", "tired**2", "tired,,expert",
                                  "tired>*2"])
def test_a_malformed_inline_block_is_one_line(text):
    with pytest.raises(ScheduleError) as info:
        parse_schedule(text, SEED_TYPES, "humanModel")
    assert "\n" not in str(info.value)


def test_a_block_count_is_capped_as_tasks_is(tmp_path):
    """``tasks:=`` stops at 2**31 - 1; a block count did not: beginner*99999999999999999999 was
    accepted and played."""
    top = settings.SETTINGS["tasks"].maximum
    assert top == MAX_TASKS == 2**31 - 1
    assert parse_schedule(f"tired*{top}", SEED_TYPES, "humanModel").blocks[0].tasks == top
    for k in (str(top + 1), "99999999999999999999"):
        with pytest.raises(ScheduleError) as info:
            parse_schedule(f"expert,tired*{k}", SEED_TYPES, "humanModel")
        assert str(info.value) == (f"block 2 'tired*{k}': K must be a whole number from 1 to "
                                   f"{top} (the most tasks a sequence has, as tasks:=)")
    path = tmp_path / "long.toml"
    path.write_text(f'[[block]]\nhuman = "expert"\ntasks = {top + 1}\n')
    with pytest.raises(ScheduleError, match=rf"{path}:1: tasks must be a whole number from 1 "
                                            rf"to {top} .*not {top + 1}"):
        parse_schedule(str(path), SEED_TYPES, "humanModel")
    # through the launch's settings: one line naming the argument
    with pytest.raises(SettingError) as info:
        settings.resolve({"tasks": "3", "schedule": "beginner*99999999999999999999"})
    assert str(info.value).startswith("schedule:=beginner*99999999999999999999: block 1 ")
    assert f"from 1 to {top}" in str(info.value) and "\n" not in str(info.value)


def test_a_schedule_file_gives_blocks_with_drift(tmp_path):
    path = tmp_path / "two.toml"
    path.write_text('[[block]]\nhuman = "expert"\ntasks = 2\n\n'
                    '[[block]]\nhuman = "tired"\ntasks = 3\ndrift_to = "walker"\n')
    schedule = parse_schedule(str(path), SEED_TYPES, "humanModel")
    assert [p.true_type for p in played(schedule, 5)] == [
        "expert", "expert", "tired>walker@0.00", "tired>walker@0.50", "tired>walker@1.00"]


def test_a_schedule_file_error_names_the_file_and_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[[block]]\nhuman = "expert"\ntasks = 2\n\n[[block]]\nhuman = "nobody"\n'
                    'tasks = 1\n')
    with pytest.raises(ScheduleError, match=rf"{path}:5: unknown human type 'nobody'"):
        parse_schedule(str(path), SEED_TYPES, "humanModel")
    path.write_text('[[block]]\nhuman = "expert"\ntasks = = 2\n')
    with pytest.raises(ScheduleError, match=rf"{path}: not TOML: .*line 3"):
        parse_schedule(str(path), SEED_TYPES, "humanModel")
    path.write_text('[[block]]\nhuman = "expert"\ntasks = 0\n')
    with pytest.raises(ScheduleError, match=rf"{path}:1: tasks must be a whole number from 1 to"):
        parse_schedule(str(path), SEED_TYPES, "humanModel")
    with pytest.raises(ScheduleError, match="cannot read it"):
        parse_schedule(str(tmp_path / "missing.toml"), SEED_TYPES, "humanModel")


def test_the_sequence_settings_are_checked_together(tmp_path):
    config = settings.resolve({"tasks": "5", "task": "fabric", "selector": "bpr",
                               "schedule": "expert_tired_noncollaborative*3"})
    assert config["tasks"] == 5 and config["task_timeout"] == 80.0
    assert settings.resolve({})["tasks"] == 0      # no sequence
    refusals = {
        "tasks:=0: must be an integer from 1 to 2147483647": {"tasks": "0"},
        "tasks:=-2: must be an integer from 1 to 2147483647": {"tasks": "-2"},
        "selector:=bpr: only with a sequence: a selector chooses between the tasks of a "
        "sequence": {"selector": "bpr"},
        "schedule:=tired*2: only with a sequence": {"schedule": "tired*2"},
        "selector:=ucb: unknown selector (known: fixed, random, bpr": {"selector": "ucb",
                                                                        "tasks": "2"},
        "selector:=bpx: unknown selector; did you mean bpr? (known: fixed, random": {
            "selector": "bpx", "tasks": "2"},
        "schedule:=sleepy*2: unknown human type 'sleepy'; known: ": {"schedule": "sleepy*2",
                                                                     "tasks": "2"},
        "task_timeout:=0: must be a number > 0 and <= 1000000 (s)": {"task_timeout": "0"},
    }
    for line, given in refusals.items():
        with pytest.raises(SettingError) as info:
            settings.resolve(given)
        assert str(info.value).startswith(line), (given, str(info.value))
    assert settings.resolve({"tasks": "2", "selector": "fixed:policy3"})["selector"] == \
        "fixed:policy3"


def test_the_utility_is_one_scale_for_every_policy():
    quick = TaskOutcome("success", "human", warnings=0, preemptions=0, duration=8.0,
                        timeout=80.0)
    assert task_utility(quick) == pytest.approx(1.0 - 0.5 * 0.1)
    assert task_utility(TaskOutcome("success", "robot", 2, 1, 40.0, 80.0)) == \
        pytest.approx(1.0 - 0.25 - 0.2 - 0.5)
    # a timeout costs the whole half, however long past it
    assert task_utility(TaskOutcome("timeout", "", 0, 0, 95.0, 80.0)) == pytest.approx(-0.5)
    assert task_utility(TaskOutcome("fail", "", 1, 0, 69.0, 80.0)) == \
        pytest.approx(-0.5 * 69 / 80 - 0.1)
    with pytest.raises(ValueError):
        TaskOutcome("won", "", 0, 0, 1.0, 80.0)


def test_a_task_play_of_a_file_model_is_labelled_by_its_stem():
    assert TaskPlay("/x/y/tired.pomdpx").true_type == "tired"


def test_the_selector_settings_are_the_registry_s():
    from ros_hrc import registry
    from ros_hrc.agents.learning import LEARNING_SELECTORS
    from ros_hrc.agents.selectors import DEFAULT_FORGETTING

    # fixed, the registry's selectors, then the learning robot's (one robot, its model learnt).
    assert settings.selector_words() == ("fixed",) + registry.names(registry.SELECTORS) + \
        tuple(LEARNING_SELECTORS)
    assert settings.default("bpr_forgetting") == DEFAULT_FORGETTING
