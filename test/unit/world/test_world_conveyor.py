"""The belt carries the object on its surface, out of the human's reach, up to the end stop."""
import numpy as np
import pytest

from ros_hrc.world import World, WorldConfig


def test_belt_carries_the_object_at_its_speed():
    with World(WorldConfig(belt_speed=0.2)) as world:
        start = world.object.position()
        world.advance(1.0)
        moved = world.object.position() - start
    assert moved[0] == pytest.approx(0.2, abs=0.02)
    assert abs(moved[1]) < 0.005 and abs(moved[2]) < 0.005


def test_a_stopped_belt_leaves_the_object_where_it_is(still_world):
    start = still_world.object.position()
    still_world.advance(1.0)
    assert np.allclose(still_world.object.position(), start, atol=0.002)


def test_speed_can_change_while_running(still_world):
    still_world.set_belt_speed(-0.1)
    start = still_world.object.position()
    still_world.advance(0.5)
    assert still_world.object.position()[0] - start[0] == pytest.approx(-0.05, abs=0.01)


def test_object_passes_out_of_reach_and_waits_at_the_end_stop():
    with World(WorldConfig(belt_speed=0.6)) as world:
        assert world.query("is_oir").value
        world.advance(2.0)   # about 1.2 m downstream: past the human
        assert not world.query("is_oir").value
        world.advance(2.0)   # long enough to reach the end of the belt
        x, _, z = world.object.position()
        half = world.object.config.size / 2
        assert x == pytest.approx(world.conveyor.stop_x - half, abs=0.01)
        assert world.conveyor.is_on_belt(world.object.position())
        world.advance(0.5)   # it stays there, the belt slipping under it
        assert world.object.position()[0] == pytest.approx(x, abs=0.005)
        assert world.robot.can_reach()  # the robot can still take it from the end of the belt


def test_reset_puts_the_object_back_at_the_start(world):
    world.advance(2.0)
    world.reset()
    assert np.allclose(world.object.position(), world.object.start_position, atol=2e-3)


def test_the_object_at_the_belts_end_is_reported_as_left_the_belt():
    """The task's end (FABRIC's GlobalFail, the seed's missed object): world.state() (and so
    /hrc/world_state's object_left_belt) says the object left the belt once nobody took it
    before the belt's end, not before, and never while someone holds it."""
    with World(WorldConfig(belt_speed=0.6)) as world:
        assert not world.state()["object"]["left_belt"]
        world.advance(2.0)
        assert not world.state()["object"]["left_belt"]   # past the human, still on its way
        world.advance(2.0)
        state = world.state()["object"]
        assert state["left_belt"] and state["holder"] == "none" and state["on_belt"]
        assert world.run("robot", "grasp").success          # the robot takes it from the end
        assert not world.state()["object"]["left_belt"]
