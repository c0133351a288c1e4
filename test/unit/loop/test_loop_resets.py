"""The resets part of the coordinator (loop/resets.py) alone: epochs, the reset's stages
(drain, reset, start), joining, failing and retrying, with its own outbox."""
from ros_hrc.loop.config import CoordinatorConfig
from ros_hrc.loop.effects import (ActHuman, Fault, ObserveWorld, Outcome, ResetDone,
                                  ResetPlanner, ResetWorld, Timer)
from ros_hrc.loop.outbox import Outbox
from ros_hrc.loop.resets import JOIN_CLOSED, RETRY, Resets
from loop_fakes import OK, of, one, snap


def resets(**config):
    outbox = Outbox()
    return Resets(CoordinatorConfig(**config), outbox), outbox


def parts(outbox):
    effects = outbox.take()
    return one(effects, ResetWorld, interrupt=False), one(effects, ResetPlanner)


def test_every_reset_mints_the_next_epoch_and_resets_world_and_planner_into_it():
    r, outbox = resets(first_epoch=40)
    assert r.epoch is None
    assert r.begin("asked", "t1") == 40 and r.drained()
    r.reset_parts(episode=3, task_index=2, true_type="tired")
    world, planner = parts(outbox)
    assert (world.epoch, world.episode, planner.epoch) == (40, 3, 40)
    assert (planner.task_index, planner.true_type) == (2, "tired")
    assert r.part_reset(outbox.answered(world.id), OK) is None
    assert not of(outbox.take(), ObserveWorld)          # the planner is not reset yet
    assert r.part_reset(outbox.answered(planner.id), OK) is None
    assert one(outbox.take(), ObserveWorld).purpose == "episode_start"
    assert r.start_time(snap(sim_time=2.5)) == (2.5, "")
    tokens, text = r.finished(episode=3)
    assert tokens == ("t1",) and text == ("world, robot belief and human MDP reset (asked): "
                                          "episode 3")
    assert r.begin("again", None) == 41


def test_a_reset_drains_the_old_epochs_calls_and_interrupts_motions_first():
    r, outbox = resets()
    r.begin("first", None)
    human = outbox.call(ActHuman, r.epoch, 0, service="look_around")
    outbox.take()
    r.begin("second", None)
    r.interrupt_motions()
    interrupt = one(outbox.take(), ResetWorld)
    assert interrupt.interrupt and not r.drained()
    outbox.answered(human.id)
    assert not r.drained()                  # the interrupting world reset is still out
    assert r.part_reset(outbox.answered(interrupt.id), OK) is None
    assert r.drained()


def test_a_failed_part_fails_the_reset_saying_what_was_and_was_not_reset():
    r, outbox = resets()
    r.begin("asked", "t")
    r.reset_parts(1, 0, "")
    world, planner = parts(outbox)
    r.part_reset(outbox.answered(world.id), OK)
    why = r.part_reset(outbox.answered(planner.id), Fault("the POMDP process is not connected"))
    assert why == ("not reset: robot planner: the POMDP process is not connected; reset: world;"
                   " the human MDP is told when all are")
    assert r.start_time(Outcome(True))[1].startswith("world: the snapshot at the episode's start")


def test_a_failed_reset_answers_who_asked_and_is_retried_doubling_up_to_the_cap():
    r, outbox = resets(retry_delay=4.0, max_retry_delay=10.0)
    delays, answers = [], []
    for _ in range(3):
        r.begin("asked", "t")
        r.failed("world: gone")
        effects = outbox.take()
        answers.append(one(effects, ResetDone).message)
        delays.append(one(effects, Timer).seconds)
        assert r.timer_fired(one(effects, Timer).id) == RETRY
    assert delays == [4.0, 8.0, 10.0]
    assert answers[0] == ("reset failed: world: gone; retried in 4 s (then every up to 10 s) "
                          "until it works")
    r.begin("asked", None)
    r.finished(1)
    r.begin("asked", None)
    r.failed("again")
    assert one(outbox.take(), Timer).seconds == 4.0    # a reset that worked starts it over


def test_a_reset_asked_the_same_way_just_after_it_finished_is_that_reset():
    r, outbox = resets(reset_join_window=1.0)
    r.asked_from_outside("/hrc/reset called")
    r.begin("/hrc/reset called", "a")
    r.finished(5)
    window = one(outbox.take(), Timer)
    assert not r.joins_finished("Enter pressed", "b")
    assert r.joins_finished("/hrc/reset called", "c")
    effects = outbox.take()
    joined = one(effects, ResetDone)
    assert joined.tokens == ("c",) and joined.success and "episode 5 (this request joined it" \
        in joined.message
    later = one(effects, Timer)                 # the window runs from the latest request
    assert r.timer_fired(window.id) is None
    assert r.timer_fired(later.id) == JOIN_CLOSED
    assert not r.joins_finished("/hrc/reset called", "d")


def test_the_run_ending_answers_who_waits_that_no_reset_comes():
    r, outbox = resets()
    r.begin("asked", "a")
    r.join("b")
    r.run_ended("the window was closed")
    done = one(outbox.take(), ResetDone)
    assert done.tokens == ("a", "b") and not done.success
    assert done.message == "no reset: the run ends (the window was closed)"
