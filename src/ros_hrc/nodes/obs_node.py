"""hrc_obs: the observer's link to the robot planner, an adapter of the loop's coordinator.

The coordinator (in hrc_human) builds the robot's observation from one snapshot of the world
(the task's, :mod:`ros_hrc.tasks`: predicate bits, the observation they map to, the robot
model's true state) and asks this node for the planner's decision. This node is the websocket client
of the POMDP process (``~pomdp_port``, 7070 by default): it sends the ``observation`` (with
the epoch and a correlation id) and returns the ``decision`` that answers it. It keeps no loop
state: a planner that was restarted refuses an observation of an epoch it was not reset into,
and the coordinator then resets the loop.

Services offered: /hrc/obs/decide (ros_hrc/Decide), /hrc/obs/reset_planner
(ros_hrc/ResetPlanner: the planner's belief back to its initial belief, in a new epoch).
Parameters: ~host (127.0.0.1), ~pomdp_port (7070), ~decide_timeout (s, 120: the longest a
decision may take), ~reset_timeout (s, 10: the POMDP's answer to a reset, which takes no
planning), ~link_session (hrc.launch's session: the link token's file) or ~token_file (by hand).

When the POMDP process is not connected (it died, or has not started yet), both services
answer at once that it is not (``success`` false): a reset then says what it could not reset
instead of waiting out a timeout, and is retried by the coordinator. A decision whose frame
is rejected (malformed, too large, of another epoch, without ``reply_to``) fails at once with
the reason (:class:`~ros_hrc.link.transport.ReplyRejected`).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import rospy

from ros_hrc.errors import HrcError, LinkError
from ros_hrc.link.protocol import Ack, Decision, Error, Observation, Reset
from ros_hrc.link.token import launch_token
from ros_hrc.link.transport import MessageClient, link_url
from ros_hrc.nodes.common import init_node, read_config, route_python_logging
from ros_hrc.srv import Decide, DecideResponse, ResetPlanner, ResetPlannerResponse


@dataclass
class ObsNodeConfig:
    host: str = "127.0.0.1"
    pomdp_port: int = 7070
    decide_timeout: float = 120.0
    reset_timeout: float = 10.0
    link_session: str = ""
    token_file: str = ""


class ObsNode:
    """Observation in, the planner's decision out."""

    def __init__(self, config: ObsNodeConfig) -> None:
        self.config = config
        self.pomdp = MessageClient(link_url(config.pomdp_port, config.host), "hrc_obs",
                                   send_timeout=config.decide_timeout, token=launch_token(config))

    def _not_connected(self) -> str:
        """Why nothing can be asked of the POMDP process now ("" when it is connected)."""
        if self.pomdp.connected:
            return ""
        return (f"the POMDP process is not connected ({self.pomdp.url}): it is down or "
                "(re)starting")

    def decide(self, req) -> DecideResponse:
        down = self._not_connected()
        if down:
            return DecideResponse(success=False, message=f"no decision: {down}")
        try:
            elapsed = getattr(req, "elapsed", -1.0)   # Decide.srv: < 0 (or not built) unknown
            reply = self.pomdp.request(Observation(
                step=req.step, observation=req.observation, bits=req.bits, state=req.state,
                elapsed=elapsed if 0.0 <= elapsed < math.inf else None,
                epoch=req.epoch), self.config.decide_timeout)
        except LinkError as exc:
            return DecideResponse(success=False, message=f"no decision from the POMDP process: "
                                                         f"{exc}")
        if isinstance(reply, Error):
            return DecideResponse(success=False, message=f"the POMDP process refused: "
                                                         f"{reply.message}")
        if not isinstance(reply, Decision):
            return DecideResponse(success=False, message=f"the POMDP process answered a "
                                                         f"{reply.type}, not a decision")
        return DecideResponse(success=True, message="", action=reply.action,
                              belief_states=list(reply.belief_states or ()),
                              belief=list(reply.belief), decision_ms=reply.decision_ms or 0.0,
                              surprise=bool(reply.surprise), rule=reply.rule or "")

    def reset_planner(self, req) -> ResetPlannerResponse:
        down = self._not_connected()
        if down:
            return ResetPlannerResponse(success=False, message=down)
        try:
            reply = self.pomdp.request(Reset(reason="reset", episode=req.episode,
                                             epoch=req.epoch), self.config.reset_timeout)
        except LinkError as exc:
            return ResetPlannerResponse(success=False, message=f"POMDP process not reset: {exc}")
        if isinstance(reply, Ack):
            return ResetPlannerResponse(success=True, message=reply.result or "belief reset")
        return ResetPlannerResponse(success=False, message=f"POMDP process: {reply.message}")


def main() -> None:
    init_node("hrc_obs")
    route_python_logging()
    try:
        node = ObsNode(read_config(ObsNodeConfig))
    except (HrcError, ValueError) as exc:
        rospy.logfatal("hrc_obs cannot start: %s", exc)
        raise SystemExit(2) from None
    node.pomdp.start()
    rospy.on_shutdown(node.pomdp.close)
    # The services are offered once the POMDP process is first connected: hrc_human waits
    # for them before its first reset, so a planner that takes a while to load is waited
    # for there, and "not connected" later means down (answered at once).
    started = time.monotonic()
    next_line = started + 10.0
    while not node.pomdp.connected and not rospy.is_shutdown():
        time.sleep(0.1)   # wall clock: /clock may not be published yet
        if time.monotonic() >= next_line:
            next_line += 10.0
            rospy.loginfo("hrc_obs: waiting for the POMDP process on %s (%.0f s)",
                          node.pomdp.url, time.monotonic() - started)
    if rospy.is_shutdown():
        return
    rospy.Service("/hrc/obs/decide", Decide, node.decide)
    rospy.Service("/hrc/obs/reset_planner", ResetPlanner, node.reset_planner)
    rospy.loginfo("hrc_obs: observing for the POMDP process on %s", node.pomdp.url)
    rospy.spin()
