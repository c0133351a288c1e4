"""The LoopRunner: a coordinator carried out with threads against fake interfaces (a scripted
world, a planner, an executor, an MDP that asks for its next step by itself). Timeouts are
safety nets only; nothing here measures time."""
import threading

import pytest

from ros_hrc.errors import SimulationError, StackEnding
from ros_hrc.tasks import seed as task
from ros_hrc.loop.coordinator import CoordinatorConfig
from loop_fakes import MDP_SCRIPT, FakePlanner, Loop

FIRST = 100   # the first epoch of every loop here


@pytest.fixture
def make_loop():
    loops = []

    def make(**config):
        # A reset asked for right after another is meant as a new one in these tests, unless
        # a test is about joining (reset_join_window).
        config.setdefault("reset_join_window", 0.0)
        loop = Loop(CoordinatorConfig(first_epoch=FIRST, **config))
        loops.append(loop)
        return loop

    yield make
    for loop in loops:
        loop.close()


def reports_after(loop, epoch, n):
    """Wait until the epoch has ``n`` reports; its reports."""
    assert loop.runner.wait_until(lambda: len(loop.reports_of(epoch)) >= n, 10), \
        loop.log.snapshot()[-20:]
    return loop.reports_of(epoch)


def assert_epochs_never_mix(loop):
    """After the MDP is told of epoch E, only steps of E are reported (until the next)."""
    current = None
    for kind, what in loop.log.snapshot():
        if kind == "mdp_reset":
            current = what.epoch
        elif kind == "report":
            assert what.epoch == current, (what, current)


def assert_steps_count_from_zero(loop):
    epochs = {r.epoch for r in loop.log.of("report")}
    for epoch in epochs:
        steps = [r.step for r in loop.reports_of(epoch)]
        assert steps == list(range(len(steps))), (epoch, steps)


def test_a_run_of_20_steps_through_threads(make_loop):
    loop = make_loop(max_steps=20)
    loop.runner.mdp_connected("mdp")
    assert loop.runner.wait_until(
        lambda: any(d.episode_over for d in loop.log.of("step_done")), 10)
    reports = loop.log.of("report")
    assert [r.step for r in reports] == list(range(20))
    assert {r.epoch for r in reports} == {FIRST} and {r.episode for r in reports} == {1}
    assert not any(r.fault for r in reports)
    assert [r.end_reason for r in reports] == [""] * 19 + ["step_limit"]
    tracker = task.RobotStateTracker()
    for r in reports:
        action, state = MDP_SCRIPT[r.step % len(MDP_SCRIPT)]
        assert (r.human_action, r.human_state) == (action, state)
        assert r.observation_bits in task.LEGAL_BITS
        assert r.robot_observation == f"O{r.observation_bits}"
        assert r.robot_state == tracker.update(state)
        assert r.robot_action == FakePlanner.ACTIONS[r.step % len(FakePlanner.ACTIONS)]
    times = [r.sim_time for r in reports]
    assert times == sorted(times) and len(set(times)) == 20
    assert loop.executor.calls == [("act", FIRST, r.step, r.robot_action) for r in reports
                                   if r.robot_action != "rIdle"]
    assert len([c for c in loop.world.calls if c[0] == "act"]) == 20
    assert [r.epoch for r in loop.log.of("mdp_reset")] == [FIRST]
    assert loop.log.of("refused") == []
    assert loop.coordinator.phase == "episode_over"


def test_a_second_mdp_client_is_refused_while_the_seated_one_steps(make_loop):
    loop = make_loop()
    loop.runner.mdp_connected("mdp")
    reports_after(loop, FIRST, 3)
    loop.runner.mdp_connected("intruder")
    assert loop.runner.wait_until(lambda: loop.log.of("seat_refused"), 10)
    assert loop.log.of("seat_refused")[0].peer == "intruder"
    n = len(loop.reports_of(FIRST))
    reports_after(loop, FIRST, n + 3)
    assert [r.epoch for r in loop.log.of("mdp_reset")] == [FIRST]


def test_resets_from_50_threads_while_stepping_are_all_answered_and_epochs_never_mix(
        make_loop):
    loop = make_loop()
    loop.runner.mdp_connected("mdp")
    reports_after(loop, FIRST, 10)
    barrier = threading.Barrier(50)
    answers = []

    def ask():
        barrier.wait(10)
        answer = loop.runner.reset("fifty at once", timeout=10)
        answers.append((answer, len(loop.log.snapshot())))

    threads = [threading.Thread(target=ask) for _ in range(50)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(15)
    assert len(answers) == 50
    assert all(ok for (ok, _), _ in answers), [m for (ok, m), _ in answers if not ok]
    final = loop.last_reset().epoch
    assert final > FIRST
    reports_after(loop, final, 5)
    log = loop.log.snapshot()
    for _, index in answers:   # no step of an older epoch after the reset answered
        told = [w.epoch for k, w in log[:index] if k == "mdp_reset"][-1]
        assert all(w.epoch >= told for k, w in log[index:] if k == "report")
    assert_epochs_never_mix(loop)
    assert_steps_count_from_zero(loop)
    assert [r.step for r in loop.reports_of(final)][:5] == [0, 1, 2, 3, 4]
    assert not any(r.fault for r in loop.log.of("report"))


def test_a_world_action_blocked_until_an_interrupting_reset_is_cut_short(make_loop):
    loop = make_loop()
    loop.world.block_act(4)                 # the human's action of step 3 hangs
    loop.runner.mdp_connected("mdp")
    assert loop.wait(loop.world.blocked.is_set)
    dropped = loop.coordinator.dropped
    ok, message = loop.runner.reset("operator", timeout=10)
    assert ok, message
    calls = loop.world.calls
    interrupt = calls.index(("reset", True))
    service = task.human_service_for(*MDP_SCRIPT[3])
    returned = calls.index(("act_returned", service, True))
    real = max(i for i, c in enumerate(calls) if c == ("reset", False))
    assert interrupt < returned < real       # interrupted, drained, then reset for real
    assert loop.coordinator.dropped > dropped
    refused = [r for r in loop.log.of("refused") if r.code == "stale"]
    assert [(r.epoch, r.step) for r in refused] == [(FIRST, 3)]
    assert [r.step for r in loop.reports_of(FIRST)] == [0, 1, 2]
    new = loop.last_reset().epoch
    assert [r.step for r in reports_after(loop, new, 3)][:3] == [0, 1, 2]
    assert_epochs_never_mix(loop)


def test_a_late_planner_answer_after_a_reset_is_dropped(make_loop):
    loop = make_loop()
    loop.planner.hold(2)                    # the decision of step 2 is slow
    loop.runner.mdp_connected("mdp")
    assert loop.wait(loop.planner.holding.is_set)
    loop.runner.request_reset("operator")
    assert loop.runner.wait_until(lambda: loop.coordinator.phase == "resetting", 10)
    # the reset waits for the old decision: the planner is not reset under it
    assert loop.planner.epoch == FIRST
    dropped = loop.coordinator.dropped
    loop.planner.release.set()
    assert loop.runner.wait_until(lambda: loop.last_reset().epoch > FIRST, 10)
    new = loop.last_reset().epoch
    reports_after(loop, new, 3)
    assert loop.coordinator.dropped == dropped + 1
    planner = loop.planner.calls
    assert planner.index(("decided", FIRST, 2)) < planner.index(("reset", new, 2))
    assert [r.step for r in loop.reports_of(FIRST)] == [0, 1]
    assert [(r.epoch, r.step, r.code) for r in loop.log.of("refused")] == [
        (FIRST, 2, "stale")]
    assert_epochs_never_mix(loop)
    assert_steps_count_from_zero(loop)


FAILURES = [  # which fake, which of its calls, what it raises, what the fault says
    ("world", "act", RuntimeError("servo on fire"), "RuntimeError: servo on fire"),
    ("world", "snapshot", KeyError("is_ov"), "KeyError"),
    ("world", "act", SimulationError("no such body"), "no such body"),
    ("planner", "decide", ZeroDivisionError("division by zero"), "ZeroDivisionError"),
    ("executor", "act", OSError("arm unplugged"), "OSError: arm unplugged"),
]


@pytest.mark.parametrize("fake, method, exc, text", FAILURES,
                         ids=[f"{f}-{m}-{type(e).__name__}" for f, m, e, _ in FAILURES])
def test_an_interface_raising_becomes_a_fault_and_the_loop_recovers(make_loop, fake, method,
                                                                    exc, text):
    loop = make_loop(retry_delay=0.01)
    loop.runner.mdp_connected("mdp")
    reports_after(loop, FIRST, 3)
    getattr(loop, fake).hooks.fail[method] = [exc]
    assert loop.runner.wait_until(lambda: any(r.fault for r in loop.log.of("report")), 10)
    failed = [r for r in loop.log.of("report") if r.fault]
    assert len(failed) == 1 and text in failed[0].fault and failed[0].epoch == FIRST
    assert [r.code for r in loop.log.of("refused")] == ["failed"]
    assert loop.runner.wait_until(lambda: loop.last_reset().epoch > FIRST, 10)
    new = loop.last_reset().epoch
    assert [r.step for r in reports_after(loop, new, 3)][:3] == [0, 1, 2]
    assert_epochs_never_mix(loop)


def test_a_dead_planner_is_retried_by_the_timer_until_it_comes_back(make_loop):
    loop = make_loop(retry_delay=0.01, max_retry_delay=0.05)
    loop.runner.mdp_connected("mdp")
    reports_after(loop, FIRST, 3)
    loop.planner.down(4)     # one decision and three resets fail, then it answers again
    assert loop.runner.wait_until(lambda: loop.last_reset().epoch > FIRST, 10)
    new = loop.last_reset().epoch
    assert [r.step for r in reports_after(loop, new, 3)][:3] == [0, 1, 2]
    failed = [r for r in loop.log.of("report") if r.fault]
    assert len(failed) == 1 and "ConnectionError" in failed[0].fault
    notes = [text for level, text in loop.log.of("note") if level == "error"]
    assert len([t for t in notes if t.startswith("reset failed")]) == 3
    resets = [c for c in loop.planner.calls if c[0] == "reset"]
    assert len(resets) == 1 + 4 and resets[-1][1] == new   # first, 3 failed, the good one
    assert loop.planner.epoch == new
    assert [r.epoch for r in loop.log.of("mdp_reset")] == [FIRST, new]
    assert_epochs_never_mix(loop)
    assert_steps_count_from_zero(loop)


def test_fifty_resets_spread_over_a_tenth_of_a_second_are_one_reset(make_loop):
    """Issue #20: 50 concurrent /hrc/reset calls made 5 to 10 resets, since they reach the
    loop spread out and a reset here finishes in no time. They are one reset: one new
    epoch, the episode number up by one, every call answered with success."""
    loop = make_loop(reset_join_window=1.0)
    loop.runner.mdp_connected("mdp")
    reports_after(loop, FIRST, 3)
    answers = []

    def ask(delay):
        threading.Event().wait(delay)
        answers.append(loop.runner.reset("fifty, spread", timeout=10))

    loop.mdp.stepping = False            # no step after the reset (a step ends the window)
    threading.Event().wait(1.2)          # past the join window of the first reset
    resets_before = len(loop.log.of("mdp_reset"))
    episode_before = loop.coordinator.episode
    threads = [threading.Thread(target=ask, args=(i * 0.002,)) for i in range(50)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(15)
    assert len(answers) == 50 and all(ok for ok, _ in answers), answers
    assert len(loop.log.of("mdp_reset")) == resets_before + 1
    assert loop.coordinator.episode == episode_before + 1
    assert_epochs_never_mix(loop)


@pytest.mark.parametrize("fake, method", [("world", "act"), ("world", "snapshot"),
                                          ("executor", "act")])
def test_the_world_shutting_down_ends_the_run_without_a_fault_or_a_reset(make_loop, fake,
                                                                          method):
    loop = make_loop(retry_delay=0.01)
    loop.runner.mdp_connected("mdp")
    reports_after(loop, FIRST, 3)
    getattr(loop, fake).hooks.fail[method] = [StackEnding("the world ends: the window closed")]
    assert loop.runner.wait_until(lambda: loop.runner.coordinator.phase == "ended", 10)
    answer = loop.runner.reset("Enter pressed", 10)
    assert not answer[0] and "the run ends" in answer[1]
    assert not any(r.fault for r in loop.log.of("report"))
    assert loop.log.of("refused") == [] and loop.last_reset().epoch == FIRST
    assert [level for level, _ in loop.log.of("note") if level in ("error", "warn")] == []
