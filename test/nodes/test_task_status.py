"""/hrc/task_status (ros_hrc/TaskStatus) and the terminal's line per task: every field of the
message is filled from the coordinator's task report (none left at its default by
omission), and hrc_human's terminal publishes it and says it in one line."""
import rospy

from ros_hrc.loop.display import task_line
from ros_hrc.loop.effects import TaskStatusReport
from ros_hrc.msg import TaskStatus
from ros_hrc.nodes import human_node

REPORT = TaskStatusReport(
    task_index=3, tasks=5, episode=7, epoch=41, human_model="expert_tired_noncollaborative",
    true_type="expert_tired_noncollaborative", outcome="success", who_succeeded="robot",
    warnings=1, preemptions=1, steps=12, duration=21.4, utility=0.13, end_reason="success",
    selector="bpr", policy="policy3", robot_model="/m/policy3.pomdpx",
    type_names=("expert_tired_noncollaborative", "beginner_tired_collaborative", "b", "c"),
    type_belief=(0.71, 0.2, 0.05, 0.04), estimation_correct=True, total_disc_reward=4.5,
    signature=(1, 17, 33))


class Publisher:
    def __init__(self):
        self.sent = []

    def publish(self, msg):
        self.sent.append(msg)


def test_every_task_status_field_comes_from_the_report(monkeypatch):
    monkeypatch.setattr(rospy.Time, "now", staticmethod(lambda: rospy.Time(1)))
    msg = human_node.task_status_message(REPORT)
    for name in TaskStatus.__slots__[1:]:
        expected = getattr(REPORT, name)
        got = getattr(msg, name)
        assert (list(got) if isinstance(expected, tuple) else got) == (
            list(expected) if isinstance(expected, tuple) else expected), name


def test_the_terminal_publishes_the_task_and_says_it_in_one_line(monkeypatch):
    monkeypatch.setattr(rospy.Time, "now", staticmethod(lambda: rospy.Time(1)))
    said = []
    monkeypatch.setattr(rospy, "loginfo", lambda fmt, *args: said.append(fmt % args))
    steps, task_statuses = Publisher(), Publisher()
    terminal = human_node.Terminal(steps, "auto", True, None, task_statuses)
    terminal.task_ended(REPORT)
    assert [m.task_index for m in task_statuses.sent] == [3] and not steps.sent
    assert said == [
        "hrc_human: task 3/5 (expert_tired_noncollaborative): success (robot) in 12 steps, "
        "21.4 s, utility 0.13, 1 warning, 1 pre-emption; policy policy3; belief: "
        "expert_tired_noncollaborative 0.71, beginner_tired_collaborative 0.20, b 0.05 ..."]


def test_a_task_without_a_robot_report_says_so_by_leaving_the_policy_out():
    bare = TaskStatusReport(task_index=1, tasks=2, episode=1, epoch=1, human_model="tired",
                            true_type="tired", outcome="fail", who_succeeded="", warnings=0,
                            preemptions=0, steps=1, duration=69.0, utility=-0.43,
                            end_reason="object_left_belt")
    assert task_line(bare) == ("task 1/2 (tired): fail in 1 step, 69.0 s, utility -0.43")
