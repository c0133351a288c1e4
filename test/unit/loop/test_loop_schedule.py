"""The episode schedule of the coordinator (loop/schedule.py) alone: which episode a reset
starts, why an episode ends, and what follows its end."""
import pytest

from ros_hrc.loop.config import CoordinatorConfig
from ros_hrc.loop.effects import StepReport
from ros_hrc.loop.schedule import CONTINUE, RESET, WAIT, Episodes
from ros_hrc.streams import EpisodeSchedule


def report(step=0, holder="none", left=False, state="evaluating", sim_time=0.0):
    return StepReport(epoch=1, episode=1, step=step, human_action="lookAround",
                      human_state=state, object_holder=holder, object_left_belt=left,
                      sim_time=sim_time)


def test_live_episodes_count_up_from_one_with_every_reset_that_works():
    e = Episodes(CoordinatorConfig())
    assert e.next() == 1
    assert [e.start(t) for t in (0.5, 9.0)] == [1, 2] and e.start_time == 9.0


def test_a_schedule_plays_its_episodes_in_order_and_one_cut_short_again():
    e = Episodes(CoordinatorConfig(episodes=EpisodeSchedule.parse("5,7")))
    assert e.start(0.0) == 5
    assert e.next() == 5                 # not ended: a reset plays it again, whole
    assert e.step_ended("success") == (False, True)
    assert e.start(0.0) == 7
    played_out, stops = e.step_ended("step_limit")
    assert played_out and stops and e.next() is None


@pytest.mark.parametrize("config, step, why", [
    (dict(), report(holder="robot"), "success"),
    (dict(), report(left=True), "object_left_belt"),
    (dict(), report(state="success"), "human_goal"),
    (dict(end_on_goal=False), report(state="success"), ""),
    (dict(tasks=2, task_timeout=10.0), report(sim_time=11.0), "task_timeout"),
    (dict(max_steps=3), report(step=2), "step_limit"),
    (dict(max_steps=3), report(step=1), ""),
])
def test_why_an_episode_ends(config, step, why):
    assert Episodes(CoordinatorConfig(**config)).end_reason(step) == why


@pytest.mark.parametrize("policy, then", [("wait", WAIT), ("reset", RESET),
                                          ("continue", CONTINUE)])
def test_an_episodes_end_is_followed_as_on_episode_end_says(policy, then):
    e = Episodes(CoordinatorConfig(on_episode_end=policy))
    e.start(0.0)
    played_out, stops = e.step_ended("success")
    assert stops == (policy != "continue")
    what, line = e.after_end("success", 4, played_out)
    assert what == then and line.startswith("episode 1 over (success) after 4 steps: ")
    # continue: the end is reported once, stepping goes on until the next reset
    assert e.end_reason(report(holder="human")) == ("" if policy == "continue" else "success")
    e.reset_begins()
    assert e.end_reason(report(holder="human")) == "success"


def test_after_the_schedules_last_episode_the_loop_waits_whatever_the_policy():
    e = Episodes(CoordinatorConfig(on_episode_end="reset", episodes=EpisodeSchedule.parse("3")))
    e.start(0.0)
    played_out, _ = e.step_ended("success")
    what, line = e.after_end("success", 1, played_out)
    assert what == WAIT and "the episodes asked for (3) are all played" in line
