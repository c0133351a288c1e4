"""The solver processes in a sequence of tasks (issue #30), without a network: the robot
process chooses a library policy on each reset that starts a task, records the task's
signature and answers task_end with task_report; the human process plays the human model the
reset names, drifting by mixing two models' rows. selector:=fixed stays today's one robot."""
import io

import numpy as np
import pytest

from ros_hrc import tasks
from ros_hrc.agents.human import HumanAgent
from ros_hrc.agents.selector_model import TrainingTask, from_tasks, write_selector_model
from ros_hrc.agents.selectors import signature_code
from ros_hrc.link.protocol import (Error, Observation, Reset, TaskEnd, TaskReport)
from ros_hrc.models import load_human_model, load_robot_model
from ros_hrc.processes import despot_mdp, despot_pomdp
from ros_hrc.processes.selection import SelectionError, load_selection

FABRIC = tasks.get("fabric")
TYPES = ("expert_tired_noncollaborative", "beginner_nontired_collaborative")


def robot_process(*words):
    args = despot_pomdp.build_parser().parse_args(
        ["--task", "fabric", "--model", "base", "--time-per-step", "0", "--max-trials", "20",
         *words])
    model = load_robot_model(args.robot_model, FABRIC)
    sequence = despot_pomdp.build_sequence_robot(FABRIC, model,
                                                 despot_pomdp.build_planner(model, args), args)
    return despot_pomdp.PomdpProcess(next(iter(sequence.agents.values())), sequence)


def fixture_selector_model(path, policies):
    """A selector model of hand-chosen numbers (a fixture, not a trained model): under the
    first type policy3 is best, under the second base; the first type shows code 16 (a
    warning), the second code 1."""
    rows = []
    for t, name in enumerate(TYPES):
        for policy in policies:
            good = (policy == "policy3") if t == 0 else (policy == "base")
            rows.append(TrainingTask(name, policy, 0.9 if good else 0.1,
                                     (16, 16, 16) if t == 0 else (1, 1, 1)))
    write_selector_model(from_tasks(rows, task="fabric", policies=policies, types=TYPES,
                                    header={"how": "a unit test's fixture: hand-chosen numbers",
                                            "from": "nothing run", "seeds": [],
                                            "command": "", "date": ""}), path)
    return path


def observe(process, epoch, step, bits=17):
    model = process.agent.model
    return process.on_observation(Observation(step=step, observation=model.observations[0],
                                              bits=bits, state=model.states[0], epoch=epoch),
                                  None)


def end(process, index, epoch, utility=0.5):
    return process.on_task_end(TaskEnd(task_index=index, outcome="success", warnings=0,
                                       preemptions=0, steps=2, duration=9.0, utility=utility,
                                       epoch=epoch, id=index), None)


def test_a_library_selector_chooses_a_policy_per_task_and_reports_it(capsys):
    process = robot_process("--selector", "random")
    names = process.sequence.selection.library.names()
    assert set(process.sequence.agents) == set(names)
    out = capsys.readouterr().out
    assert all(f"despot_pomdp: policy {name}: planner " in out for name in names)
    chosen = []
    for index in (1, 2, 3):
        process.on_reset(Reset(episode=index, task_index=index, true_type=TYPES[0],
                               epoch=10 + index), None)
        policy = process.sequence.record.policy
        assert process.agent is process.sequence.agents[policy]
        observe(process, 10 + index, 0)
        observe(process, 10 + index, 1, bits=3)
        report = end(process, index, 10 + index)
        assert isinstance(report, TaskReport) and report.reply_to == index
        assert (report.selector, report.policy) == ("random", policy)
        assert report.robot_model.endswith(f"{policy}.pomdpx") or policy == "reactive"
        assert report.signature == (signature_code(17, FABRIC), signature_code(3, FABRIC))
        assert report.type_names is None and report.type_belief is None
        chosen.append(policy)
    assert "##### TASK 3: selector random chose policy " in capsys.readouterr().out


def test_a_task_played_again_keeps_its_policy_and_starts_its_record_afresh():
    process = robot_process("--selector", "random")
    process.on_reset(Reset(episode=1, task_index=1, epoch=1), None)
    policy = process.sequence.record.policy
    observe(process, 1, 0)
    for episode in (2, 3, 4):   # cut short: the same task again
        process.on_reset(Reset(episode=episode, task_index=1, epoch=1 + episode), None)
        assert process.sequence.record.policy == policy
    assert process.sequence.record.signature == []


def test_a_reset_into_task_1_after_a_sequence_ended_starts_a_new_sequence_with_a_fresh_selector():
    """One launch plays many sequences (an experiment cell's): after the last task of a
    one-task sequence, task 1 again is a new sequence's, not the same task played again."""
    process = robot_process("--selector", "random", "--seed", "3")
    chosen = []
    for sequence in range(8):
        process.on_reset(Reset(episode=sequence, task_index=1, epoch=sequence + 1), None)
        selector = process.sequence.selector
        chosen.append(process.sequence.record.policy)
        end(process, 1, sequence + 1)
        assert process.sequence.record.ended
        if sequence:
            assert selector is not previous     # a fresh selector for each sequence
        previous = selector
    # Each sequence draws on its own stream: the choices are not one policy kept eight times.
    assert len(set(chosen)) > 1, chosen


def test_the_same_seed_chooses_the_same_policies():
    def choices():
        process = robot_process("--selector", "random", "--seed", "7")
        picked = []
        for index in range(1, 6):
            process.on_reset(Reset(episode=index, task_index=index, epoch=index), None)
            picked.append(process.sequence.record.policy)
            end(process, index, index)
        return picked
    assert choices() == choices()


def test_bpr_learns_the_type_from_the_signatures_and_reports_its_belief(tmp_path):
    policies = load_selection("random", "auto", "auto", FABRIC).library.names()
    path = fixture_selector_model(tmp_path / "model.json", policies)
    process = robot_process("--selector", "bpr", "--selector-model", str(path),
                            "--bpr-forgetting", "0")
    warning = next(bits for bits in range(FABRIC.observations.max_bits + 1)
                   if signature_code(bits, FABRIC) == 16)
    for index in (1, 2):
        process.on_reset(Reset(episode=index, task_index=index, epoch=index), None)
        for step in range(3):
            observe(process, index, step, bits=warning)
        report = end(process, index, index, utility=0.9)
    assert report.type_names == TYPES
    assert report.type_belief[0] > 0.99
    process.on_reset(Reset(episode=3, task_index=3, epoch=3), None)
    assert process.sequence.record.policy == "policy3"   # the first type's best


def test_selector_fixed_is_the_one_robot_and_still_reports_a_task():
    process = robot_process("--model", "policy3")
    assert list(process.sequence.agents) == ["policy3"]
    process.on_reset(Reset(episode=1, task_index=1, epoch=1), None)
    observe(process, 1, 0)
    report = end(process, 1, 1)
    assert (report.selector, report.policy) == ("fixed", "policy3")
    assert report.type_names is None
    # without a sequence, resets are as before and a task_end is refused
    plain = robot_process()
    plain.on_reset(Reset(episode=1, epoch=1), None)
    assert plain.sequence.record is None
    assert isinstance(end(plain, 1, 1), Error)


def test_a_selector_that_needs_a_model_in_a_library_without_one_names_make_train_selector(
        library_without_model):
    with pytest.raises(SelectionError) as info:
        load_selection("bpr", str(library_without_model), "auto", FABRIC)
    assert str(info.value).startswith(
        f"selector:=bpr needs a selector model, and the library has none (looked for "
        f"{library_without_model.parent}/selector_model.json): `make train-selector` writes it")


def test_the_shipped_selector_models_fit_their_libraries():
    for task in (FABRIC, tasks.get("seed")):
        for selector in ("bpr", "bpr-pi", "bpr-fabric", "oracle"):
            load_selection(selector, "auto", "auto", task)     # no refusal


@pytest.mark.parametrize("words, line", [
    (("fixed:policy99", "auto", "auto"), "selector:=fixed:policy99: no policy 'policy99' in "
                                         "the library models/fabric/library.toml"),
    (("random", "/nowhere/library.toml", "auto"), "library:=/nowhere/library.toml: "),
    (("random", "auto", "/nowhere/model.json"), "selector_model:=/nowhere/model.json: "),
])
def test_each_refusal_of_the_selection_is_one_line_naming_the_argument(words, line):
    with pytest.raises(SelectionError) as info:
        load_selection(*words, FABRIC)
    assert str(info.value).startswith(line) and "\n" not in str(info.value)


def test_a_selector_model_of_another_library_is_refused(tmp_path):
    path = fixture_selector_model(tmp_path / "model.json", ("base", "policy3"))
    with pytest.raises(SelectionError, match="selector_model:=.*trained on the policies base, "
                                             "policy3; the library's are base, policy1"):
        load_selection("bpr", "auto", str(path), FABRIC)


# -- the human ------------------------------------------------------------------------------

def test_a_drifting_human_mixes_the_two_models_rows():
    first = load_human_model(TYPES[0], FABRIC)
    second = load_human_model(TYPES[1], FABRIC)
    agent = HumanAgent(first, reaction=FABRIC.reaction)
    agent.play(first, second, 0.25)
    assert np.allclose(agent._dense_T, 0.75 * first.dense_T + 0.25 * second.dense_T)
    agent.play(second)
    assert agent.model is second and np.allclose(agent._dense_T, second.dense_T)
    with pytest.raises(ValueError):
        agent.play(first, second, 1.5)


def test_the_mdp_process_plays_the_human_each_reset_names():
    args = despot_mdp.build_parser().parse_args(["--task", "fabric", "--model", TYPES[1]])
    model = load_human_model(args.human_model, FABRIC)
    agent = HumanAgent(model, reaction=FABRIC.reaction)
    out = io.StringIO()
    process = despot_mdp.MdpProcess(agent, client=None, args=args, out=out)
    process.start_episode(Reset(episode=1, task_index=1, human_model=TYPES[0], epoch=1))
    assert agent.model.source.endswith(f"{TYPES[0]}.pomdpx")
    loaded = process.models[TYPES[0]]
    process.start_episode(Reset(episode=2, task_index=2, human_model=TYPES[0],
                                drift_to=TYPES[1], drift=0.5, epoch=2))
    assert process.models[TYPES[0]] is loaded      # loaded once
    assert np.allclose(agent._dense_T, 0.5 * loaded.dense_T
                       + 0.5 * process.models[TYPES[1]].dense_T)
    assert f"task 2: human {TYPES[0]} drifting to {TYPES[1]} (0.50)" in out.getvalue()
    # a reset without a human model keeps the one played
    process.start_episode(Reset(episode=3, epoch=3))
    assert agent.model is loaded
