"""hrc_robot: carries out the robot POMDP's actions in the world.

A websocket server (port ``~port``, 8080 by default, bound to ``~host``) that the POMDP
process connects to. Each ``action`` message is carried out through the world's /robot/*
services (``rIdle`` moves nothing; ``rPoint_obj`` /robot/point_to_obj, ``rGrasp_obj``
/robot/grasp, ``rStop_all`` /robot/cancel_action) and answered with an ``ack`` carrying what
happened. A ``reset`` calls /robot/reset.

Parameters: ~host (127.0.0.1), ~port (8080), ~service_timeout (30 s to wait for the world).
Services used: /robot/point_to_obj, /robot/grasp, /robot/cancel_action, /robot/reset.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import rospy

from ros_hrc import task
from ros_hrc.link.protocol import Ack, Action, Error, Message, Reset
from ros_hrc.link.transport import MessageServer, Peer
from ros_hrc.nodes.common import (ServiceUnavailable, TriggerCaller, read_config,
                                  route_python_logging)


@dataclass
class RobotNodeConfig:
    host: str = "127.0.0.1"
    port: int = 8080
    service_timeout: float = 30.0


class RobotNode:
    """Adapter from the POMDP's action messages to the world's robot services."""

    def __init__(self, config: RobotNodeConfig) -> None:
        self.config = config
        self.call = TriggerCaller(config.service_timeout)
        self.server = MessageServer(config.port, self.handle, host=config.host, name="hrc_robot")

    def handle(self, msg: Message, peer: Peer) -> Optional[Message]:
        if isinstance(msg, Action):
            if msg.action not in task.ROBOT_ACTION_SERVICES:
                return Error(message=f"unknown robot action {msg.action!r}; known: "
                                     f"{', '.join(task.ROBOT_ACTION_SERVICES)}",
                             in_reply_to=msg.type, step=msg.step)
            service = task.ROBOT_ACTION_SERVICES[msg.action]
            if service is None:
                ok, result = True, "robot stays idle and keeps observing"
            else:
                try:
                    ok, result = self.call(f"/robot/{service}")
                except ServiceUnavailable as exc:
                    ok, result = False, str(exc)
            rospy.logdebug("step %d: %s -> %s (%s)", msg.step, msg.action, ok, result)
            return Ack(step=msg.step, of=msg.type, action=msg.action, success=ok, result=result)
        if isinstance(msg, Reset):
            try:
                ok, result = self.call("/robot/reset")
            except ServiceUnavailable as exc:
                ok, result = False, str(exc)
            return Ack(step=0, of=msg.type, success=ok, result=result)
        return Error(message=f"hrc_robot does not take {msg.type} messages",
                     in_reply_to=msg.type, step=getattr(msg, "step", None))


def main() -> None:
    rospy.init_node("hrc_robot")
    route_python_logging()
    node = RobotNode(read_config(RobotNodeConfig))
    node.server.start()
    rospy.loginfo("hrc_robot: waiting for the POMDP process on %s", node.server.url)
    rospy.on_shutdown(node.server.stop)
    rospy.spin()
