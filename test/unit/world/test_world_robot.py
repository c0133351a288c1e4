"""The robot points, grasps what it can reach, refuses what it cannot, stops and resets."""
import math

import numpy as np
import pytest

from ros_hrc.world import World, WorldConfig
from ros_hrc.world.geometry import angle_between
from ros_hrc.world.object import ObjectConfig


@pytest.fixture
def near_robot():
    """The object placed on the belt in front of the robot, belt stopped."""
    with World(WorldConfig(belt_speed=0.0, work_object=ObjectConfig(start=(0.3, 0.0)))) as world:
        yield world


def test_robot_grasp_takes_the_object_and_lifts_it(near_robot):
    outcome = near_robot.run("robot", "grasp")
    assert outcome.success, outcome.message
    assert outcome.duration >= 1.0
    assert near_robot.object.holder == "robot" and not near_robot.query("is_ho").value
    assert near_robot.object.position()[2] > near_robot.conveyor.config.surface_height + 0.1
    assert "robot holds" in near_robot.query("is_ho").message
    refused = near_robot.run("human", "grasp")
    assert not refused.success and "robot holds" in refused.message


def test_robot_grasp_out_of_reach_fails_without_taking_it(world):
    outcome = world.run("robot", "grasp")
    assert not outcome.success and "out of reach" in outcome.message
    assert world.object.holder == "none"


def test_robot_cannot_take_the_object_from_the_human(world):
    world.run("human", "grasp")
    outcome = world.run("robot", "grasp")
    assert not outcome.success and "human holds" in outcome.message


def test_point_to_obj_aims_the_gripper_at_the_object(world):
    outcome = world.run("robot", "point_to_obj")
    assert outcome.success and outcome.duration >= 1.0
    tool = world.robot.tool_position()
    _, palm = world.robot.link_frame("r_gripper_palm_link")
    aim = angle_between(palm[:, 0], world.object.position() - tool)
    assert math.degrees(aim) < 15.0


def test_cancel_stops_a_grasp_mid_way_and_holds_still(near_robot):
    ticket = near_robot.submit("robot", "grasp")
    near_robot.advance(0.5)
    cancel = near_robot.run("robot", "cancel_action")
    assert ticket.done() and not ticket.outcome.success and "interrupted" in ticket.outcome.message
    assert cancel.success and "cancelled grasp" in cancel.message
    held = near_robot.robot.tool_position()
    near_robot.advance(0.5)
    assert np.allclose(near_robot.robot.tool_position(), held, atol=0.01)
    assert near_robot.object.holder == "none"


def test_robot_reset_returns_a_held_object_to_the_belt_start(near_robot):
    near_robot.run("robot", "grasp")
    outcome = near_robot.run("robot", "reset")
    assert outcome.success and near_robot.object.holder == "none"
    assert np.allclose(near_robot.object.position(), near_robot.object.start_position, atol=2e-3)
    rest = near_robot.robot.positions(["r_shoulder_lift_joint", "torso_lift_joint"])
    assert rest["torso_lift_joint"] == pytest.approx(0.30, abs=1e-6)


def test_a_refused_grasp_reaches_towards_the_object_and_stops_short(world):
    """A watcher sees the robot try: the gripper moves towards the object, stops short of it
    (it never closes on it), and the arm goes back to rest."""
    start = world.robot.tool_position()
    target = world.object.position()
    ticket = world.submit("robot", "grasp")
    nearest, path = np.linalg.norm(start - target), []
    while not ticket.done():
        world.step()
        tool = world.robot.tool_position()
        path.append(float(np.linalg.norm(tool - start)))
        nearest = min(nearest, float(np.linalg.norm(tool - world.object.position())))
    outcome = ticket.outcome
    assert not outcome.success and "out of reach" in outcome.message
    initial = float(np.linalg.norm(start - target))
    assert nearest < initial - 0.2, f"the gripper came no nearer than {nearest:.2f} m (from {initial:.2f} m)"
    assert nearest > world.robot.config.grasp_tolerance
    assert max(path) > 0.2   # a reach a person sees, not a twitch
    assert np.linalg.norm(world.robot.tool_position() - start) < 0.01   # back at rest
    assert world.object.holder == "none"


# -- planning a grasp (FABRIC's graspPlanning: /robot/grasp_planning) --------------------------
def _pregrasp_gap(world):
    return world.robot.tool_position() - world.object.position()


def test_grasp_planning_opens_the_gripper_over_where_the_belt_brings_the_object():
    with World(WorldConfig(belt_speed=0.05, work_object=ObjectConfig(start=(0.0, 0.0)))) as w:
        predicted = w.predict_object(w.robot.plan_lead)
        assert predicted[0] == pytest.approx(w.object.position()[0] + 0.05 * w.robot.plan_lead)
        outcome = w.run("robot", "grasp_planning")
        assert outcome.success and "ready to grasp" in outcome.message, outcome.message
        assert outcome.duration == pytest.approx(w.robot.config.reach_time, abs=1 / 60)
        # the belt brought the object where it was predicted, under the open gripper
        assert np.allclose(w.object.position(), predicted, atol=0.01)
        gap = _pregrasp_gap(w)
        assert np.linalg.norm(gap) == pytest.approx(w.robot.config.approach, abs=0.01)
        assert gap[2] > 0.05                      # above it
        assert w.robot.commanded["r_gripper_l_finger_joint"] > 0.04   # open
        assert w.object.holder == "none"          # no grasp
        assert w.state()["robot"]["action"] == "grasp_planning"
        assert w.run("robot", "grasp").success    # a grasp goes on from the pre-grasp pose


def test_grasp_planning_aims_at_the_end_stop_where_the_belt_stops_the_object():
    with World(WorldConfig(belt_speed=0.2, work_object=ObjectConfig(start=(0.6, 0.0)))) as w:
        stop = w.conveyor.stop_x - w.object.config.size / 2
        assert w.predict_object(10.0)[0] == pytest.approx(stop)
        outcome = w.run("robot", "grasp_planning")
        assert outcome.success, outcome.message
        assert w.robot.tool_position()[0] == pytest.approx(stop, abs=0.01)   # straight above
        assert _pregrasp_gap(w)[2] == pytest.approx(w.robot.config.approach, abs=0.01)


def test_grasp_planning_out_of_reach_stretches_towards_the_object_and_says_so(world):
    start = world.robot.tool_position()
    outcome = world.run("robot", "grasp_planning")
    assert not outcome.success and "out of reach" in outcome.message, outcome.message
    assert world.object.holder == "none"
    target = world.predict_object(0.0)
    assert np.linalg.norm(world.robot.tool_position() - target) < \
        np.linalg.norm(start - target) - 0.2


@pytest.mark.parametrize("holder", ["human", "robot"])
def test_grasp_planning_is_refused_while_someone_holds_the_object(holder):
    with World(WorldConfig(belt_speed=0.0, work_object=ObjectConfig(start=(0.0, 0.0)))) as w:
        assert w.run(holder, "grasp").success          # both reach it there
        outcome = w.run("robot", "grasp_planning")
        assert not outcome.success and f"the {holder} holds the object" in outcome.message
        assert w.object.holder == holder


def test_cancel_stops_a_grasp_planning_mid_way(near_robot):
    ticket = near_robot.submit("robot", "grasp_planning")
    near_robot.advance(0.4)
    assert near_robot.run("robot", "cancel_action").success
    assert ticket.done() and "interrupted" in ticket.outcome.message
