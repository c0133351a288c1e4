"""The robot process with a robot model of human types (issue #31; ros_hrc.pomdp.typed): its
decisions carry the belief over the task's states (the types summed out) and the belief over
the types; in a sequence the type belief at a task's end, mixed with uniform by the
forgetting, is the next task's prior; /hrc/status carries the type belief. No network: the
handlers are called as the server would."""
import numpy as np
import pytest
import rospy

from ros_hrc import tasks
from ros_hrc.agents.selectors import mix_with_uniform
from ros_hrc.link.protocol import Decision, Observation, Reset, TaskEnd, TaskReport
from ros_hrc.loop.effects import DECISION_IN_REPORT, Decision as LoopDecision, StepReport
from ros_hrc.models import load_robot_model
from ros_hrc.nodes.human_node import status_message
from ros_hrc.pomdp.typed import TypeLayout, compose
from ros_hrc.processes import despot_pomdp

SEED = tasks.get("seed")
TYPES = ("considerate", "plain")
#: Observations a seed human gives, each possible after the robot's idle start.
OBSERVATIONS = ("O35", "O3", "O7", "O33", "O1")


def typed_model(prior=None):
    """The seed task's robot model of two types: a human fitted as considerate, and one
    fitted as the plain seed human."""
    return compose({TYPES[0]: load_robot_model("robot_considerate_fitted", SEED),
                    TYPES[1]: load_robot_model("robot_fitted", SEED)}, prior)


def robot_process(model, forgetting=0.2):
    """The launch's one robot (selector:=fixed) planning on ``model``."""
    args = despot_pomdp.build_parser().parse_args(
        ["--time-per-step", "0", "--max-trials", "5", "--bpr-forgetting", str(forgetting)])
    sequence = despot_pomdp.build_sequence_robot(SEED, model,
                                                 despot_pomdp.build_planner(model, args), args)
    return despot_pomdp.PomdpProcess(next(iter(sequence.agents.values())), sequence)


def observe(process, epoch, step, observation="O35", state="S0"):
    return process.on_observation(Observation(step=step, observation=observation,
                                              bits=int(observation[1:]), state=state,
                                              epoch=epoch), None)


def play(process, index, epoch, steps=len(OBSERVATIONS)):
    """Task ``index`` from its reset, ``steps`` observations long, not ended."""
    process.on_reset(Reset(episode=epoch, task_index=index, epoch=epoch), None)
    for step, observation in enumerate(OBSERVATIONS[:steps]):
        observe(process, epoch, step, observation)


def end(process, index, epoch):
    return process.on_task_end(TaskEnd(task_index=index, outcome="success", warnings=0,
                                       preemptions=0, steps=2, duration=9.0, utility=0.5,
                                       epoch=epoch, id=index), None)


def start_type_marginal(process):
    """P(type) of the belief the task under way started from."""
    return process.agent.layout.type_marginal(process.agent.belief)


def test_a_decision_carries_the_task_states_belief_and_the_type_belief(capsys):
    model = typed_model()
    process = robot_process(model)
    process.on_reset(Reset(episode=1, epoch=1), None)
    decision = observe(process, 1, 0)
    assert isinstance(decision, Decision)
    layout = TypeLayout.of(model)
    assert decision.belief_states == tuple(SEED.robot_states)
    assert sum(decision.belief) == pytest.approx(1.0)
    assert decision.belief == pytest.approx(layout.state_marginal(process.agent.belief))
    assert decision.type_names == TYPES
    assert sum(decision.type_belief) == pytest.approx(1.0)
    assert decision.type_belief == pytest.approx(layout.type_marginal(process.agent.belief))
    first, second = sorted(zip(TYPES, decision.type_belief), key=lambda item: -item[1])
    assert (f"- Type belief: {first[0]} {first[1]:.2f}, {second[0]} {second[1]:.2f}"
            in capsys.readouterr().out)


def test_a_robot_of_no_types_sends_no_type_belief():
    process = robot_process(load_robot_model("robot_fitted", SEED))
    process.on_reset(Reset(episode=1, epoch=1), None)
    decision = observe(process, 1, 0)
    assert decision.type_names is None and decision.type_belief is None
    assert decision.belief_states == tuple(SEED.robot_states)


def test_the_type_belief_at_a_task_s_end_is_the_next_task_s_prior_with_the_forgetting():
    # By hand: the model's prior 0.9/0.1, task 1 ends before a step, forgetting 0.2:
    # task 2 starts from 0.8 * (0.9, 0.1) + 0.2 / 2 = (0.82, 0.18).
    model = typed_model([0.9, 0.1])
    process = robot_process(model, forgetting=0.2)
    play(process, 1, epoch=1, steps=0)
    assert start_type_marginal(process) == pytest.approx([0.9, 0.1])
    report = end(process, 1, 1)
    assert report.type_belief == pytest.approx([0.9, 0.1])
    play(process, 2, epoch=2, steps=0)
    assert start_type_marginal(process) == pytest.approx([0.82, 0.18])
    # Each type's own start is kept: the state belief given a type is the model's.
    layout = TypeLayout.of(model)
    given = layout.blocks(process.agent.belief) / np.array([[0.82], [0.18]])
    assert given == pytest.approx(layout.blocks(model.initial_belief) / np.array([[0.9], [0.1]]))
    # After steps, the same rule: the next start is the end's belief mixed with uniform.
    for step, observation in enumerate(OBSERVATIONS):
        observe(process, 2, step, observation)
    at_end = end(process, 2, 2).type_belief
    assert not np.allclose(at_end, [0.82, 0.18])     # the steps moved it
    play(process, 3, epoch=3, steps=0)
    assert start_type_marginal(process) == pytest.approx(mix_with_uniform(np.array(at_end), 0.2))


def test_a_task_played_again_restarts_from_its_own_prior_and_task_1_from_the_model_s():
    model = typed_model([0.9, 0.1])
    process = robot_process(model, forgetting=0.5)
    play(process, 1, epoch=1, steps=0)
    end(process, 1, 1)
    play(process, 2, epoch=2)                      # cut short ...
    moved = start_type_marginal(process)
    play(process, 2, epoch=3, steps=0)             # ... and played again
    assert start_type_marginal(process) == pytest.approx([0.7, 0.3])
    assert not np.allclose(moved, [0.7, 0.3])      # not from where it was cut
    end(process, 2, 3)
    play(process, 1, epoch=4, steps=0)             # a new sequence
    assert process.agent.belief == pytest.approx(model.initial_belief)
    process.on_reset(Reset(episode=5, epoch=5), None)   # outside a sequence
    assert process.agent.belief == pytest.approx(model.initial_belief)


def test_selector_fixed_reports_the_model_s_type_belief_at_the_task_s_end():
    process = robot_process(typed_model())
    play(process, 1, epoch=1)
    at_end = process.agent.type_belief
    report = end(process, 1, 1)
    assert isinstance(report, TaskReport) and report.selector == "fixed"
    assert report.type_names == TYPES
    assert report.type_belief == pytest.approx(at_end)


def test_the_task_s_reward_is_the_one_expected_under_the_type_belief():
    model = typed_model([0.9, 0.1])
    process = robot_process(model)
    play(process, 1, epoch=1, steps=0)
    decision = observe(process, 1, 0, "O35", state="S3")
    action = model.actions.index(decision.action)
    expected = sum(p * model.R_sa[action, model.states.index(f"S3__{t}")]
                   for t, p in zip(TYPES, decision.type_belief))
    assert process.sequence.record.reward == pytest.approx(expected)


def test_a_status_built_from_such_a_step_carries_the_type_belief(monkeypatch):
    monkeypatch.setattr(rospy.Time, "now", staticmethod(lambda: rospy.Time(1)))
    process = robot_process(typed_model())
    process.on_reset(Reset(episode=1, epoch=1), None)
    decision = LoopDecision.of(observe(process, 1, 0))
    report = StepReport(epoch=1, episode=1, step=0, human_action="idle", human_state="idle")
    for name, reported_as in DECISION_IN_REPORT.items():   # as the coordinator copies it
        setattr(report, reported_as, getattr(decision, name))
    status = status_message(report, "auto")
    assert list(status.type_names) == list(TYPES)
    assert list(status.type_belief) == pytest.approx(list(decision.type_belief))
    assert list(status.belief_states) == list(SEED.robot_states)
    plain = status_message(StepReport(epoch=1, episode=1, step=0, human_action="idle",
                                      human_state="idle"), "auto")
    assert list(plain.type_names) == [] and list(plain.type_belief) == []
