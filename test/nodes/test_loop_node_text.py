"""What hrc_human's terminal and hrc_world's topics say, as a user reads them: the step block's
time counts from the episode's start (the message keeps the raw time), /hrc/world_state names
the robot's action as the step block does, and the world's services, once it ends, answer
that it is shutting down (what hrc_human reads as the run's end) instead of a fault."""
import pytest
import rospy
from std_srvs.srv import TriggerResponse

from ros_hrc import tasks
from ros_hrc.errors import WORLD_ENDING, StackEnding
from ros_hrc.msg import Status
from ros_hrc.nodes.common import ServiceUnavailable
from ros_hrc.nodes.human_node import format_step
from ros_hrc.nodes.loop_ports import world_call
from ros_hrc.nodes.world_node import (WINDOW_CLOSED, WorldEnd, robot_action_names,
                                      state_message, until_the_end)
from ros_hrc.world import WindowClosed


def a_step(sim_time, episode_start_time):
    status = Status(step=2, episode=2, human_action="graspAttempt", robot_observation="O11",
                    observation_bits=11, human_state="success", robot_state="S1",
                    robot_action="rIdle", object_holder="human", sim_time=sim_time,
                    episode_start_time=episode_start_time)
    return status


def test_the_step_block_counts_time_from_the_episode_start():
    status = a_step(sim_time=93.2, episode_start_time=88.48)
    block = format_step(status)
    assert "(t = 4.72 s simulated since the episode's start)" in block
    assert "93.20" not in block and status.sim_time == 93.2   # the message keeps the raw time


@pytest.mark.parametrize("task, world, named", [
    ("seed", "cancel_action", "rStop_all"), ("seed", "grasp", "rGrasp_obj"),
    ("seed", "point_to_obj", "rPoint_obj"), ("seed", "idle", "rIdle"),
    ("seed", "grasp_planning", "grasp_planning"),   # no seed action moves so: the world's name
    ("fabric", "grasp_planning", "graspPlanning"), ("fabric", "cancel_action", "cancel"),
    ("fabric", "idle", "idle"),
])
def test_world_state_names_the_robot_action_as_the_task_does(task, world, named):
    state = {"sim_time": 1.0, "object": {"position": [0, 0, 1], "orientation": [0, 0, 0, 1],
                                          "holder": "none", "on_belt": True, "left_belt": False},
             "human": {"action": "idle"}, "robot": {"action": world}, "belt_speed": 0.02,
             "predicates": dict.fromkeys(("is_ov", "is_oir", "is_ho", "is_a0", "is_a2",
                                          "is_h4"), False)}
    msg = state_message(state, rospy.Time(1), robot_action_names(tasks.get(task)))
    assert msg.robot_action == named


def test_the_world_answers_that_it_shuts_down_once_it_ends():
    end = WorldEnd()
    calls = []

    def act(request):
        calls.append(request)
        return TriggerResponse(True, "done")

    handle = until_the_end(act, end)
    assert handle("first").message == "done"
    end.begin("the node was asked to stop")
    with pytest.raises(rospy.ServiceException,
                       match=f"^{WORLD_ENDING}: the node was asked to stop$"):
        handle("second")
    assert calls == ["first"]   # the world was not touched again


def test_an_action_cut_short_by_the_closed_window_is_the_end_not_a_fault():
    end = WorldEnd()

    def act(_request):
        raise WindowClosed()

    with pytest.raises(rospy.ServiceException, match=f"^{WORLD_ENDING}: {WINDOW_CLOSED}$"):
        until_the_end(act, end)("grasp")
    assert end.why == WINDOW_CLOSED


def test_an_answer_made_while_the_world_ends_is_not_taken_for_the_world_s():
    end = WorldEnd()

    def act(_request):
        end.begin("the node was asked to stop")   # e.g. the action abandoned by close()
        return TriggerResponse(False, "human/grasp abandoned: the world was closed")

    with pytest.raises(rospy.ServiceException, match=WORLD_ENDING):
        until_the_end(act, end)("grasp")


def test_a_fault_of_a_running_world_stays_a_fault():
    def act(_request):
        raise ValueError("a bug")

    with pytest.raises(ValueError):
        until_the_end(act, WorldEnd())("grasp")


def test_hrc_human_reads_the_world_s_end_as_the_run_s_end_and_other_errors_as_faults():
    with pytest.raises(StackEnding):
        with world_call():
            raise ServiceUnavailable("service /robot/grasp failed: service [/robot/grasp] "
                                     "responded with an error: b'service cannot process "
                                     f"request: {WORLD_ENDING}: {WINDOW_CLOSED}'")
    with pytest.raises(ServiceUnavailable):
        with world_call():
            raise ServiceUnavailable("service /robot/grasp is not available: timeout")


def test_a_failed_robot_action_says_why_in_the_step_block():
    """The reason of a failed grasp (out of reach, how far) was only in a solver's log; the
    block said rGrasp_obj, then "on the belt"."""
    why = ("cannot grasp: the object is out of reach, 0.99 m from the right shoulder (the arm "
           "reaches 0.83 m)")
    status = a_step(sim_time=5.0, episode_start_time=1.0)
    status.robot_action, status.object_holder = "rGrasp_obj", "none"
    status.robot_result, status.robot_failed = why, True
    lines = format_step(status).splitlines()
    at = lines.index("robot action      : rGrasp_obj")
    assert lines[at + 1] == f"robot failed      : {why}"
    status.robot_failed = False           # one that worked: no such line
    assert not any(line.startswith("robot failed") for line in format_step(status).splitlines())


def test_the_step_report_carries_whether_the_robot_failed(monkeypatch):
    from ros_hrc.loop.effects import StepReport
    from ros_hrc.nodes.human_node import status_message

    monkeypatch.setattr(rospy.Time, "now", staticmethod(lambda: rospy.Time(1)))  # no master
    report = StepReport(epoch=1, episode=1, step=0, human_action="idle", human_state="s",
                        robot_action="rGrasp_obj", robot_acted=False,
                        robot_result="cannot grasp: the object is out of reach")
    assert status_message(report, "auto").robot_failed
    assert not status_message(StepReport(epoch=1, episode=1, step=0, human_action="idle",
                                         human_state="s"), "auto").robot_failed


def test_the_readme_s_example_block_is_the_first_step_s_as_printed():
    """The README showed "step 1" where the first block printed is step 0; its lines must be
    the block's, in the block's order."""
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    example = readme.split("Every step prints one block\nin the ROS terminal:\n\n```\n", 1)[1]
    example = example.split("```", 1)[0].splitlines()
    first = Status(step=0, episode=1, human_action="graspAttempt", robot_observation="O7",
                   observation_bits=7, robot_action="rGrasp_obj", belief_states=["S0"],
                   belief=[1.0], action_names=["rGrasp_obj", "rIdle"], action_values=[2.0, 1.0])
    printed = format_step(first).splitlines()
    assert example[0] == printed[0]
    assert [line.split(":")[0] for line in example[1:]] == \
        [line.split(":")[0] for line in printed[1:]]
