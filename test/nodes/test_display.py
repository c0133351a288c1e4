"""What a watcher is shown of a step (ros_hrc.loop.display) and the agents' descriptions for
RViz (ros_hrc.commands.description): no ROS, no PyBullet."""
from types import SimpleNamespace
import xml.etree.ElementTree as ElementTree

from ros_hrc.commands.description import main as description_main
from ros_hrc.commands.description import prefixed_description
from ros_hrc.loop.display import StepCaption, belief_bars, status_lines

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


def test_the_caption_names_the_step_being_played_then_its_outcome():
    """Over the life of a step: the action under way, its outcome, the step's report; the
    next step's action replaces the last report at once (the robot never reaches under the
    last step's "does rIdle")."""
    caption = StepCaption()
    assert caption.reset() == ["episode 1: the world was reset; waiting for step 0"]
    lines = caption.action_started("human", "attempt_grasp")
    assert lines == ["episode 1, step 0: playing", "human: tries to grasp the object ...",
                     "robot: waits for the human"]
    lines = caption.action_finished("human", "attempt_grasp", False, "missed the object by 0.10 m")
    assert lines[1:] == ["human: tries to grasp the object -> missed the object by 0.10 m",
                         "robot: decides"]
    assert caption.action_started("robot", "grasp")[2] == "robot: reaches for the object ..."
    lines = caption.action_finished("robot", "grasp", False, "cannot grasp: out of reach")
    assert lines[2] == "robot: reaches for the object -> cannot grasp: out of reach"
    report = status(step=0, episode=1, robot_action="rGrasp_obj",
                    robot_result="cannot grasp: out of reach")
    done = caption.step_done(report)
    assert done[0] == "episode 1, step 0: done" and "does rGrasp_obj" in done[2]
    assert done[3] == "  -> cannot grasp: out of reach"
    assert done[1:3] + done[4:] == status_lines(report)[1:]

    # The next step: the robot idled in step 0, and now it points, under its own caption.
    caption.step_done(status(step=0, episode=1, robot_action="rIdle"))
    caption.action_started("human", "idle")
    caption.action_finished("human", "idle", True, "idle at the belt")
    lines = caption.action_started("robot", "point_to_obj")
    assert lines == ["episode 1, step 1: playing", "human: stays idle -> idle at the belt",
                     "robot: points at the object ...",
                     "before this step: P(human needs help) = 0.95; nobody holds the object"]
    assert not any("rIdle" in line for line in lines)


def test_the_caption_clears_on_reset_and_follows_a_report_that_comes_late():
    caption = StepCaption()
    caption.reset()
    over = caption.step_done(status(step=4, episode=1, object_holder="robot", episode_over=True,
                                    end_reason="success"))
    assert over[-1].endswith("episode over: success")
    lines = caption.reset()
    assert lines == ["episode 2: the world was reset; waiting for step 0"]
    assert caption.reset() == lines   # a second reset (the loop's early one) names no new episode
    # Step 0's report reaches the world after step 1's human action began: step 1 stays shown.
    caption.action_started("human", "grasp")
    caption.action_finished("human", "grasp", True, "grasped the object")
    started = caption.action_started("human", "walk_away")
    assert started[0] == "episode 2, step 1: playing"
    late = caption.step_done(status(step=0, episode=2))
    assert late[0] == "episode 2, step 1: playing" and late[1] == "human: walks away ..."
    assert caption.action_finished("human", "walk_away", True, "walked")[1] == \
        "human: walks away -> walked"
    failed = caption.step_done(status(step=1, episode=2, fault="the robot's decision timed out"))
    assert failed[0] == "episode 2, step 1: failed (the robot's decision timed out)"
    assert caption.lines() == failed


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


def test_rviz_shows_the_caption_and_a_reset_clears_the_last_episode():
    from ros_hrc.loop.display import is_reset_caption
    from ros_hrc.nodes.viz_node import status_markers

    markers = status_markers(status(), "world", (0, 0, 0), 0.1, 0.5, (0, 0, 2),
                             caption="episode 2, step 4: playing\nhuman: walks away ...")
    assert next(m for m in markers.markers if m.ns == "step").text.startswith("episode 2, step 4: playing")
    plain = status_markers(status(), "world", (0, 0, 0), 0.1, 0.5, (0, 0, 2))
    assert next(m for m in plain.markers if m.ns == "step").text == "\n".join(status_lines(status()))
    caption = StepCaption()
    assert is_reset_caption("\n".join(caption.reset()))
    assert not is_reset_caption("\n".join(caption.action_started("human", "grasp")))


def test_fabric_s_grasp_planning_has_words_of_its_own():
    caption = StepCaption()
    caption.reset()
    caption.action_started("human", "attempt_grasp")
    caption.action_finished("human", "attempt_grasp", False, "missed")
    assert caption.action_started("robot", "grasp_planning")[2] == \
        "robot: plans a grasp over the object ..."


def test_a_fabric_step_is_shown_in_fabric_s_words():
    """The task is the one whose robot states the belief is over: fabric's bits and its
    needs-help states (before, the seed's: 'has_object', and no help believed at all)."""
    from ros_hrc import tasks

    fabric = tasks.get("fabric").robot_states
    belief = [0.0] * len(fabric)
    belief[fabric.index("NeedsHelp")], belief[fabric.index("TaskHuman")] = 0.7, 0.3
    step = status(observation_bits=8 | 2 | 1, robot_observation="O8", robot_state="NeedsHelp",
                  belief_states=fabric, belief=belief, robot_action="grasp")
    lines = status_lines(step)
    assert "(visible+in_range+object_taken)" in lines[2]
    assert lines[3].startswith("P(human needs help) = 0.70")
    assert [b.state for b in belief_bars(step) if b.needs_help] == [
        "MayNotBeCapable", "MayBeTired", "NoFocus", "NeedsToBeReminded", "NeedsHelp"]
