"""Each human action changes the predicates as a person would expect."""
import math

import numpy as np

from ros_hrc.world import PREDICATES, World, WorldConfig
from ros_hrc.world.object import ObjectConfig


def predicates(world):
    return {name: world.query(name).value for name in PREDICATES}


def test_at_the_start_the_object_is_seen_and_in_reach_and_the_human_is_idle(world):
    assert predicates(world) == {"is_ov": True, "is_oir": True, "is_ho": False,
                                 "is_a0": False, "is_a2": True, "is_h4": False}
    assert "field of view" in world.query("is_ov").message


def test_walk_away_takes_the_human_out_of_reach_and_sight(world):
    outcome = world.run("human", "walk_away")
    assert outcome.success and outcome.duration >= 1.0
    assert "away" in outcome.message
    state = predicates(world)
    assert not state["is_oir"] and not state["is_ov"] and not state["is_a2"]
    assert "out of reach" in world.query("is_oir").message
    assert world.run("human", "walk_away").message == "already away from the belt"


def test_a_human_who_stays_away_lets_the_belt_run_for_his_away_time():
    """away_time (fabric's world): a walk away while away is time spent away, so a human who
    waits in recovery sees the object travel on; 0 (the seed's) takes no time."""
    from ros_hrc.world.human import HumanConfig
    with World(WorldConfig(human=HumanConfig(away_time=0.8))) as world:
        world.run("human", "walk_away")
        x = world.object.position()[0]
        outcome = world.run("human", "walk_away")
        assert outcome.success and outcome.message == "stays away from the belt for 0.8 s"
        assert outcome.duration >= 0.75 and not world.human.at_station()
        assert world.object.position()[0] > x + 0.01   # 0.02 m/s for 0.8 s


def test_look_around_loses_sight_of_the_object_and_finds_it_again(still_world):
    ticket = still_world.submit("human", "look_around")
    seen = []
    while not ticket.done():
        still_world.step()
        seen.append(still_world.query("is_ov").value)
    assert seen[0] and not all(seen) and seen[-1]
    assert ticket.outcome.success and "back in view" in ticket.outcome.message
    assert ticket.outcome.duration >= 2.0
    assert still_world.query("is_a2").value  # looking around is over: idle again


def test_warn_robot_raises_the_left_arm(world):
    head_height = world.human.link_frame("head")[0][2]
    outcome = world.run("human", "warn_robot")
    assert outcome.success and "left arm" in outcome.message
    assert world.human.hand_position("left")[2] > head_height + 0.2
    assert world.query("is_h4").value and not world.query("is_a2").value
    world.run("human", "idle")  # relaxing ends the warning
    assert not world.query("is_h4").value and world.query("is_a2").value


def test_attempt_grasp_reaches_and_misses(still_world):
    ticket = still_world.submit("human", "attempt_grasp")
    closest = math.inf
    while not ticket.done():
        still_world.step()
        for side in ("left", "right"):
            gap = np.linalg.norm(still_world.human.hand_position(side) - still_world.object.position())
            closest = min(closest, gap)
    assert ticket.outcome.success and "missed" in ticket.outcome.message
    assert 0.05 < closest < 0.2  # the hand got near the object, but not on it
    assert still_world.query("is_a0").value and not still_world.query("is_ho").value
    assert not still_world.query("is_a2").value


def test_grasp_in_reach_holds_the_object_and_it_moves_with_the_hand(world):
    outcome = world.run("human", "grasp")
    assert outcome.success, outcome.message
    assert world.query("is_ho").value and world.object.holder == "human"
    assert not world.query("is_a0").value
    assert world.object.position()[2] > world.conveyor.config.surface_height + 0.2  # lifted
    world.run("human", "walk_away")
    assert world.query("is_ho").value  # carried along
    assert world.object.position()[1] < -1.5


def test_grasp_out_of_reach_fails_and_says_why():
    far = ObjectConfig(start=(0.55, 0.0))
    with World(WorldConfig(belt_speed=0.0, work_object=far)) as world:
        assert not world.query("is_oir").value
        outcome = world.run("human", "grasp")
        assert not outcome.success
        assert "out of reach" in outcome.message and "shoulder" in outcome.message
        assert not world.query("is_ho").value and world.query("is_a0").value


def test_grasp_after_walking_away_walks_back_first(world):
    world.run("human", "walk_away")
    outcome = world.run("human", "grasp")
    assert outcome.success and outcome.message.startswith("walked back")
    assert world.human.at_station()


def test_human_reset_restores_the_human_and_the_object(world):
    world.run("human", "grasp")
    world.run("human", "walk_away")
    outcome = world.run("human", "reset")
    assert outcome.success
    assert predicates(world) == {"is_ov": True, "is_oir": True, "is_ho": False,
                                 "is_a0": False, "is_a2": True, "is_h4": False}
    assert np.allclose(world.object.position(), world.object.start_position, atol=2e-3)


def test_an_occluder_on_the_line_of_sight_hides_the_object(still_world):
    client = still_world.client
    eyes, _ = still_world.human.link_frame("eyes")
    middle = (eyes + still_world.object.position()) / 2
    wall = client.createCollisionShape(client.GEOM_BOX, halfExtents=[0.2, 0.02, 0.2])
    client.createMultiBody(0, wall, basePosition=middle.tolist())
    reading = still_world.query("is_ov")
    assert not reading.value and "hidden behind" in reading.message
