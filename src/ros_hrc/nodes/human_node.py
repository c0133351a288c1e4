"""hrc_human: carries out the human MDP's steps in the world and runs the loop's lockstep.

A websocket server (``~port``, 9090 by default, bound to ``~host``) that the MDP process
(``despot_mdp``) connects to. For each ``step`` message it

1. carries out the human's action through the world's /human/* services
   (graspAttempt -> /human/grasp when the MDP's next state is ``success``, else
   /human/attempt_grasp; lookAround -> /human/look_around; idle -> /human/idle;
   walkAway -> /human/walk_away; warnRobot -> /human/warn_robot),
2. asks hrc_obs (``/hrc/observe``) to observe, let the POMDP decide and the robot act,
3. prints one block in the terminal, publishes ros_hrc/Status on ``/hrc/status``, and
4. answers the MDP with an ``ack`` carrying the robot's action.

Resetting (``/hrc/reset``, Enter on the terminal, or a ``reset`` from the MDP) puts the world
back (/human/reset, /robot/reset), resets the observer and the POMDP's belief
(/hrc/obs/reset) and the MDP's belief and step counter (a ``reset`` message). Steps of the
MDP that were under way before a reset are refused until it starts again from step 0.

Topics: /hrc/status (ros_hrc/Status), one message per step.
Services offered: /hrc/reset (std_srvs/Trigger), /hrc/set_human_state (ros_hrc/SetHumanState:
the human's next state, for manual mode without a terminal).
Services used: /human/*, /hrc/observe, /hrc/obs/reset.
Parameters: ~host (127.0.0.1), ~port (9090), ~mode (auto|manual, for the printout),
~read_stdin (true: Enter on this node's terminal resets everything), ~print_steps (true),
~service_timeout (30), ~reply_timeout (10: wait for the MDP's answer to a next state).
"""
from __future__ import annotations

import sys
import threading
from dataclasses import dataclass
from typing import Optional

import rospy
from std_srvs.srv import Trigger, TriggerResponse

from ros_hrc import task
from ros_hrc.link.protocol import Ack, Error, Message, NextState, Reset, Step
from ros_hrc.link.transport import MessageServer, Peer
from ros_hrc.msg import Status
from ros_hrc.nodes.common import (ServiceUnavailable, TriggerCaller, read_config,
                                  route_python_logging)
from ros_hrc.srv import (Observe, ObserveRequest, SetHumanState, SetHumanStateResponse)

MDP_NAME = "despot_mdp"


@dataclass
class HumanNodeConfig:
    host: str = "127.0.0.1"
    port: int = 9090
    mode: str = "auto"
    read_stdin: bool = True
    print_steps: bool = True
    service_timeout: float = 30.0
    reply_timeout: float = 10.0


def format_step(status: Status) -> str:
    """The block the ROS terminal prints for one step."""
    bits = status.observation_bits
    belief = " | ".join(f"{name} {p:.3f}" for name, p in zip(status.belief_states, status.belief))
    return "\n".join([
        f"------------------------------ step {status.step} ------------------------------",
        f"human action      : {status.human_action}",
        f"human observation : {status.human_observation}",
        f"robot observation : {status.robot_observation} ({task.describe_bits(bits)})",
        f"human state       : {status.human_state} ({status.human_state_index})",
        f"robot state       : {status.robot_state}",
        f"robot action      : {status.robot_action}",
        f"robot belief      : {belief}",
        f"object            : {object_text(status)} (t = {status.sim_time:.2f} s simulated)",
    ])


def object_text(status: Status) -> str:
    if status.object_holder in ("human", "robot"):
        return f"held by the {status.object_holder}"
    return "missed: it left the belt" if status.object_left_belt else "on the belt"


class HumanNode:
    """The loop's coordinator on the ROS side."""

    def __init__(self, config: HumanNodeConfig) -> None:
        self.config = config
        self.call = TriggerCaller(config.service_timeout)
        self.server = MessageServer(config.port, self.handle, host=config.host, name="hrc_human",
                                    on_connect=self.on_connect)
        self.status_pub = rospy.Publisher("/hrc/status", Status, queue_size=100)
        self._observe = rospy.ServiceProxy("/hrc/observe", Observe)
        self._loop_lock = threading.RLock()   # a step or a reset at a time
        self._await_fresh_start = False       # after a reset, only a step 0 is accepted
        self._mdp_connections = 0
        self._mdp_peer: Optional[int] = None  # the MDP process being served (the newest)
        self._answers = threading.Condition()
        self._answer: Optional[Message] = None

    # -- websocket side ----------------------------------------------------------------------
    def on_connect(self, peer: Peer) -> None:
        if peer.who != MDP_NAME:
            return
        self._mdp_connections += 1
        self._mdp_peer = peer.id
        if self._mdp_connections > 1:
            # A respawned or reconnected MDP: everything starts over together from step 0.
            threading.Thread(target=self.reset_all, args=("the MDP process reconnected",),
                             daemon=True).start()

    def handle(self, msg: Message, peer: Peer) -> Optional[Message]:
        if isinstance(msg, Step):
            if peer.id != self._mdp_peer:
                return Error(message="another MDP process is connected and being served",
                             in_reply_to=msg.type, step=msg.step)
            return self.run_step(msg)
        if isinstance(msg, Reset):
            ok, text = self.reset_all(f"asked by {peer.who}", tell_mdp=False)
            return Ack(step=0, of=msg.type, success=ok, result=text)
        if isinstance(msg, (Ack, Error)) and (msg.type == "error" or msg.of == "next_state"):
            with self._answers:   # the MDP's answer to a next_state
                self._answer = msg
                self._answers.notify_all()
            return None
        return Error(message=f"hrc_human does not take {msg.type} messages here",
                     in_reply_to=msg.type, step=getattr(msg, "step", None))

    def run_step(self, msg: Step) -> Message:
        with self._loop_lock:
            if self._await_fresh_start and msg.step != 0:
                return Error(message=f"step {msg.step} is from before the reset; start again "
                                     "from step 0", in_reply_to=msg.type, step=msg.step)
            self._await_fresh_start = False
            try:
                service = task.human_service_for(msg.action, msg.state)
            except ValueError as exc:
                return Error(message=str(exc), in_reply_to=msg.type, step=msg.step)
            try:
                acted, action_result = self.call(f"/human/{service}")
                response = self._observe(ObserveRequest(
                    step=msg.step, human_action=msg.action, human_state=msg.state,
                    human_state_index=msg.state_index or 0, human_reward=msg.reward or 0.0))
            except (ServiceUnavailable, rospy.ServiceException) as exc:
                return Error(message=f"step {msg.step} not carried out: {exc}",
                             in_reply_to=msg.type, step=msg.step)
            status = response.status
            if not status.robot_action:
                # Nothing was decided (no POMDP process, or it restarted): no step to report.
                rospy.logwarn("step %d: %s", msg.step, response.message)
                return Error(message=f"step {msg.step} not completed: {response.message}",
                             in_reply_to=msg.type, step=msg.step)
            status.mode = self.config.mode
            self.status_pub.publish(status)
            if self.config.print_steps:
                print(format_step(status), flush=True)
                if not acted:
                    print(f"(human: {action_result})", flush=True)
            if not response.success:
                rospy.logwarn("step %d: %s", msg.step, response.message)
            return Ack(step=msg.step, of=msg.type, action=status.robot_action or None,
                       success=response.success,
                       result=response.message or action_result,
                       extra={k: v for k, v in msg.extra.items() if k == "episode"})

    # -- resets --------------------------------------------------------------------------------
    def reset_all(self, reason: str, tell_mdp: bool = True):
        """World, observer, POMDP and (if ``tell_mdp``) MDP back to step 0: (ok, message)."""
        with self._loop_lock:
            problems = []
            for service in ("/human/reset", "/robot/reset", "/hrc/obs/reset"):
                try:
                    ok, text = self.call(service)
                except ServiceUnavailable as exc:
                    ok, text = False, str(exc)
                if not ok:
                    problems.append(f"{service}: {text}")
            if tell_mdp:
                self.server.send(Reset(reason=reason), who=MDP_NAME)
            self._await_fresh_start = True
            summary = "; ".join(problems) if problems else "world, robot belief and human MDP reset"
            print(f"=============== RESET ({reason}): {summary} ===============", flush=True)
            return not problems, summary

    def reset_service(self, _req) -> TriggerResponse:
        ok, text = self.reset_all("/hrc/reset called")
        return TriggerResponse(success=ok, message=text)

    def set_human_state(self, req) -> SetHumanStateResponse:
        state = None if req.state < 0 else int(req.state)
        with self._answers:
            self._answer = None
        if self.server.send(NextState(state=state), who=MDP_NAME) == 0:
            return SetHumanStateResponse(success=False, message="no MDP process is connected")
        with self._answers:
            self._answers.wait_for(lambda: self._answer is not None, self.config.reply_timeout)
            answer = self._answer
        if answer is None:
            return SetHumanStateResponse(success=False, message="the MDP process did not answer")
        if isinstance(answer, Error):
            return SetHumanStateResponse(success=False, message=answer.message)
        return SetHumanStateResponse(success=True, message=answer.result or "next state queued")

    def read_enter(self) -> None:
        """Each Enter on this node's terminal resets everything."""
        for _line in sys.stdin:
            if rospy.is_shutdown():
                break
            threading.Thread(target=self.reset_all, args=("Enter pressed",), daemon=True).start()


def main() -> None:
    rospy.init_node("hrc_human")
    route_python_logging()
    node = HumanNode(read_config(HumanNodeConfig))
    rospy.Service("/hrc/reset", Trigger, node.reset_service)
    rospy.Service("/hrc/set_human_state", SetHumanState, node.set_human_state)
    node.server.start()
    rospy.on_shutdown(node.server.stop)
    if node.config.read_stdin and sys.stdin is not None and not sys.stdin.closed:
        threading.Thread(target=node.read_enter, name="enter-resets", daemon=True).start()
        print("hrc_human: press Enter in this terminal to reset the whole scenario", flush=True)
    rospy.loginfo("hrc_human: waiting for the MDP process on %s", node.server.url)
    rospy.spin()
