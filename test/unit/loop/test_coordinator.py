"""The episode coordinator, driven by hand (no threads): events in through its methods,
effects out through effects(), calls answered with call_done. Each test is one behaviour a
user of the loop would check: step order and reports, faults and recovery, resets (mid-step,
bursts, failed ones), the MDP's seat, stale steps and episode ends."""
import pytest

from ros_hrc.streams import EpisodeSchedule
from ros_hrc.tasks import seed as task
from ros_hrc.loop.coordinator import CoordinatorConfig
from ros_hrc.loop.effects import (ActRobot, Decision, Fault, MdpRefused, MdpReset, MdpStepDone,
                                  Note, ObserveWorld, Outcome, PublishStep, ResetDone,
                                  ResetPlanner, ResetWorld, SeatRefused, Snapshot, Timer)
from loop_fakes import OK, Driver, calls, of, one, snap, stage_of


def ready_driver(config=None, peer="mdp"):
    d = Driver(config, peer=peer)
    return d, d.ready()


def answer_for(stage):
    """A proper answer to the call of a stage (for late answers)."""
    return {"human": OK, "observe": snap("is_ov"), "decide": Decision("rPoint_obj"),
            "robot": OK, "outcome": snap("is_ov")}[stage]


# -- the first MDP, the first reset, the first steps ----------------------------------------------

def test_first_mdp_client_is_seated_and_reset_into_a_new_epoch():
    d = Driver(CoordinatorConfig(first_epoch=41))
    out = d.connect()
    assert d.c.seat == "mdp" and d.c.phase == "resetting"
    rw, rp = calls(out)
    assert isinstance(rw, ResetWorld) and not rw.interrupt and isinstance(rp, ResetPlanner)
    assert rw.epoch == rp.epoch == 41 and rp.episode == 1
    assert not of(out, MdpReset)

    out = d.answer(rw, OK)
    assert not calls(out) and not of(out, MdpReset)
    out = d.answer(rp, OK)
    start = one(out, ObserveWorld, purpose="episode_start")
    assert start.epoch == 41 and not of(out, MdpReset)
    out = d.answer(start, snap(sim_time=2.5))
    reset = one(out, MdpReset)
    assert (reset.peer, reset.epoch, reset.episode) == ("mdp", 41, 1)
    assert d.c.phase == "ready" and d.c.expected_step == 0 and d.c.epoch == 41
    assert not of(out, ResetDone)   # nobody asked for it with a token


def test_mdp_is_told_only_after_world_and_planner_reset_in_either_order():
    d = Driver()
    rw, rp = calls(d.connect())
    out = d.answer(rp, OK)          # the planner answers first
    assert not calls(out) and not of(out, MdpReset)
    out = d.answer(rw, OK)
    out = d.answer(one(out, ObserveWorld, purpose="episode_start"), snap())
    assert one(out, MdpReset).epoch == rw.epoch


def test_steps_run_in_order_with_consistent_reports():
    d, reset = ready_driver()
    script = [  # action, state, observed predicates, decision, robot state expected
        ("graspAttempt", "failed_to_grasp", snap("is_ov", "is_oir", "is_a0"),
         Decision("rPoint_obj", belief=(0.25, 0.75), belief_states=("S0", "S2"),
                  decision_ms=3.0, surprise=True, rule="help"), "S2"),
        ("lookAround", "evaluating", snap("is_ov", "is_a0", "is_a2"),   # 37: not legal
         Decision("rIdle"), "S2"),
        ("graspAttempt", "failed_to_grasp", snap("is_ov", "is_oir", "is_a0", "is_h4"),
         Decision("rGrasp_obj"), "S3"),
    ]
    tracker = task.RobotStateTracker()
    reports = []
    for n, (action, state, seen, decision, robot_state) in enumerate(script):
        played = d.play_step(action, state, observe=seen, decision=decision,
                             outcome=snap("is_ov", sim_time=2.0 + n), reward=-1.0)
        stages = [stage_of(c) for c in played.calls]
        expected = ["human", "observe", "decide", "robot", "outcome"]
        if decision.action == "rIdle":
            expected.remove("robot")
        assert stages == expected
        assert all(c.epoch == reset.epoch and c.step == n for c in played.calls)
        act, decide = played.calls[0], played.calls[2]
        assert act.service == task.human_service_for(action, state)

        report, done = played.report, played.done
        kinds = [type(e) for e in played.effects if isinstance(e, (PublishStep, MdpStepDone))]
        assert kinds == [PublishStep, MdpStepDone]
        raw = task.bits_from_predicates(seen.predicates)
        assert (report.epoch, report.episode, report.step) == (reset.epoch, 1, n)
        assert (report.human_action, report.human_state) == (action, state)
        assert report.human_state_index == task.HUMAN_STATES.index(state)
        assert report.human_reward == -1.0 and report.human_acted
        assert report.human_observation == task.predicates_text(seen.predicates)
        assert report.observation_bits in task.LEGAL_BITS
        assert report.observation_bits == task.legal_bits(raw)
        assert report.robot_observation == f"O{report.observation_bits}"
        assert report.robot_state == tracker.update(state) == robot_state
        assert (decide.observation, decide.bits, decide.state) == (
            report.robot_observation, raw, report.robot_state)
        assert report.robot_action == decision.action
        assert report.belief == decision.belief and report.rule == decision.rule
        assert report.surprise == decision.surprise
        assert report.sim_time == 2.0 + n and report.episode_start_time == 1.5
        assert not report.episode_over and report.end_reason == "" and report.fault == ""
        assert (done.peer, done.epoch, done.step, done.episode) == ("mdp", reset.epoch, n, 1)
        assert done.reply == played.request.reply
        assert done.robot_action == decision.action and not done.episode_over
        reports.append(report)
    assert [r.step for r in reports] == [0, 1, 2]
    # step 1 saw 37 (visible + grasp attempt + idle), not an observation of the model: mapped
    assert task.bits_from_predicates(script[1][2].predicates) == 37
    assert reports[1].observation_bits != 37
    assert d.c.expected_step == 3 and d.c.phase == "ready"


def test_a_grasp_attempt_that_succeeds_calls_the_grasp_service():
    d, _ = ready_driver()
    played = d.play_step("graspAttempt", "success", until="human")
    assert played.calls[0].service == "grasp"
    other, _ = ready_driver()
    assert other.play_step("graspAttempt", "failed_to_grasp",
                           until="human").calls[0].service == "attempt_grasp"


def test_rIdle_skips_the_robot_executor():
    d, _ = ready_driver()
    played = d.play_step(decision=Decision("rIdle"))
    assert [stage_of(c) for c in played.calls] == ["human", "observe", "decide", "outcome"]
    assert not of(d.log, ActRobot)
    assert played.report.robot_action == "rIdle" and played.report.robot_acted
    assert played.report.robot_result
    assert played.done.robot_action == "rIdle" and played.done.success


def test_a_refused_world_action_is_reported_and_the_step_goes_on():
    d, reset = ready_driver()
    played = d.play_step("graspAttempt", "failed_to_grasp",
                         human=Outcome(False, "out of reach"))
    assert [stage_of(c) for c in played.calls] == ["human", "observe", "decide", "robot",
                                                   "outcome"]
    report = played.report
    assert not report.human_acted and report.human_result == "out of reach"
    assert report.fault == "" and played.refused is None and played.done is not None
    assert d.c.phase == "ready" and d.c.epoch == reset.epoch
    assert d.play_step().report.step == 1


def test_a_refused_robot_action_is_reported_not_a_fault():
    d, _ = ready_driver()
    played = d.play_step(robot=Outcome(False, "blocked"))
    assert not played.report.robot_acted and played.report.robot_result == "blocked"
    assert played.report.fault == ""
    assert not played.done.success and played.done.result == "blocked"
    assert d.c.phase == "ready"


# -- faults ------------------------------------------------------------------------------------------

FAULT_STAGES = [  # play_step argument, what the report's fault names
    ("human", "the human's action (/human/look_around)"),
    ("observe", "the world's snapshot"),
    ("decision", "the robot planner"),
    ("robot", "the robot executor (rPoint_obj)"),
    ("outcome", "the world's snapshot"),
]


@pytest.mark.parametrize("where, names", FAULT_STAGES, ids=[s for s, _ in FAULT_STAGES])
def test_a_fault_from_each_interface_fails_the_step_and_the_loop_recovers(where, names):
    d, reset = ready_driver()
    d.play_step()
    played = d.play_step(**{where: Fault("connection lost")})
    report = played.report
    assert report.step == 1 and report.epoch == reset.epoch
    assert names in report.fault and "connection lost" in report.fault
    assert played.done is None
    refused = played.refused
    assert (refused.peer, refused.code, refused.step, refused.epoch) == (
        "mdp", "failed", 1, reset.epoch)
    order = [type(e) for e in played.effects if isinstance(e, (PublishStep, MdpRefused))]
    assert order == [PublishStep, MdpRefused]
    assert of(played.effects, Note, level="error")
    # the recovery reset: world and planner, in a new epoch, nothing to interrupt
    assert not of(played.effects, ResetWorld, interrupt=True)
    rw = one(played.effects, ResetWorld)
    rp = one(played.effects, ResetPlanner)
    assert rw.epoch == rp.epoch == reset.epoch + 1 and rp.episode == 2
    new = one(d.finish_reset(played.effects), MdpReset)
    assert (new.epoch, new.episode) == (reset.epoch + 1, 2)
    again = d.play_step()
    assert (again.report.epoch, again.report.step, again.report.fault) == (new.epoch, 0, "")
    # the MDP's old epoch is over: refused, and the reset the MDP then waits for comes
    late = d.start_step(epoch=reset.epoch, step=2)
    _refused_then_reset(d, late, "stale", 2, reset.epoch)


NONSENSE = [
    ("human", Snapshot({})),                 # not an Outcome
    ("observe", Outcome(True)),              # not a Snapshot
    ("decision", Decision("rDance")),        # an action the robot does not have
    ("decision", Outcome(True)),             # not a Decision
    ("outcome", None),
]


@pytest.mark.parametrize("where, answer", NONSENSE,
                         ids=[f"{w}-{type(a).__name__}" for w, a in NONSENSE])
def test_an_interface_answering_nonsense_fails_the_step(where, answer):
    d, reset = ready_driver()
    played = d.play_step(**{where: answer})
    assert played.report.fault and played.refused.code == "failed"
    assert one(played.effects, ResetPlanner).epoch == reset.epoch + 1


def test_a_restarted_solver_not_reset_into_the_epoch_is_a_fault_and_recovers():
    d, reset = ready_driver()
    d.play_step()
    played = d.play_step(decision=Fault(f"not reset into epoch {reset.epoch}"))
    assert "robot planner" in played.report.fault
    assert f"not reset into epoch {reset.epoch}" in played.report.fault
    assert played.refused.code == "failed"
    rp = one(played.effects, ResetPlanner)
    assert rp.epoch == reset.epoch + 1
    assert one(d.finish_reset(played.effects), MdpReset).epoch == rp.epoch
    assert d.play_step().report.step == 0


# -- resets mid-step, late answers, bursts ----------------------------------------------------------

MID_STAGES = ["human", "observe", "decide", "robot", "outcome"]


@pytest.mark.parametrize("stage", MID_STAGES)
def test_a_reset_mid_step_drains_the_old_call_and_drops_its_late_answer(stage):
    d, reset = ready_driver()
    d.play_step()
    played = d.play_step(until=stage)
    old = played.calls[-1]
    assert stage_of(old) == stage and d.c.phase == "stepping"
    out = d.reset(token="t")
    refused = one(out, MdpRefused)
    assert (refused.code, refused.step, refused.epoch) == ("stale", 1, reset.epoch)
    world_action = stage in ("human", "robot")
    interrupts = of(out, ResetWorld, interrupt=True)
    assert not of(out, ResetWorld, interrupt=False) and not of(out, ResetPlanner)
    if world_action:
        assert len(interrupts) == 1 and interrupts[0].epoch == reset.epoch + 1
    else:
        assert not interrupts
    dropped = d.c.dropped
    late = d.answer(old, answer_for(stage))
    assert d.c.dropped == dropped + 1
    assert not of(late, PublishStep) and not of(late, MdpStepDone)
    if world_action:
        assert not calls(late)   # still waits for the interrupting reset
        late += d.answer(interrupts[0], OK)
    rw = one(late, ResetWorld, interrupt=False)
    assert rw.epoch == one(late, ResetPlanner).epoch == reset.epoch + 1
    out = d.finish_reset(late)
    assert one(out, MdpReset).epoch == reset.epoch + 1
    done = one(out, ResetDone)
    assert done.tokens == ("t",) and done.success
    # no report of the interrupted step, ever; the new epoch starts at step 0
    assert [(p.report.epoch, p.report.step) for p in of(d.log, PublishStep)] == [
        (reset.epoch, 0)]
    assert d.play_step().report.step == 0
    assert one(d.start_step(epoch=reset.epoch, step=2), MdpRefused).code == "stale"


@pytest.mark.parametrize("stage", ["human", "robot"])
def test_a_reset_waits_for_the_old_world_action_even_when_the_interrupt_answers_first(stage):
    d, reset = ready_driver()
    old = d.play_step(until=stage).calls[-1]
    interrupt = one(d.reset(), ResetWorld, interrupt=True)
    out = d.answer(interrupt, OK)
    assert not calls(out)    # the old action is still out: it could still move things
    out = d.answer(old, Outcome(False, "interrupted"))
    assert d.c.dropped == 1
    assert one(out, ResetWorld, interrupt=False).epoch == reset.epoch + 1
    assert one(d.finish_reset(out), MdpReset).epoch == reset.epoch + 1


def test_a_late_fault_of_an_old_call_is_dropped_not_a_failed_step():
    d, reset = ready_driver()
    old = d.play_step(until="decide").calls[-1]
    d.reset()
    out = d.answer(old, Fault("planner died meanwhile"))
    assert d.c.dropped == 1
    assert not of(out, PublishStep) and not of(out, MdpRefused)
    assert one(d.finish_reset(out), MdpReset).epoch == reset.epoch + 1


def test_a_burst_of_50_resets_while_one_is_under_way_is_one_reset():
    d, reset = ready_driver()
    d.play_step()
    old = d.play_step(until="decide").calls[-1]
    out = []
    for token in range(20):                       # while draining the old call
        out += d.reset(token=token)
    out += d.answer(old, Decision("rIdle"))
    for token in range(20, 35):                   # while world and planner reset
        out += d.reset(token=token)
    rw, rp = one(out, ResetWorld), one(out, ResetPlanner)
    out += d.answer(rw, OK) + d.answer(rp, OK)
    start = one(out, ObserveWorld, purpose="episode_start")
    for token in range(35, 50):                   # while the episode starts
        out += d.reset(token=token)
    out += d.answer(start, snap())
    assert rw.epoch == rp.epoch == reset.epoch + 1 == d.c.epoch
    assert len(of(d.log, ResetWorld)) == len(of(d.log, ResetPlanner)) == 2   # first + this
    assert one(out, MdpReset).epoch == reset.epoch + 1
    done = one(out, ResetDone)
    assert done.tokens == tuple(range(50)) and done.success
    assert d.c.episode == 2 and d.c.phase == "ready"


def test_resets_asked_for_just_after_one_finished_are_that_reset():
    """Issue #20: fifty /hrc/reset calls sent within 19 ms reach the coordinator spread
    out; those that came after the first reset finished each started another (5 to 10
    resets, the episode number jumping). Within reset_join_window they are that reset."""
    d = Driver(CoordinatorConfig(reset_join_window=1.0))
    d.let_time_pass = False
    d.ready()
    d.close_join_window()
    out = d.finish_reset(d.reset(token="first"))
    assert one(out, ResetDone).tokens == ("first",) and d.c.episode == 2
    epoch = d.c.epoch
    started = d.play_step(until="observe")          # step 0 of the new episode is under way
    out = []
    for token in range(49):
        out += d.reset(token=token)
    assert not calls(out) and not of(out, MdpRefused) and not of(out, MdpReset)
    assert [done.tokens for done in of(out, ResetDone)] == [(t,) for t in range(49)]
    assert all(done.success and "episode 2" in done.message for done in of(out, ResetDone))
    assert (d.c.epoch, d.c.episode) == (epoch, 2)
    out = d.answer(started.calls[-1], snap())      # step 0 goes on in the same epoch
    while calls(out):
        call = calls(out)[0]
        out = d.answer(call, answer_for(stage_of(call)))
    assert one(out, PublishStep).report.epoch == epoch and not one(out, PublishStep).report.fault
    # a reset asked for another way (Enter, after fifty /hrc/reset calls) is a new one
    out = d.finish_reset(d.reset(token="enter", reason="Enter pressed"))
    assert one(out, ResetDone).tokens == ("enter",) and d.c.episode == 3
    # and so is one asked for once the window has passed
    d.close_join_window()
    out = d.finish_reset(d.reset(token="later", reason="Enter pressed"))
    assert one(out, ResetDone).tokens == ("later",) and d.c.episode == 4


def test_a_reset_asked_for_after_the_episode_ended_is_a_new_one_even_at_once():
    d = Driver(CoordinatorConfig(reset_join_window=1.0, max_steps=1))
    d.let_time_pass = False
    d.ready()
    assert d.play_step().done.episode_over and d.c.phase == "episode_over"
    out = d.finish_reset(d.reset(token="t"))
    assert one(out, ResetDone).tokens == ("t",) and d.c.episode == 2


def test_a_step_that_waits_says_what_for_and_fails_when_the_world_does_not_answer():
    """Issue #20: world-service storms starved the loop for 40 s with nothing said. A step
    whose call is out says every wait_note_every seconds what it waits for, and a world
    call that has not come back in world_call_timeout fails the step, naming it."""
    d, reset = ready_driver(CoordinatorConfig(wait_note_every=5.0, world_call_timeout=12.0))
    played = d.play_step(action="walkAway", state="no_attention", until="human")
    timer = one(played.effects, Timer)
    assert timer.seconds == 5.0
    d.c.timer_fired(timer.id)
    out = d.take()
    note = one(out, Note, level="warn")
    assert "/human/walk_away" in note.text and "5 s" in note.text
    d.c.timer_fired(one(out, Timer).id)               # 10 s
    out = d.take()
    assert "10 s" in one(out, Note, level="warn").text
    last = one(out, Timer)
    assert last.seconds == 2.0                        # up to the world's timeout
    d.c.timer_fired(last.id)
    out = d.take()
    report = one(out, PublishStep).report
    assert "/human/walk_away" in report.fault and "12 s" in report.fault
    assert one(out, MdpRefused).code == "failed"
    assert d.c.phase == "resetting"


def test_a_step_waiting_for_the_planner_is_noted_but_not_failed_by_the_world_timeout():
    d, reset = ready_driver(CoordinatorConfig(wait_note_every=5.0, world_call_timeout=6.0))
    played = d.play_step(until="decide")
    timer = [t for t in of(played.effects, Timer)][-1]
    for waited in (5, 10, 15):
        d.c.timer_fired(timer.id)
        out = d.take()
        assert f"{waited} s" in one(out, Note, level="warn").text
        assert not of(out, PublishStep)
        timer = one(out, Timer)
    out = d.answer(played.calls[-1], Decision("rIdle"))
    d.c.timer_fired(timer.id)                          # answered meanwhile: nothing
    assert not of(d.take(), Note)


def test_a_reset_that_fails_says_what_was_reset_and_what_was_not():
    """Issue #20: with the POMDP down, /hrc/reset answers what it could and could not reset."""
    d, reset = ready_driver()
    out = d.finish_reset(d.reset(token="t"), planner=Fault("the POMDP process is not "
                                                            "connected"))
    done = one(out, ResetDone)
    assert not done.success
    assert "not reset: robot planner: the POMDP process is not connected" in done.message
    assert "reset: world" in done.message and "retried" in done.message


def test_a_reset_with_no_mdp_seated_answers_its_requester_only():
    d = Driver()
    out = d.finish_reset(d.reset(token="t"))
    assert one(out, ResetDone).tokens == ("t",) and not of(out, MdpReset)
    assert d.c.phase == "ready"


# -- stale and refused steps -----------------------------------------------------------------------

def _refused_without_calls(d, out, code, step, epoch, peer="mdp"):
    refused = one(out, MdpRefused)
    assert not calls(out)
    assert (refused.code, refused.step, refused.epoch, refused.peer) == (code, step, epoch, peer)
    assert refused.reply is not None and refused.message
    return refused


def _refused_then_reset(d, out, code, step, epoch, peer="mdp"):
    """The step was refused with ``code``, and (the protocol's word: after a refused step
    the MDP waits for the next reset) a reset into a new epoch began, which tells the MDP."""
    refused = one(out, MdpRefused, code=code)
    assert (refused.step, refused.epoch, refused.peer) == (step, epoch, peer)
    assert "wait for the reset" in refused.message
    before = d.c.episode
    new = one(d.finish_reset(out), MdpReset)
    assert new.peer == peer and new.epoch == d.c.epoch and new.episode == before + 1
    return refused


def test_a_step_of_an_older_epoch_is_refused_stale_and_the_loop_resets():
    d, reset = ready_driver()
    d.play_step()
    d.finish_reset(d.reset())
    out = d.start_step(epoch=reset.epoch, step=1)
    _refused_then_reset(d, out, "stale", 1, reset.epoch)
    out = d.start_step(epoch=None, step=0)
    _refused_then_reset(d, out, "stale", 0, None)
    assert d.play_step().report.step == 0             # the new epoch steps


@pytest.mark.parametrize("step", [0, 2, 7, -1])
def test_a_step_with_the_wrong_number_is_refused_invalid_and_the_loop_resets(step):
    d, reset = ready_driver()
    d.play_step()                                     # expected now: 1
    out = d.start_step(step=step)
    _refused_then_reset(d, out, "invalid", step, reset.epoch)
    assert d.play_step().report.step == 0             # step 0 of the new epoch


def test_a_step_while_one_is_under_way_is_refused_busy_and_the_loop_resets():
    d, reset = ready_driver()
    first = d.play_step(until="decide")
    out = d.start_step(step=0)
    # the first step is cut short by the reset (stale), the second refused busy
    assert one(out, MdpRefused, code="stale").reply == first.request.reply
    assert not calls(out)          # the reset waits for the decision under way (drain)
    out += d.answer(first.calls[-1], Decision("rIdle"))   # the old decision: dropped
    _refused_then_reset(d, out, "busy", 0, reset.epoch)
    assert d.c.dropped == 1


def test_a_step_while_the_loop_resets_is_refused():
    d, reset = ready_driver()
    out = d.reset()
    assert d.c.phase == "resetting"
    _refused_without_calls(d, d.start_step(epoch=reset.epoch, step=0), "stale", 0,
                           reset.epoch)
    _refused_without_calls(d, d.start_step(epoch=d.c.epoch, step=0), "not_ready", 0,
                           d.c.epoch)
    assert one(d.finish_reset(out), MdpReset).epoch == d.c.epoch


@pytest.mark.parametrize("action, state", [("dance", "evaluating"), ("lookAround", "happy"),
                                           ("", "")])
def test_an_invalid_human_action_or_state_is_refused_invalid_and_the_loop_resets(action, state):
    d, reset = ready_driver()
    out = d.start_step(action=action, state=state)
    _refused_then_reset(d, out, "invalid", 0, reset.epoch)
    assert d.c.phase == "ready"
    assert d.play_step().report.step == 0


def test_answers_to_unknown_or_already_answered_calls_are_ignored():
    d, reset = ready_driver()
    played = d.play_step()
    assert d.answer(played.calls[0], OK) == []
    d.c.call_done(10_000, OK)
    assert d.take() == [] and d.c.dropped == 0


# -- the MDP's seat ----------------------------------------------------------------------------------

def test_a_second_mdp_client_is_refused_and_the_seated_one_keeps_stepping():
    d, reset = ready_driver(peer="a")
    d.play_step()
    out = d.connect("b")
    refused = one(out, SeatRefused)
    assert refused.peer == "b" and refused.message
    assert [type(e) for e in out] == [SeatRefused]      # no reset, nothing else
    assert d.c.seat == "a" and d.c.epoch == reset.epoch
    assert d.play_step().report.step == 1
    assert d.connect("a") == []                          # the seated one again: nothing


def test_a_step_from_a_peer_that_is_not_seated_is_refused_seat_taken():
    d, reset = ready_driver(peer="a")
    out = d.start_step(peer="b")
    _refused_without_calls(d, out, "seat_taken", 0, reset.epoch, peer="b")
    assert d.play_step().report.step == 0


def test_a_refused_client_leaving_changes_nothing():
    d, reset = ready_driver(peer="a")
    d.connect("b")
    d.c.mdp_disconnected("b")
    assert d.take() == [] and d.c.seat == "a"


def test_when_the_seated_client_leaves_the_loop_resets_and_the_next_gets_a_reset_of_its_own():
    d, reset = ready_driver(peer="a")
    d.play_step()
    d.c.mdp_disconnected("a")
    out = d.take()
    assert d.c.seat is None
    assert one(out, ResetPlanner).epoch == reset.epoch + 1
    out = d.finish_reset(out)
    assert not of(out, MdpReset) and d.c.phase == "ready"
    out = d.connect("b")
    assert d.c.seat == "b"
    assert one(out, ResetPlanner).epoch == reset.epoch + 2
    new = one(d.finish_reset(out), MdpReset)
    assert (new.peer, new.epoch) == ("b", reset.epoch + 2)
    played = d.play_step(peer="b")
    assert played.report.step == 0 and played.done.peer == "b"
    assert one(d.start_step(peer="a", epoch=new.epoch, step=1), MdpRefused).code == \
        "seat_taken"


def test_a_client_connecting_while_the_leave_reset_runs_is_reset_before_stepping():
    d, reset = ready_driver(peer="a")
    d.c.mdp_disconnected("a")
    out = d.take()
    out += d.connect("b")
    assert d.c.seat == "b"
    new = one(d.finish_reset(out), MdpReset)
    assert new.peer == "b" and new.epoch == d.c.epoch > reset.epoch
    assert d.play_step(peer="b").report.step == 0


def test_the_seated_client_leaving_mid_step_ends_that_step():
    d, reset = ready_driver(peer="a")
    old = d.play_step(until="robot").calls[-1]
    d.c.mdp_disconnected("a")
    out = d.take()
    assert one(out, MdpRefused).code == "stale"
    interrupt = one(out, ResetWorld, interrupt=True)
    out = d.answer(old, OK) + d.answer(interrupt, OK)
    d.finish_reset(out)
    assert not of(d.log, PublishStep) and d.c.phase == "ready"


# -- failed resets ---------------------------------------------------------------------------------

def test_a_failed_reset_answers_false_and_is_retried_by_a_timer_until_it_works():
    d, reset = ready_driver(CoordinatorConfig(retry_delay=0.5))
    out = d.finish_reset(d.reset(token="t"), planner=Fault("connection refused"))
    done = one(out, ResetDone)
    assert done.tokens == ("t",) and not done.success
    assert "robot planner" in done.message and "connection refused" in done.message
    timer = one(out, Timer)
    assert timer.seconds == 0.5
    assert not of(out, MdpReset) and not of(out, ObserveWorld)
    assert d.c.phase == "broken" and of(out, Note, level="error")
    _refused_without_calls(d, d.start_step(epoch=d.c.epoch, step=0), "not_ready", 0,
                           d.c.epoch)
    d.c.timer_fired(timer.id + 1000)                   # not this timer: nothing
    assert d.take() == []
    failed_epoch = d.c.epoch
    d.c.timer_fired(timer.id)
    out = d.take()
    assert one(out, ResetPlanner).epoch == failed_epoch + 1
    out = d.finish_reset(out)
    assert one(out, MdpReset).epoch == failed_epoch + 1
    assert not of(out, ResetDone)       # the token was answered already
    assert d.c.phase == "ready"
    d.c.timer_fired(timer.id)                          # fired again late: nothing
    assert d.take() == []
    assert d.play_step().report.step == 0


@pytest.mark.parametrize("world, planner, start, names", [
    (Outcome(False, "stuck"), OK, None, "world: stuck"),
    (Fault("no service"), OK, None, "world: no service"),
    (OK, Fault("gone"), None, "robot planner: gone"),
    (Fault("a"), Fault("b"), None, "world: a; robot planner: b"),
    (OK, OK, Fault("no state"), "world: no state"),
])
def test_a_reset_fails_when_any_part_of_it_fails(world, planner, start, names):
    d = Driver()
    out = d.finish_reset(d.reset(token="t"), world=world, planner=planner, start=start)
    done = one(out, ResetDone)
    assert not done.success and names in done.message
    assert one(out, Timer) and d.c.phase == "broken" and not of(out, MdpReset)


def test_retries_back_off_doubling_up_to_the_maximum_and_start_again_after_success():
    d = Driver(CoordinatorConfig(retry_delay=0.5, max_retry_delay=3.0))
    out = d.connect()
    delays = []
    for _ in range(5):
        out = d.finish_reset(out, planner=Fault("down"))
        timer = one(out, Timer)
        delays.append(timer.seconds)
        d.c.timer_fired(timer.id)
        out = d.take()
    assert delays == [0.5, 1.0, 2.0, 3.0, 3.0]
    assert one(d.finish_reset(out), MdpReset)
    out = d.finish_reset(d.reset(), planner=Fault("down again"))
    assert one(out, Timer).seconds == 0.5


def test_a_reset_asked_for_while_waiting_to_retry_starts_at_once():
    d, _ = ready_driver()
    out = d.finish_reset(d.reset(), planner=Fault("down"))
    timer = one(out, Timer)
    out = d.reset(token="now")
    out = d.finish_reset(out)
    assert one(out, ResetDone).tokens == ("now",) and one(out, MdpReset)
    d.c.timer_fired(timer.id)
    assert d.take() == [] and d.c.phase == "ready"


def test_a_retried_reset_keeps_its_reason_short():
    d = Driver()
    out = d.connect()
    for _ in range(3):
        out = d.finish_reset(out, planner=Fault("down"))
        d.c.timer_fired(one(out, Timer).id)
        out = d.take()
    reason = one(d.finish_reset(out), MdpReset).reason
    assert reason.count("retrying") <= 1, reason


def test_failed_attempts_do_not_consume_episode_numbers():
    d = Driver()
    out = d.connect()
    for _ in range(2):
        out = d.finish_reset(out, planner=Fault("the planner is still starting"))
        d.c.timer_fired(one(out, Timer).id)
        out = d.take()
    reset = one(d.finish_reset(out), MdpReset)
    assert reset.episode == 1      # the first episode played
    assert d.play_step().report.episode == 1


def test_nonsense_time_at_episode_start_is_a_failed_reset_not_a_wedge():
    d = Driver()
    rw, rp = calls(d.connect())
    d.answer(rw, OK)
    start = one(d.answer(rp, OK), ObserveWorld, purpose="episode_start")
    d.c.call_done(start.id, Snapshot({}, sim_time="soon"))
    out = d.take()
    assert one(out, Timer) and d.c.phase == "broken"


@pytest.mark.parametrize("answer", [None, Outcome(False, "no world")],
                         ids=["None", "Outcome"])
def test_nonsense_at_episode_start_is_a_failed_reset(answer):
    d = Driver()
    rw, rp = calls(d.connect())
    d.answer(rw, OK)
    start = one(d.answer(rp, OK), ObserveWorld, purpose="episode_start")
    out = d.answer(start, answer)
    assert not of(out, MdpReset) and one(out, Timer)


# -- episode ends --------------------------------------------------------------------------------

ENDS = [  # action, state, outcome snapshot, end reason
    ("graspAttempt", "success", snap("is_ho", holder="human"), "success"),
    ("lookAround", "evaluating", snap(holder="robot"), "success"),
    ("lookAround", "evaluating", snap(left_belt=True), "object_left_belt"),
    ("lookAround", "evaluating", snap(holder="human", left_belt=True), "success"),
    ("graspAttempt", "success", snap("is_ov"), "human_goal"),
]


@pytest.mark.parametrize("action, state, outcome, reason", ENDS,
                         ids=["human-holds", "robot-holds", "left-belt", "holds-and-left",
                              "human-goal"])
def test_each_end_reason_ends_the_episode(action, state, outcome, reason):
    d, reset = ready_driver()
    d.play_step()
    played = d.play_step(action, state, outcome=outcome)
    assert played.report.episode_over and played.report.end_reason == reason
    assert played.done.episode_over and played.done.end_reason == reason
    assert played.report.object_holder == outcome.holder
    assert played.report.object_left_belt == outcome.left_belt
    assert of(played.effects, Note, level="info")
    assert d.c.phase == "episode_over"


def test_the_human_goal_ends_nothing_without_end_on_goal():
    d, _ = ready_driver(CoordinatorConfig(end_on_goal=False))
    played = d.play_step("graspAttempt", "success")
    assert not played.report.episode_over and d.c.phase == "ready"


def test_the_goal_state_is_configurable():
    d, _ = ready_driver(CoordinatorConfig(goal_state="tired"))
    assert d.play_step("idle", "tired").report.end_reason == "human_goal"


def test_max_steps_ends_the_episode_with_step_limit():
    d, _ = ready_driver(CoordinatorConfig(max_steps=3))
    reasons = [d.play_step().report.end_reason for _ in range(3)]
    assert reasons == ["", "", "step_limit"] and d.c.phase == "episode_over"


def test_after_an_end_with_wait_steps_are_refused_until_a_reset():
    d, reset = ready_driver(CoordinatorConfig(on_episode_end="wait"))
    played = d.play_step(outcome=snap(left_belt=True))
    assert played.done.episode_over
    assert not of(played.effects, ResetWorld) and not of(played.effects, ResetPlanner)
    for _ in range(2):
        _refused_without_calls(d, d.start_step(step=1), "episode_over", 1, reset.epoch)
    new = one(d.finish_reset(d.reset()), MdpReset)
    assert (new.epoch, new.episode) == (reset.epoch + 1, 2)
    again = d.play_step()
    assert (again.report.epoch, again.report.episode, again.report.step) == (
        reset.epoch + 1, 2, 0)


def test_after_an_end_with_reset_a_new_epoch_begins_by_itself():
    d, reset = ready_driver(CoordinatorConfig(on_episode_end="reset"))
    played = d.play_step(outcome=snap(holder="robot"))
    assert played.done.episode_over and played.done.end_reason == "success"
    kinds = [type(e) for e in played.effects if isinstance(e, (MdpStepDone, ResetWorld,
                                                               ResetPlanner))]
    assert kinds == [MdpStepDone, ResetWorld, ResetPlanner]   # answered, then reset
    new = one(d.finish_reset(played.effects), MdpReset)
    assert (new.epoch, new.episode) == (reset.epoch + 1, 2)
    assert d.play_step().report.step == 0


def test_after_an_end_with_continue_the_end_is_reported_once_and_stepping_goes_on():
    d, reset = ready_driver(CoordinatorConfig(on_episode_end="continue"))
    held = snap("is_ho", holder="human")
    reasons = [d.play_step(outcome=held).report.end_reason for _ in range(4)]
    assert reasons == ["success", "", "", ""]
    assert d.c.phase == "ready" and d.c.epoch == reset.epoch
    d.finish_reset(d.reset())
    assert d.play_step(outcome=held).report.end_reason == "success"   # a new episode


def test_continue_with_max_steps_reports_the_step_limit_once():
    d, _ = ready_driver(CoordinatorConfig(max_steps=2, on_episode_end="continue"))
    reports = [d.play_step().report for _ in range(4)]
    assert [r.end_reason for r in reports] == ["", "step_limit", "", ""]
    assert [r.step for r in reports] == [0, 1, 2, 3]


@pytest.mark.parametrize("kwargs", [dict(on_episode_end="later"), dict(max_steps=-1),
                                    dict(retry_delay=0), dict(first_epoch=-1)])
def test_a_bad_configuration_is_refused(kwargs):
    with pytest.raises(ValueError):
        CoordinatorConfig(**kwargs)


def test_every_code_of_a_refused_step_is_a_protocol_error_code():
    from ros_hrc.link.protocol import ERROR_CODES
    from ros_hrc.loop import coordinator
    codes = {coordinator.STALE, coordinator.BUSY, coordinator.SEAT_TAKEN, coordinator.INVALID,
             coordinator.EPISODE_IS_OVER, coordinator.FAILED, coordinator.NOT_READY}
    assert codes <= ERROR_CODES


# -- the run's end: the processes stopping together are not a fault ------------------------------

def test_the_seated_client_stopping_mid_step_is_no_news_and_the_next_is_reset_as_always():
    d, reset = ready_driver(peer="a")
    old = d.play_step(until="robot").calls[-1]
    d.c.mdp_disconnected("a", stopped=True)
    out = d.take()
    # Said only for the logs: no warning, no reset, no refusal to a peer that is gone.
    assert [n.level for n in of(out, Note)] == ["debug"]
    assert not calls(out) and not of(out, MdpRefused) and d.c.seat is None
    out = d.answer(old, OK)                    # the step's late answer: dropped, unreported
    assert not of(out, PublishStep) and not calls(out)
    assert not of(d.log, PublishStep)
    new = one(d.finish_reset(d.connect("b")), MdpReset)
    assert new.peer == "b" and new.epoch == reset.epoch + 1
    assert d.play_step(peer="b").report.step == 0


def test_the_run_ending_mid_step_reports_nothing_and_resets_nothing():
    d, reset = ready_driver()
    old = d.play_step(until="robot").calls[-1]
    d.c.run_ended("the world ends: the PyBullet window was closed")
    out = d.take()
    assert [n.level for n in of(out, Note)] == ["debug"] and not calls(out)
    assert d.c.phase == "ended"
    out = d.answer(old, Fault("service /robot/grasp failed"))   # the step's call fails too
    assert out == []
    out = d.reset()                                              # Enter, /hrc/reset
    done = one(out, ResetDone)
    assert not done.success and "the run ends" in done.message and not calls(out)
    d.c.mdp_disconnected("mdp")                                  # the MDP leaves as it ends
    assert d.take() == [] and not of(d.log, PublishStep)


def test_the_run_ending_during_a_reset_answers_its_callers_and_stops_retrying():
    d, reset = ready_driver()
    out = d.reset(token="enter")
    rw = one(out, ResetWorld, interrupt=False)
    d.c.run_ended("the world ends")
    out = d.take()
    assert one(out, ResetDone).tokens == ("enter",) and not one(out, ResetDone).success
    assert d.answer(rw, Fault("the world is shutting down")) == []
    for timer in of(d.log, Timer):                               # nothing is retried
        d.c.timer_fired(timer.id)
    assert not calls(d.take())


@pytest.mark.parametrize("policy, steps, said", [
    ("wait", 4, "episode 1 over (step_limit) after 4 steps: Enter (or `rosservice call "
                "/hrc/reset`) resets and starts the next, or on_episode_end:=reset to go on "
                "by itself"),
    ("wait", 1, "episode 1 over (step_limit) after 1 step: Enter"),
    ("reset", 2, "episode 1 over (step_limit) after 2 steps: the next starts now"),
    ("continue", 1, "episode 1 over (step_limit) after 1 step: stepping goes on"),
])
def test_the_end_of_an_episode_says_once_what_happens_next(policy, steps, said):
    d, _ = ready_driver(CoordinatorConfig(max_steps=steps, on_episode_end=policy))
    effects = []
    for _ in range(steps + (1 if policy == "continue" else 0)):
        effects += d.play_step().effects
    overs = [n.text for n in of(effects, Note, level="info") if " over " in n.text]
    assert len(overs) == 1 and overs[0].startswith(said), overs


def test_the_last_episode_of_a_schedule_says_no_reset_starts_another():
    d, _ = ready_driver(CoordinatorConfig(max_steps=1, episodes=EpisodeSchedule.parse("1")))
    overs = [n.text for n in of(d.play_step().effects, Note, level="info")]
    assert overs == ["episode 1 over (step_limit) after 1 step: the episodes asked for (1) "
                     "are all played: no reset starts another"]
