"""The world serves its driver (the loop) first: other callers of its services never make the
loop's actions wait (issue #20: sixteen threads calling world services starved the loop)."""
import random
import threading

import pytest

from ros_hrc.world import HUMAN_ACTIONS, ROBOT_ACTIONS

LOOP = "/hrc_human"


def test_without_a_driver_every_caller_is_served_in_order(still_world):
    first = still_world.submit("human", "warn_robot", caller="/a")
    second = still_world.submit("human", "idle", caller="/b")
    while not second.done():
        still_world.step()
    assert first.outcome.success and second.outcome.success
    assert not first.refused and not second.refused


def test_the_drivers_action_interrupts_another_callers_and_cancels_those_queued(still_world):
    walking = still_world.submit("human", "walk_away", caller="/storm")
    queued = still_world.submit("human", "look_around", caller="/storm")
    still_world.advance(0.5)
    assert not walking.done()
    warn = still_world.submit("human", "warn_robot", caller=LOOP, driver=True)
    still_world.step()
    assert walking.done() and not walking.outcome.success
    assert "interrupted by human/warn_robot (asked by /hrc_human)" in walking.outcome.message
    assert queued.done() and "cancelled by human/warn_robot" in queued.outcome.message
    while not warn.done():
        still_world.step()
    assert warn.outcome.success, warn.outcome.message
    # the loop's result says why its human did not start from where the last step left it
    assert "it first interrupted human/walk_away (asked by /storm)" in warn.outcome.message


@pytest.mark.parametrize("agent, action", [("human", "grasp"), ("human", "reset"),
                                           ("world", "reset")])
def test_other_callers_are_refused_at_once_while_the_driver_acts(still_world, agent, action):
    looking = still_world.submit("human", "look_around", caller=LOOP, driver=True)
    still_world.step()
    other = still_world.submit(agent, action, caller="/storm")
    assert other.done() and other.refused and not other.outcome.success
    assert other.outcome.message.startswith(
        "busy: the human is doing look_around for /hrc_human, which drives it")
    # the other agent is free: served as before
    pointing = still_world.submit("robot", "point_to_obj", caller="/storm")
    assert not pointing.done()
    while not looking.done():
        still_world.step()
    assert looking.outcome.success and "interrupted" not in looking.outcome.message
    # the driver is done: others are served again
    again = still_world.submit("human", "idle", caller="/storm")
    assert not again.refused


def test_a_storm_of_callers_never_delays_the_drivers_actions(still_world):
    """Sixteen threads calling every action while the driver runs its own: each of the
    driver's actions starts at the control step after it was asked for (simulated time: no
    clock is timed) and does what it was asked."""
    still_world.start(real_time_factor=0.0)
    stop = threading.Event()
    answers = {"refused": 0, "served": 0}
    lock = threading.Lock()

    def storm(seed):
        rng = random.Random(seed)
        calls = [("human", a) for a in HUMAN_ACTIONS] + [("robot", a) for a in ROBOT_ACTIONS] \
            + [("world", "reset")]
        while not stop.is_set():
            agent, action = rng.choice(calls)
            ticket = still_world.submit(agent, action, caller=f"/storm_{seed}")
            ticket.wait(120.0)
            with lock:
                answers["refused" if ticket.refused else "served"] += 1

    threads = [threading.Thread(target=storm, args=(i,), daemon=True) for i in range(16)]
    for thread in threads:
        thread.start()
    try:
        for agent, action in [("human", "warn_robot"), ("robot", "point_to_obj"),
                              ("human", "look_around"), ("robot", "cancel_action"),
                              ("human", "idle"), ("robot", "point_to_obj")] * 2:
            ticket = still_world.submit(agent, action, caller=LOOP, driver=True)
            outcome = ticket.wait(120.0)
            assert outcome.success, (agent, action, outcome.message)
            # started at the very step after it was asked for: it waited behind no one
            assert ticket.started_at == ticket.submitted_at, (agent, action)
    finally:
        stop.set()
        for thread in threads:
            thread.join(120.0)
    assert answers["refused"] > 0 and answers["served"] > 0, answers
