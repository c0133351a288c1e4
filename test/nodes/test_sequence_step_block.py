"""A sequence's step block in hrc_human's terminal (issue #41, newcomer item 7): fabric's
``robot belief`` line fits an 80-column terminal (it was about 230 characters), and the policy
the selector chose shows at the task's start (its first step's block, and /hrc/status on
every step), not only in the line at its end."""
import rospy

from ros_hrc import tasks
from ros_hrc.loop.effects import Decision
from ros_hrc.msg import Status
from ros_hrc.nodes.human_node import Terminal, format_step
from loop_fakes import Driver

FABRIC = tasks.get("fabric")
BELIEF = [0.01, 0.05, 0.201, 0.02, 0.03, 0.612, 0.04, 0.012, 0.01, 0.005, 0.01]


def fabric_step(step=0, policy="policy3"):
    return Status(step=step, episode=1, human_action="lookAround", human_state="Evaluating",
                  observation_bits=3, robot_observation="O3", robot_state="NeedsHelp",
                  robot_action="point", belief_states=list(FABRIC.robot_states),
                  belief=BELIEF, policy=policy)


def test_fabric_s_belief_line_fits_a_terminal():
    block = format_step(fabric_step(), FABRIC).splitlines()
    line = next(line for line in block if line.startswith("robot belief"))
    assert len(line) <= 80
    assert line == "robot belief      : NeedsHelp 0.612 | MayBeTired 0.201 | +9 others 0.187"


def test_the_task_s_first_step_shows_the_policy_its_selector_chose():
    block = format_step(fabric_step(), FABRIC).splitlines()
    at = block.index("robot policy      : policy3 (decides this task)")
    assert block[at + 1] == "robot action      : point"
    later = format_step(fabric_step(step=4), FABRIC)
    assert "robot policy" not in later
    assert "robot policy" not in format_step(fabric_step(policy=""), FABRIC)


def test_every_step_s_status_carries_the_policy_from_the_decision(monkeypatch):
    monkeypatch.setattr(rospy.Time, "now", staticmethod(lambda: rospy.Time(1)))
    driver = Driver()
    driver.ready()
    report = driver.play_step(decision=Decision("rPoint_obj", policy="policy3")).report
    assert report.policy == "policy3"
    published = []

    class Publisher:
        def publish(self, msg):
            published.append(msg)

    Terminal(Publisher(), "auto", False).step(report)
    assert published[0].policy == "policy3"
