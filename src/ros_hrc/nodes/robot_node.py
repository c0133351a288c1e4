"""hrc_robot: the robot executor, an adapter of the loop's coordinator.

A websocket server (``~robot_port``, 8080 by default, bound to ``~host``). The coordinator
(in hrc_human) connects and, once the planner has decided, sends the ``action`` to carry out;
this node carries it out through the world's /robot/* service the task names for it
(:attr:`ros_hrc.tasks.definition.Task.robot_action_services`; the seed's: ``rIdle`` moves
nothing, ``rPoint_obj`` /robot/point_to_obj, ``rGrasp_obj`` /robot/grasp, ``rStop_all``
/robot/cancel_action; fabric's ``graspPlanning`` /robot/grasp_planning) and answers with an ``ack`` saying what happened (``success`` false: the
world refused, e.g. out of reach). When the world cannot be reached the answer is an
``error``: a fault, which fails the step. A ``reset`` calls /robot/reset. No loop state here.

**Orders from the coordinator only.** The port has one seat: the coordinator's connection
(a client whose hello says ``hrc_human``, with the launch's link token). Any other client
(a planner written for protocol version 1, which drove the robot itself, or any other
holder of the token) is refused with ``error`` code ``refused``; a second ``hrc_human``
connection while one is served gets ``seat_taken`` and is closed. An ``action`` must carry
``epoch`` and ``id`` (the coordinator stamps both; it sends an action only in its current
epoch, checked in the one place stale things are dropped): one without is refused
``invalid``. So no token holder can move the robot but the coordinator.

Parameters: ~task (seed), ~host (127.0.0.1), ~robot_port (8080), ~service_timeout (30 s to wait
for the world),
~link_session (hrc.launch's session: the link token's file) or ~token_file (by hand).
Services used: /robot/point_to_obj, /robot/grasp, /robot/cancel_action, /robot/reset (and
/robot/grasp_planning with task:=fabric).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Tuple

import rospy

from ros_hrc.errors import HrcError
from ros_hrc.link.protocol import (ERR_FAILED, ERR_INVALID, ERR_REFUSED, ERR_SEAT_TAKEN, Ack,
                                   Action, DispatchTable, Message, Reset, reply_error)
from ros_hrc.link.token import launch_token
from ros_hrc.link.transport import MessageServer, Peer
from ros_hrc import tasks
from ros_hrc.nodes.common import (ServiceUnavailable, TriggerCaller, init_node, read_config,
                                  route_python_logging)


#: Who may give the robot orders: the name the coordinator's client says in its hello.
COORDINATOR = "hrc_human"


@dataclass
class RobotNodeConfig:
    task: str = tasks.DEFAULT_TASK
    host: str = "127.0.0.1"
    robot_port: int = 8080
    service_timeout: float = 30.0
    link_session: str = ""
    token_file: str = ""


class RobotNode:
    """Adapter from action messages to the world's robot services."""

    def __init__(self, config: RobotNodeConfig) -> None:
        self.config = config
        self.services = tasks.get(config.task).robot_action_services
        self.call = TriggerCaller(config.service_timeout)
        table = DispatchTable("hrc_robot")
        table.on(Action, self.on_action)
        table.on(Reset, self.on_reset)
        self.seat: Optional[Peer] = None   # the coordinator's connection
        self.server = MessageServer(config.robot_port, table, host=config.host,
                                    name="hrc_robot", token=launch_token(config),
                                    on_disconnect=self._left)

    def _left(self, peer: Peer) -> None:
        if peer is self.seat:
            self.seat = None

    def _refusal(self, msg: Message, peer: Peer) -> Tuple[bool, Optional[Message]]:
        """(refused, the reply refusing it) for an order that is not the coordinator's:
        (False, None) for one that is. Runs on the server's threads one call at a time (the
        server serialises handlers), so the seat needs no lock."""
        if peer.who != COORDINATOR:
            rospy.logwarn("hrc_robot: refused a %s from %r: only the coordinator (%s) gives "
                          "the robot orders", msg.type, peer, COORDINATOR)
            return True, reply_error(msg, f"hrc_robot takes orders only from the coordinator "
                                          f"({COORDINATOR}), not from {peer.who!r}: the "
                                          "planner answers observations with decisions, and "
                                          "the coordinator has the robot act", ERR_REFUSED)
        if self.seat is not None and self.seat is not peer and self.seat.connected:
            peer.send(reply_error(msg, "another coordinator connection is served on this "
                                       "port; one at a time", ERR_SEAT_TAKEN))
            peer.close(reason="the coordinator is already served")
            return True, None
        self.seat = peer
        if isinstance(msg, Action) and (msg.epoch is None or msg.id is None):
            return True, reply_error(msg, "an action must carry the epoch and id the "
                                          "coordinator stamps on it", ERR_INVALID)
        return False, None

    def on_action(self, msg: Action, peer: Peer) -> Optional[Message]:
        refused, reply = self._refusal(msg, peer)
        if refused:
            return reply
        if msg.action not in self.services:
            return reply_error(msg, f"unknown robot action {msg.action!r}; known: "
                                    f"{', '.join(self.services)}", ERR_INVALID)
        service = self.services[msg.action]
        if service is None:
            ok, result = True, "the robot stays idle and keeps observing"
        else:
            try:
                ok, result = self.call(f"/robot/{service}")
            except ServiceUnavailable as exc:
                return reply_error(msg, str(exc), ERR_FAILED)
        rospy.logdebug("step %d: %s -> %s (%s)", msg.step, msg.action, ok, result)
        return Ack(step=msg.step, of=msg.type, action=msg.action, success=ok, result=result,
                   epoch=msg.epoch, reply_to=msg.id)

    def on_reset(self, msg: Reset, peer: Peer) -> Optional[Message]:
        refused, reply = self._refusal(msg, peer)
        if refused:
            return reply
        try:
            ok, result = self.call("/robot/reset")
        except ServiceUnavailable as exc:
            return reply_error(msg, str(exc), ERR_FAILED)
        return Ack(step=0, of=msg.type, success=ok, result=result, epoch=msg.epoch,
                   reply_to=msg.id)


def main() -> None:
    init_node("hrc_robot")
    route_python_logging()
    try:
        node = RobotNode(read_config(RobotNodeConfig))
        node.server.start()
    except (HrcError, ValueError) as exc:
        rospy.logfatal("hrc_robot cannot start: %s", exc)
        raise SystemExit(2) from None
    rospy.loginfo("hrc_robot: carrying out the robot's actions on %s", node.server.url)
    rospy.on_shutdown(node.server.stop)
    rospy.spin()
