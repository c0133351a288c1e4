"""The step part of the coordinator (loop/step.py) alone: one step's pipeline, observe ->
decide -> act, its report, its refusals, its faults and its waits, driven with its own outbox
and no coordinator."""
import pytest

from ros_hrc import tasks
from ros_hrc.loop.config import CoordinatorConfig
from ros_hrc.loop.effects import (ActHuman, ActRobot, Decide, Decision, Fault, MdpRefused,
                                  MdpStepDone, Note, ObserveWorld, PublishStep,
                                  ReactionRequest, StepRequest, Timer)
from ros_hrc.loop.outbox import Outbox
from ros_hrc.loop.step import StepActed, StepComplete, StepFailed, StepPipeline
from loop_fakes import OK, calls, of, one, snap

EPOCH = 7


def pipeline(**config):
    outbox = Outbox()
    step = StepPipeline(CoordinatorConfig(**config), outbox)
    step.episode_started(1)
    return step, outbox


def request(step=0, action="lookAround", state="evaluating"):
    return StepRequest(epoch=EPOCH, step=step, action=action, state=state, reply="r")


def answer(step, outbox, result):
    """Answer the one call the step has out: what the pipeline said, and the effects."""
    (call,) = [c for c in outbox.outstanding.values() if c.step is not None]
    outbox.answered(call.id)
    return step.call_done(call, result), outbox.take()


def test_a_step_goes_human_observe_decide_robot_outcome_and_then_answers_the_mdp():
    step, outbox = pipeline()
    assert step.start("mdp", request(), episode=1, start_time=1.5) is None
    made = [calls(outbox.take())[0]]
    for result in (OK, snap("is_ov"), Decision("rPoint_obj"), OK):
        said, effects = answer(step, outbox, result)
        assert said is None
        made.append(calls(effects)[0])
    said, effects = answer(step, outbox, snap("is_ov", sim_time=3.0))
    assert [type(c) for c in made] == [ActHuman, ObserveWorld, Decide, ActRobot, ObserveWorld]
    assert made[0].service == "look_around" and made[3].action == "rPoint_obj"
    assert [c.purpose for c in made if isinstance(c, ObserveWorld)] == ["observe", "outcome"]
    assert all(c.epoch == EPOCH and c.step == 0 for c in made)
    assert made[2].elapsed == 0.0     # the observation's time since the episode's start
    assert isinstance(said, StepActed) and said.report.sim_time == 3.0
    assert not effects          # the episode's say comes first: nothing published yet
    report = step.finish("", stops=False, played_out=False)
    effects = outbox.take()
    assert report is said.report and one(effects, PublishStep).report is report
    done = one(effects, MdpStepDone)
    assert (done.robot_action, done.episode_over, done.end_reason) == ("rPoint_obj", False, "")
    assert step.current is None and step.expected_step == 1


def test_an_idle_robot_acts_not_and_the_outcome_is_read_at_once():
    step, outbox = pipeline()
    step.start("mdp", request(), 1, 0.0)
    for result in (OK, snap("is_ov")):
        answer(step, outbox, result)
    _, effects = answer(step, outbox, Decision("rIdle"))
    assert one(effects, ObserveWorld).purpose == "outcome" and not of(effects, ActRobot)
    assert step.current.report.robot_result == "the robot stays idle and keeps observing"


@pytest.mark.parametrize("req, why", [
    (request(step=1), "expected step 0, not 1"),
    (request(state="dancing"), "unknown human state 'dancing'"),
    (request(action="fly"), "fly"),
])
def test_a_step_the_task_does_not_have_is_refused_and_nothing_is_called(req, why):
    step, outbox = pipeline()
    code, message = step.start("mdp", req, 1, 0.0)
    assert code == "invalid" and why in message
    assert not outbox.take() and step.current is None


def test_a_fault_fails_the_step_visibly_and_refuses_it_to_the_mdp():
    step, outbox = pipeline()
    step.start("mdp", request(), 1, 0.0)
    outbox.take()
    said, effects = answer(step, outbox, Fault("/human/look_around is gone"))
    assert isinstance(said, StepFailed) and "/human/look_around is gone" in said.why
    assert one(effects, PublishStep).report.fault == said.why
    assert one(effects, MdpRefused).code == "failed"
    assert "the loop starts again from a reset" in one(effects, Note, level="error").text
    assert step.current is None


def test_a_call_that_waits_is_named_every_so_often_and_a_silent_world_fails_the_step():
    step, outbox = pipeline(wait_note_every=5.0, world_call_timeout=12.0)
    step.start("mdp", request(), 1, 0.0)
    timers = of(outbox.take(), Timer)
    waited = []
    for _ in range(2):
        (timer,) = timers
        assert step.owns_timer(timer.id)
        assert step.timer_fired(timer.id, EPOCH) is None
        effects = outbox.take()
        waited.append(one(effects, Note, level="warn").text)
        timers = of(effects, Timer)
    assert waited == ["step 0 waits for the human's action (/human/look_around): 5 s so far",
                      "step 0 waits for the human's action (/human/look_around): 10 s so far"]
    assert timers[0].seconds == 2.0         # up to the world's timeout, not past it
    failed = step.timer_fired(timers[0].id, EPOCH)
    assert isinstance(failed, StepFailed) and "has not answered in 12 s" in failed.why


def test_a_reset_interrupts_the_step_and_the_mdp_hears_it_was_stale():
    step, outbox = pipeline()
    step.start("mdp", request(), 1, 0.0)
    outbox.take()
    step.interrupt()
    refused = one(outbox.take(), MdpRefused)
    assert refused.code == "stale" and "interrupted by a reset" in refused.message
    step.start("mdp", request(), 1, 0.0)
    outbox.take()
    assert step.drop() and not outbox.take() and not step.drop()


def test_a_human_who_hears_the_robot_completes_the_step_with_his_reaction():
    step, outbox = pipeline(task=tasks.get("fabric"))
    step.start("mdp", request(state="Evaluating"), 1, 0.0)
    for result in (OK, snap("is_ov"), Decision("point"), OK):
        answer(step, outbox, result)
    said, _ = answer(step, outbox, snap("is_ov", sim_time=2.0))
    assert step.finish("", stops=False, played_out=False) is None
    effects = outbox.take()
    assert one(effects, MdpStepDone).robot_action == "point" and not of(effects, PublishStep)
    react_timer = one(effects, Timer)
    assert step.owns_timer(react_timer.id)
    step.timer_fired(react_timer.id, EPOCH)
    assert "waits for the human's reaction to the robot's point" in \
        one(outbox.take(), Note).text
    assert step.react("mdp", ReactionRequest(EPOCH, 3, "Tired")) is None   # not step 3
    assert one(outbox.take(), MdpRefused).in_reply_to == "reaction"
    done = step.react("mdp", ReactionRequest(EPOCH, 0, "Tired", rule="r1"))
    assert isinstance(done, StepComplete) and done.report is said.report
    assert (done.report.human_state, done.report.reaction) == ("Tired", "r1")
    assert one(outbox.take(), PublishStep).report is done.report
    assert step.expected_step == 1 and step.current is None
