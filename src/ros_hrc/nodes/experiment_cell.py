"""The ROS side of one experiment cell: the node that resets the cell's stack and watches it.

:func:`drive_cell` is called by :func:`ros_hrc.experiment.stack.run_cell` in the cell's own
process, once ``hrc.launch`` has been started against the cell's own master. For each episode
it calls ``/hrc/reset``, reads the world's clock (``/hrc/world/state``), collects
``/hrc/status`` until the episode is over, scores it and hands the row over.
"""
from __future__ import annotations

import subprocess
import threading
import time
from pathlib import Path
from typing import Callable, Optional

import rospy
from std_srvs.srv import Trigger

from ros_hrc.experiment.episode import end_reason, score_episode, step_rows
from ros_hrc.experiment.results import EpisodeRow
from ros_hrc.experiment.stack import CellFailed, CellSpec, stop_launched
from ros_hrc.msg import Status
from ros_hrc.nodes.common import init_node_when_master_is_up
from ros_hrc.pomdp.model import Model
from ros_hrc.srv import GetWorldState


class StatusInbox:
    """The /hrc/status messages of the episode under way."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.steps: list = []
        self.since: Optional[float] = None   # simulated time the episode started at
        self.last_seen = time.monotonic()

    def begin(self, sim_time: float) -> None:
        with self.cond:
            self.steps, self.since = [], sim_time

    def on_status(self, msg) -> None:
        with self.cond:
            self.last_seen = time.monotonic()
            if self.since is None or msg.sim_time < self.since:
                return   # from before the reset
            if not self.steps and msg.step != 0:
                return   # a step under way at the reset, refused or late: not this episode
            self.steps.append(msg)
            self.cond.notify_all()

    def wait_for_step(self, count: int, timeout: float) -> list:
        """The episode's steps once there are at least ``count``; raises CellFailed after
        ``timeout`` wall seconds without any status."""
        with self.cond:
            while len(self.steps) < count:
                if time.monotonic() - self.last_seen > timeout:
                    raise CellFailed(f"no step for {timeout:.0f} s")
                self.cond.wait(1.0)
            return list(self.steps)


def drive_cell(spec: CellSpec, model: Model, proc: subprocess.Popen,
               deliver: Callable[[EpisodeRow, list], None], name: str, log_dir: Path) -> int:
    """Run ``spec``'s episodes on the stack ``proc`` (``hrc.launch``, already started):
    reset, watch, score, ``deliver`` each. Returns how many were delivered."""
    init_node_when_master_is_up("hrc_experiment_cell", wait=120.0)
    inbox = StatusInbox()
    rospy.Subscriber("/hrc/status", Status, inbox.on_status, queue_size=1000)
    bag = None
    if spec.record_bag:
        bag = subprocess.Popen(["rosbag", "record", "-q", "-O", str(log_dir / f"{name}.bag"),
                                "/hrc/status"], stdin=subprocess.DEVNULL,
                               stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                               start_new_session=True)
    try:
        for service in ("/hrc/reset", "/hrc/world/state"):
            try:
                rospy.wait_for_service(service, timeout=180.0)
            except rospy.ROSException as exc:
                raise CellFailed(f"{name}: the stack did not come up ({exc}); see "
                                 f"{log_dir / (name + '.log')}") from exc
        reset = rospy.ServiceProxy("/hrc/reset", Trigger, persistent=True)
        world = rospy.ServiceProxy("/hrc/world/state", GetWorldState, persistent=True)
        delivered = 0
        for episode in spec.episodes:
            if proc.poll() is not None:
                raise CellFailed(f"{name}: hrc.launch exited ({proc.returncode})")
            started = time.monotonic()
            answer = reset()
            if not answer.success:
                raise CellFailed(f"{name}: /hrc/reset failed: {answer.message}")
            start_sim = world().state.sim_time
            inbox.begin(start_sim)
            count = 1
            while True:
                steps = inbox.wait_for_step(count, spec.episode_timeout)
                reason = end_reason(steps, spec.step_limit)
                if reason is not None:
                    break
                count = len(steps) + 1
            key = (spec.human_model, spec.robot_policy, spec.seed, episode)
            row = score_episode(key, steps, reason, start_sim, model,
                                time.monotonic() - started)
            deliver(row, step_rows(key, steps))
            delivered += 1
        return delivered
    finally:
        if bag is not None:
            stop_launched(bag)
        rospy.signal_shutdown("cell done")
