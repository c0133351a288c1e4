"""hrc_obs: the robot's eyes. Turns the world's predicates into the POMDP's observation.

When the human node has carried out a step it calls ``/hrc/observe``: this node asks the six
/human/is_* predicates, sums their bits (DESIGN §4: 1 visible, 2 in range, 4 grasp attempt,
8 has object, 16 warning, 32 idle), maps the pattern to the nearest legal observation of the
robot model, works out the robot model's true state from the human's state and its history
(reported only), sends the observation to the POMDP process (a websocket client of port
``~pomdp_port``, 7070 by default), and waits for the robot's action to be carried out. It
returns the whole step as a ros_hrc/Status.

If the POMDP process dies, roslaunch respawns it and the link reconnects; a decision under way
then fails at once (its answer cannot come), and since the new process starts from the initial
belief, this node refuses observations and calls /hrc/reset so that the whole loop starts over
together from step 0.

Services offered: /hrc/observe (ros_hrc/Observe), /hrc/obs/reset (std_srvs/Trigger: forget
the history and reset the POMDP's belief).
Services used: /human/is_ov, /human/is_oir, /human/is_a0, /human/is_ho, /human/is_h4,
/human/is_a2, /hrc/world/state (where the object ends up after the step), /hrc/reset (when
the POMDP process was restarted).
Parameters: ~pomdp_host (127.0.0.1), ~pomdp_port (7070), ~reply_timeout (s to wait for the
POMDP's decision and the robot's motion, 120), ~service_timeout (30).
"""
from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Dict

import rospy
from std_srvs.srv import Trigger, TriggerResponse

from ros_hrc import task
from ros_hrc.errors import LinkError
from ros_hrc.link.protocol import Ack, Action, Error, Message, Observation, Reset
from ros_hrc.link.transport import MessageClient, link_url
from ros_hrc.msg import Status
from ros_hrc.nodes.common import (ServiceUnavailable, TriggerCaller, read_config,
                                  route_python_logging)
from ros_hrc.srv import GetWorldState, Observe, ObserveResponse


@dataclass
class ObsNodeConfig:
    pomdp_host: str = "127.0.0.1"
    pomdp_port: int = 7070
    reply_timeout: float = 120.0
    service_timeout: float = 30.0


def human_observation_text(predicates: Dict[str, bool]) -> str:
    """The predicates as the ROS terminal prints them, e.g. ``ov=1 oir=1 ho=0 ...``."""
    return " ".join(f"{name[3:]}={int(value)}" for name, value in predicates.items())


class ObsNode:
    """Observer: world predicates in, observation out to the POMDP, the step's status back."""

    def __init__(self, config: ObsNodeConfig) -> None:
        self.config = config
        self.call = TriggerCaller(config.service_timeout)
        self.tracker = task.RobotStateTracker()
        self.pomdp = MessageClient(link_url(config.pomdp_port, config.pomdp_host), "hrc_obs",
                                   send_timeout=config.reply_timeout,
                                   on_connect=self._on_pomdp_connect)
        self._lock = threading.Lock()   # one observation (or reset) at a time
        # The POMDP connection whose belief is in step with the loop (None: not used yet).
        self._in_step_connection = None
        self._reset_pending = threading.Event()
        self._world_state = None   # persistent proxy of /hrc/world/state, made on first use

    # -- a restarted POMDP process -------------------------------------------------------------
    def _on_pomdp_connect(self) -> None:
        if self.pomdp.connections > 1:
            self.request_loop_reset("the POMDP process reconnected (restarted?)")

    def request_loop_reset(self, reason: str) -> None:
        """Ask the human node to reset everything (once, however many times this is asked
        before the reset comes)."""
        if self._reset_pending.is_set():
            return
        self._reset_pending.set()
        rospy.logwarn("hrc_obs: %s: resetting the whole loop", reason)

        def call_reset() -> None:
            try:
                ok, text = self.call("/hrc/reset")
            except ServiceUnavailable as exc:
                ok, text = False, str(exc)
            if not ok:
                self._reset_pending.clear()   # let the next observation ask again
                rospy.logerr("hrc_obs: could not reset the loop: %s", text)

        threading.Thread(target=call_reset, name="loop-reset", daemon=True).start()

    def read_predicates(self) -> Dict[str, bool]:
        """The six /human/is_* answers; raises ServiceUnavailable if the world is not there."""
        return {name: self.call(f"/human/{name}")[0] for name in task.PREDICATE_BITS}

    def observe(self, req) -> ObserveResponse:
        with self._lock:
            status = Status()
            status.header.stamp = rospy.Time.now()
            status.step = req.step
            status.human_action = req.human_action
            status.human_state = req.human_state
            status.human_state_index = req.human_state_index
            status.human_reward = req.human_reward
            try:
                predicates = self.read_predicates()
                raw_bits = task.bits_from_predicates(predicates)
                bits = task.legal_bits(raw_bits)
                status.human_observation = human_observation_text(predicates)
                status.observation_bits = bits
                status.robot_observation = task.observation_name(bits)
                status.robot_state = self.tracker.update(req.human_state)
            except (ServiceUnavailable, ValueError) as exc:
                return ObserveResponse(success=False, message=str(exc), status=status)
            if self._reset_pending.is_set():
                return ObserveResponse(success=False, status=status, message=(
                    "the POMDP process restarted: waiting for the loop to reset"))
            try:
                self.pomdp.drain()  # anything stale from before a reset or a reconnect
                connection = self.pomdp.send(Observation(
                    step=req.step, observation=status.robot_observation, bits=raw_bits,
                    state=status.robot_state))
                reply = self.pomdp.receive(
                    self.config.reply_timeout,
                    match=lambda m: isinstance(m, (Action, Error)) and
                    getattr(m, "step", None) in (req.step, None),
                    connection=connection)
            except LinkError as exc:
                return ObserveResponse(success=False, status=status,
                                       message=f"no decision from the POMDP process: {exc}")
            if self._in_step_connection is None:
                self._in_step_connection = connection
            elif connection != self._in_step_connection:
                # A new process answered from its initial belief, out of step with the loop.
                self.request_loop_reset("the POMDP process was restarted")
                return ObserveResponse(success=False, status=status, message=(
                    "the POMDP process restarted: waiting for the loop to reset"))
            if isinstance(reply, Error):
                return ObserveResponse(success=False, status=status,
                                       message=f"the POMDP process refused: {reply.message}")
            status.robot_action = reply.action
            status.belief = list(reply.belief)
            status.belief_states = list(reply.belief_states or [])
            status.decision_ms = reply.decision_ms or 0.0
            self.fill_world_outcome(status)
            result = reply.extra.get("result", "")
            ok = bool(reply.extra.get("success", True))
            return ObserveResponse(success=ok, message=result, status=status)

    def fill_world_outcome(self, status: Status) -> None:
        """Where the object is once both agents have acted: who holds it, whether it was
        missed, and the world's simulated time (experiments score episodes by these)."""
        try:
            if self._world_state is None:
                rospy.wait_for_service("/hrc/world/state", timeout=self.config.service_timeout)
                self._world_state = rospy.ServiceProxy("/hrc/world/state", GetWorldState,
                                                       persistent=True)
            world = self._world_state().state
        except (rospy.ROSException, rospy.ServiceException, OSError) as exc:
            self._world_state = None   # reconnect next time
            rospy.logwarn("hrc_obs: no world state for step %d: %s", status.step, exc)
            return
        status.sim_time = world.sim_time
        status.object_holder = world.holder
        status.object_left_belt = world.object_left_belt

    def reset(self, _req) -> TriggerResponse:
        with self._lock:
            self.tracker.reset()
            try:
                self.pomdp.drain()
                reply = self.pomdp.request(Reset(reason="reset requested"),
                                           timeout=self.config.reply_timeout)
            except LinkError as exc:
                return TriggerResponse(success=False, message=f"POMDP process not reset: {exc}")
            if isinstance(reply, Ack):
                self._in_step_connection = self.pomdp.connections
                self._reset_pending.clear()
                return TriggerResponse(success=True, message="observer history and robot belief reset")
            return TriggerResponse(success=False, message=f"POMDP process: {reply.message}")


def main() -> None:
    rospy.init_node("hrc_obs")
    route_python_logging()
    node = ObsNode(read_config(ObsNodeConfig))
    node.pomdp.start()
    rospy.Service("/hrc/observe", Observe, node.observe)
    rospy.Service("/hrc/obs/reset", Trigger, node.reset)
    rospy.on_shutdown(node.pomdp.close)
    rospy.loginfo("hrc_obs: observing for the POMDP process on %s", node.pomdp.url)
    rospy.spin()
