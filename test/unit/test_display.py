"""What a watcher is shown of a step (ros_hrc.loop.display) and the agents' descriptions for
RViz (ros_hrc.description): no ROS, no PyBullet."""
from types import SimpleNamespace
import xml.etree.ElementTree as ElementTree

from ros_hrc.description import main as description_main
from ros_hrc.description import prefixed_description
from ros_hrc.loop.display import belief_bars, status_lines

STATES = ("S0", "S1", "S2", "S3", "S4", "S5", "S6")


def status(**over):
    values = dict(step=3, episode=2, human_action="graspAttempt", human_state="failed_to_grasp",
                  observation_bits=7, robot_observation="O7", robot_action="rGrasp_obj",
                  robot_state="S2", belief_states=STATES,
                  belief=(0.05, 0.0, 0.6, 0.25, 0.1, 0.0, 0.0), object_holder="none",
                  episode_over=False, end_reason="")
    values.update(over)
    return SimpleNamespace(**values)


def test_the_lines_say_the_step_both_agents_and_the_belief_in_help():
    lines = status_lines(status())
    assert lines[0] == "episode 2, step 3"
    assert lines[1] == "human: graspAttempt -> failed_to_grasp"
    assert "sees O7 (visible+in_range+grasp_attempt)" in lines[2] and "does rGrasp_obj" in lines[2]
    assert "true state S2" in lines[2]
    assert lines[3] == "P(human needs help) = 0.95; nobody holds the object"
    over = status_lines(status(object_holder="robot", episode_over=True, end_reason="success"))
    assert over[3].endswith("the robot holds the object; episode over: success")


def test_the_bars_mark_the_true_state_and_the_states_of_need():
    bars = belief_bars(status())
    assert [b.state for b in bars] == list(STATES)
    assert [b.true_state for b in bars] == [s == "S2" for s in STATES]
    assert [b.needs_help for b in bars] == [s in ("S2", "S3", "S4", "S5") for s in STATES]
    assert bars[2].probability == 0.6


def test_each_agents_links_are_prefixed_and_its_joints_kept(capsys):
    urdf = ('<robot name="r"><link name="base"/><link name="arm"/>'
            '<joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/>'
            '</joint></robot>')
    root = ElementTree.fromstring(prefixed_description(urdf, "robot"))
    assert [link.get("name") for link in root.iter("link")] == ["robot/base", "robot/arm"]
    joint = root.find("joint")
    assert joint.get("name") == "shoulder"
    assert (joint.find("parent").get("link"), joint.find("child").get("link")) == \
        ("robot/base", "robot/arm")
    assert description_main(["human", "__name:=x"]) == 0
    shipped = ElementTree.fromstring(capsys.readouterr().out)
    assert all(l.get("name").startswith("human/") for l in shipped.iter("link"))
    assert description_main(["dog"]) == 2


def test_snapshot_names_differ_across_runs_and_within_one():
    from ros_hrc.nodes.world_node import snapshot_name

    names = {snapshot_name("20261123-160436-4242", n, 12.5) for n in (1, 2)}
    names.add(snapshot_name("20261123-160437-4243", 1, 12.5))
    assert len(names) == 3
    assert snapshot_name("20261123-160436-4242", 3, 12.5) == \
        "world_20261123-160436-4242_0003_00012.500s.png"
