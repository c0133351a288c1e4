"""Start-up: hrc_human waits for the world's services and its link to the planner however long
they take (saying every ~10 s which are still awaited), and the MDP's step 0 waits with it: no
reset, no step, no call before they are up; then exactly one step 0, carried out once.

The waiting itself (nodes/common.ServiceWait) with a fake master and a fake clock; the loop
with the runner's fakes (loop_fakes.py) behind a closed gate, as hrc_human wires it."""
import threading
import time

import pytest

from ros_hrc.loop.coordinator import CoordinatorConfig
from ros_hrc.nodes.common import ServiceUnavailable, ServiceWait
from ros_hrc.nodes.human_node import PLANNER_LINK, STARTUP_SERVICES, WORLD_SERVICES
from loop_fakes import Loop

FIRST = 100
#: What the start-up waits for of the planner: hrc_human's link to the POMDP process.
PLANNER = (PLANNER_LINK,)


class FakeMaster:
    """The names registered so far; the fake clock advances one poll per question."""

    def __init__(self, clock) -> None:
        self.up = set()
        self.clock = clock
        self.asked = 0
        self.script = {}   # question number -> names that come up then

    def __call__(self) -> set:
        self.asked += 1
        self.up |= set(self.script.get(self.asked, ()))
        return set(self.up)


class FakeClock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def run_wait(script, every=10.0, poll=1.0):
    """Run a ServiceWait whose fake clock advances by ``poll`` per question; its lines."""
    clock = FakeClock()
    master = FakeMaster(clock)
    master.script = script
    lines = []
    wait = ServiceWait(STARTUP_SERVICES, say=lines.append, every=every, poll=0.0,
                       registered=master, clock=clock)

    def registered():
        up = master()
        clock.now += poll
        return up
    wait.registered = registered
    wait.run()
    return wait, lines


def test_the_startup_services_are_every_call_the_loop_makes():
    assert WORLD_SERVICES == ("/hrc/world/reset", "/hrc/world/state", "/human/attempt_grasp",
                              "/human/grasp", "/human/idle", "/human/look_around",
                              "/human/walk_away", "/human/warn_robot", "/robot/cancel_action",
                              "/robot/grasp", "/robot/point_to_obj")
    assert STARTUP_SERVICES[1] == ("the robot planner (despot_pomdp)", ("ws://127.0.0.1:7070",))


def test_everything_up_at_once_says_nothing():
    wait, lines = run_wait({1: WORLD_SERVICES + PLANNER})
    assert wait.ready and lines == [] and wait.missing() == []


def test_a_world_that_takes_a_minute_is_waited_for_with_a_line_every_10_s():
    # The planner is up at once; the world's services come up after 62 questions (62 s).
    wait, lines = run_wait({1: PLANNER, 62: WORLD_SERVICES})
    assert wait.ready
    world = ", ".join(WORLD_SERVICES)
    assert lines[:6] == [f"waiting for the world (hrc_world): {world} ({t} s; no step is "
                         "taken before they are up)" for t in (10, 20, 30, 40, 50, 60)]
    assert lines[6:] == ["The world (hrc_world) and the robot planner (despot_pomdp) are up after "
                         "62 s: the loop starts (its first reset, then step 0)"]


def test_the_line_names_only_the_services_still_awaited():
    wait, lines = run_wait({5: WORLD_SERVICES[:3], 15: WORLD_SERVICES[3:-1],
                            25: WORLD_SERVICES[-1:], 35: PLANNER})
    assert lines[0].startswith(f"waiting for the world (hrc_world): "
                               f"{', '.join(WORLD_SERVICES[3:])}; for the robot planner "
                               f"(despot_pomdp): {PLANNER_LINK} (10 s;")
    assert lines[1].startswith(f"waiting for the world (hrc_world): {WORLD_SERVICES[-1]}; for "
                               f"the robot planner (despot_pomdp): {PLANNER_LINK} (20 s;")
    assert lines[2].startswith(f"waiting for the robot planner (despot_pomdp): {PLANNER_LINK} "
                               "(30 s;")
    assert lines[3].endswith("are up after 35 s: the loop starts (its first reset, then step 0)")
    assert len(lines) == 4


def test_a_caller_waits_without_a_timeout_and_a_stop_releases_it():
    up = set()
    wait = ServiceWait([("the world", ["/a"])], say=lambda _t: None, every=10.0, poll=0.01,
                       registered=lambda: set(up))
    threading.Thread(target=wait.run, daemon=True).start()
    assert wait.wait(0.2) is False                 # still waiting
    up.add("/a")
    assert wait.wait(5.0) is True and wait.ready

    stopped = ServiceWait([("the world", ["/a"])], say=lambda _t: None, poll=0.01,
                          registered=set)
    threading.Thread(target=stopped.run, daemon=True).start()
    threading.Timer(0.1, stopped.stop).start()
    with pytest.raises(ServiceUnavailable, match="stopped while waiting for the world: /a"):
        stopped.wait()


# -- the loop behind the gate, as hrc_human wires it ----------------------------------------------

class Gated:
    """A world, planner or executor fake whose every call first waits at the gate
    (hrc_human's RosWorld, LinkPlanner and RosExecutor call ServiceWait.wait first)."""

    def __init__(self, inner, gate: ServiceWait) -> None:
        self.inner = inner
        self.gate = gate

    def __getattr__(self, name):
        method = getattr(self.inner, name)
        if not callable(method):
            return method

        def gated(*args, **kwargs):
            self.gate.wait()
            return method(*args, **kwargs)
        return gated


@pytest.fixture
def gated_loop():
    up = set()
    lines = []
    gate = ServiceWait(STARTUP_SERVICES, say=lines.append, every=0.2, poll=0.01,
                       registered=lambda: set(up))
    loop = Loop(CoordinatorConfig(first_epoch=FIRST, max_steps=3))
    loop.runner.world = Gated(loop.world, gate)
    loop.runner.planner = Gated(loop.planner, gate)
    loop.runner.executor = Gated(loop.executor, gate)
    threading.Thread(target=gate.run, daemon=True).start()
    yield loop, gate, up, lines
    gate.stop()
    loop.close()


def test_step_0_waits_for_the_world_and_is_carried_out_once(gated_loop):
    loop, gate, up, lines = gated_loop
    loop.runner.mdp_connected("mdp")
    # A slow world: a second with nothing up, then the planner, then another second.
    time.sleep(1.0)
    up.update(PLANNER)
    time.sleep(1.0)
    assert loop.log.of("mdp_reset") == [], "the MDP was told to start before the world was up"
    assert loop.log.of("report") == [] and loop.log.of("refused") == []
    assert loop.world.calls == [] and loop.planner.calls == []
    assert loop.coordinator.phase == "resetting"
    assert any(t.startswith("waiting for the world (hrc_world): /hrc/world/reset") for t in lines)
    # The world comes up: one reset, then steps 0, 1, 2 of that epoch, each carried out once.
    up.update(WORLD_SERVICES)
    assert loop.runner.wait_until(
        lambda: any(d.episode_over for d in loop.log.of("step_done")), 10)
    assert [r.epoch for r in loop.log.of("mdp_reset")] == [FIRST]
    assert [(r.epoch, r.step) for r in loop.log.of("report")] == [(FIRST, 0), (FIRST, 1),
                                                                    (FIRST, 2)]
    assert not any(r.fault for r in loop.log.of("report"))
    assert loop.log.of("refused") == []
    acts = [c for c in loop.world.calls if c[0] == "act"]
    assert acts == [("act", "look_around"), ("act", "attempt_grasp"), ("act", "idle")]
    assert [c for c in loop.world.calls if c[0] == "reset"] == [("reset", False)]
    assert not any(level == "error" for level, _t in loop.log.of("note")), loop.log.of("note")
    assert lines[-1].startswith("The world (hrc_world) and the robot planner (despot_pomdp) are "
                                "up")


def test_a_reset_asked_for_while_waiting_joins_the_first_one(gated_loop):
    loop, gate, up, lines = gated_loop
    loop.runner.mdp_connected("mdp")
    answer = {}
    asker = threading.Thread(target=lambda: answer.update(r=loop.runner.reset("asked", 10)))
    asker.start()
    time.sleep(0.3)
    up.update(WORLD_SERVICES + PLANNER)
    asker.join(10)
    assert answer["r"][0] is True, answer
    assert loop.runner.wait_until(lambda: len(loop.log.of("report")) >= 1, 10)
    assert [r.epoch for r in loop.log.of("mdp_reset")] == [FIRST]
    assert [c for c in loop.world.calls if c[0] == "reset"] == [("reset", False)]
