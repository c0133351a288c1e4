"""hrc_human's adapters of the coordinator's four interfaces (:mod:`ros_hrc.loop.runner`):
the world's ROS services, the POMDP process's link, the robot executor (the world's
``/robot/*`` services) and the served MDP's connection. Each carries a call out and reports
what came back; none keeps loop state. The node that wires them is
:mod:`ros_hrc.nodes.human_node`.

The run's end is not a fault: a world that answers that it is shutting down
(:data:`~ros_hrc.errors.WORLD_ENDING`: its window was closed, or the launch stops) raises
:class:`~ros_hrc.errors.StackEnding`, and a POMDP process that closed its link itself
(going away: it was asked to stop) is waited for, not reported, until it is back (a respawn)
or this node ends with it (the launch stops).
"""
from __future__ import annotations

import math
from contextlib import contextmanager
from typing import Callable, Iterator, Mapping, Optional

import rospy

from ros_hrc.errors import WORLD_ENDING, LinkError, StackEnding
from ros_hrc.link.protocol import (ERR_SEAT_TAKEN, Ack, Error, Observation, Reset, Step,
                                   TaskEnd, TaskReport)
from ros_hrc.link.protocol import Decision as DecisionMessage
from ros_hrc.link.transport import CLOSE_GOING_AWAY, LinkClosed, MessageClient
from ros_hrc.loop.effects import (Decision, EndTask, MdpRefused, MdpReset, MdpStepDone,
                                  Outcome, SeatRefused, Snapshot, TaskAnswer)
from ros_hrc.loop.runner import ExecutorPort, MdpPort, PlannerPort, WorldPort
from ros_hrc.nodes.common import ServiceUnavailable, TriggerCaller
from ros_hrc.srv import GetWorldState
from ros_hrc.streams import WORLD_EPISODE_PARAM, WORLD_SEED_PARAM


def no_wait() -> None:
    """The default ``ready``: nothing to wait for."""
    return None


@contextmanager
def world_call() -> Iterator[None]:
    """Around a call of the world's services: a service error saying that the world is
    shutting down becomes :class:`~ros_hrc.errors.StackEnding` (the end, not a fault)."""
    try:
        yield
    except ServiceUnavailable as exc:
        if WORLD_ENDING in str(exc):
            raise StackEnding(f"the world ends: {exc}") from exc
        raise


class RosWorld(WorldPort):
    """The world's services. ``ready()`` blocks until the start-up wait is over. ``seed``:
    the run's seed, whose (seed, episode) stream the world draws from in each episode (a
    warm stack's next cell brings a new one; None: the world's own)."""

    def __init__(self, call: TriggerCaller, ready: Callable[[], object] = no_wait,
                 seed: Optional[int] = None) -> None:
        self.call = call
        self.ready = ready
        self.seed = seed

    def act_human(self, service: str) -> Outcome:
        self.ready()
        with world_call():
            ok, message = self.call(f"/human/{service}")
        return Outcome(ok, message)

    def snapshot(self) -> Snapshot:
        self.ready()
        with world_call():
            state = self.call.call("/hrc/world/state", GetWorldState).state
        return Snapshot(predicates={
            "is_ov": state.object_visible, "is_oir": state.object_in_reach,
            "is_a0": state.human_attempting_grasp, "is_ho": state.human_has_object,
            "is_h4": state.human_warning, "is_a2": state.human_idle},
            sim_time=state.sim_time, holder=state.holder, left_belt=state.object_left_belt)

    def reset(self, interrupt: bool, episode: int) -> Outcome:
        self.ready()
        if not interrupt:
            # The world reseeds its stream for this episode at the reset (only this node
            # resets the world, so the parameter is read by the reset it precedes).
            if self.seed is not None:
                rospy.set_param(WORLD_SEED_PARAM, self.seed)
            rospy.set_param(WORLD_EPISODE_PARAM, episode)
        with world_call():
            ok, message = self.call("/hrc/world/reset")
        return Outcome(ok, message)


class LinkPlanner(PlannerPort):
    """The robot planner: the POMDP process, of which this node is the websocket client.

    A decision is one request on the link: the ``observation`` (with the epoch and a
    correlation id) out, the ``decision`` that answers it in; a reset is a ``reset`` into the
    new epoch. It keeps no loop state: a planner that restarted refuses an observation of an
    epoch it was not reset into, and the coordinator then resets the loop. While the POMDP
    process is not connected (it died, or is starting again) both answer at once that it is
    not: a reset then says what it could not reset instead of waiting out a timeout, and is
    retried. A POMDP process that closed the link itself (going away: it was asked to stop)
    is waited for instead (up to the call's timeout): either it comes back (a respawn; its
    fresh planner then refuses the old epoch, and the loop resets) or the launch is stopping
    and this node ends meanwhile, which is the end of the run, not a fault
    (:class:`~ros_hrc.errors.StackEnding` once the link is closed). A decision whose frame is rejected (malformed, too large, of another epoch,
    without ``reply_to``) fails at once with the reason
    (:class:`~ros_hrc.link.transport.ReplyRejected`). ``ready()`` blocks until the start-up
    wait is over."""

    def __init__(self, client: MessageClient, decide_timeout: float, reset_timeout: float,
                 ready: Callable[[], object] = no_wait) -> None:
        self.client = client
        self.decide_timeout = decide_timeout
        self.reset_timeout = reset_timeout
        self.ready = ready

    def _not_connected(self, timeout: float) -> str:
        """Why nothing can be asked of the POMDP process now ("" when it is connected); one
        that stopped on purpose is waited for up to ``timeout`` s first."""
        if self.client.connected:
            return ""
        if self._stopped():
            self._wait_for_return(timeout)
            if self.client.connected:
                return ""
        return (f"the POMDP process is not connected ({self.client.url}): it is down or "
                "(re)starting")

    def _stopped(self) -> bool:
        """Whether the POMDP process's last connection ended by its own close, going away:
        it was asked to stop (it did not crash)."""
        last = self.client.last_close
        return last is not None and last[0] == CLOSE_GOING_AWAY

    def _wait_for_return(self, timeout: float) -> None:
        """Wait up to ``timeout`` s for the POMDP process to be connected again; raises
        StackEnding when this node closed the link meanwhile (it ends)."""
        try:
            self.client.connect(timeout)
        except LinkClosed as exc:
            raise StackEnding(f"this node ends: {exc}") from exc
        except LinkError:
            pass   # not back in time: said by the caller

    def decide(self, epoch: int, step: int, observation: str, bits: int, state: str,
               elapsed: Optional[float] = None) -> Decision:
        self.ready()
        down = self._not_connected(self.decide_timeout)
        if down:
            raise LinkError(f"no decision: {down}")
        try:
            reply = self.client.request(Observation(
                step=step, observation=observation, bits=bits, state=state,
                elapsed=elapsed if elapsed is not None and 0.0 <= elapsed < math.inf else None,
                epoch=epoch), self.decide_timeout)
        except LinkClosed as exc:
            raise StackEnding(f"this node ends: {exc}") from exc
        except LinkError as exc:
            if self._stopped():   # it stopped during the request: back, or the end
                self._wait_for_return(self.decide_timeout)
            raise LinkError(f"no decision from the POMDP process: {exc}") from exc
        if isinstance(reply, Error):
            raise LinkError(f"the POMDP process refused: {reply.message}")
        if not isinstance(reply, DecisionMessage):
            raise LinkError(f"the POMDP process answered a {reply.type}, not a decision")
        return Decision.of(reply)

    def reset(self, epoch: int, episode: int, task_index: Optional[int] = None,
              true_type: Optional[str] = None) -> Outcome:
        self.ready()
        down = self._not_connected(self.reset_timeout)
        if down:
            return Outcome(False, down)
        try:
            reply = self.client.request(Reset(reason="reset", episode=episode, epoch=epoch,
                                              task_index=task_index or None,
                                              true_type=true_type or None),
                                        self.reset_timeout)
        except LinkClosed as exc:
            raise StackEnding(f"this node ends: {exc}") from exc
        except LinkError as exc:
            if self._stopped():   # it stopped during the request: back, or the end
                self._wait_for_return(self.reset_timeout)
            return Outcome(False, f"POMDP process not reset: {exc}")
        if isinstance(reply, Ack):
            return Outcome(True, reply.result or "belief reset")
        if isinstance(reply, Error):
            return Outcome(False, f"POMDP process: {reply.message}")
        return Outcome(False, f"POMDP process: answered a {reply.type}, not an ack")


    def end_task(self, epoch: int, call: EndTask) -> TaskAnswer:
        """``task_end`` out, the robot process's ``task_report`` in (an older process
        answers ``unknown_type``: a LinkError, and the task is published without its part)."""
        self.ready()
        down = self._not_connected(self.reset_timeout)
        if down:
            raise LinkError(f"no task report: {down}")
        outcome = call.outcome
        try:
            reply = self.client.request(TaskEnd(
                task_index=call.task_index, outcome=outcome.outcome,
                who_succeeded=outcome.who_succeeded or None, warnings=outcome.warnings,
                preemptions=outcome.preemptions, steps=call.steps, duration=outcome.duration,
                utility=call.utility, epoch=epoch), self.decide_timeout)
        except LinkClosed as exc:
            raise StackEnding(f"this node ends: {exc}") from exc
        except LinkError as exc:
            raise LinkError(f"no task report from the POMDP process: {exc}") from exc
        if isinstance(reply, Error):
            raise LinkError(f"the POMDP process refused task_end: {reply.message}")
        if not isinstance(reply, TaskReport):
            raise LinkError(f"the POMDP process answered a {reply.type}, not a task_report")
        return TaskAnswer.of(reply)


class RosExecutor(ExecutorPort):
    """The robot executor: the world's /robot/* service of the task's robot action
    (``services``: action -> service, None for an action that moves nothing). A refused
    action (``success`` false: out of reach) is what happened; a service that errors or is
    gone raises (a fault, which fails the step). ``ready()`` blocks until the start-up wait
    is over."""

    def __init__(self, call: TriggerCaller, services: Mapping[str, Optional[str]],
                 ready: Callable[[], object] = no_wait) -> None:
        self.call = call
        self.services = services
        self.ready = ready

    def act(self, epoch: int, step: int, action: str) -> Outcome:
        self.ready()
        service = self.services[action]
        if service is None:
            return Outcome(True, "the robot stays idle and keeps observing")
        with world_call():
            ok, message = self.call(f"/robot/{service}")
        return Outcome(ok, message)


class LinkMdp(MdpPort):
    """The served MDP's connection: answers are queued by the server, never block."""

    def reset(self, effect: MdpReset) -> None:
        effect.peer.send(Reset(reason=effect.reason, episode=effect.episode,
                               epoch=effect.epoch, task_index=effect.task_index or None,
                               true_type=effect.true_type or None,
                               human_model=effect.human_model or None,
                               drift_to=effect.drift_to or None,
                               drift=effect.drift if effect.drift_to else None))

    def step_done(self, effect: MdpStepDone) -> None:
        effect.peer.send(Ack(step=effect.step, of=Step.TYPE, action=effect.robot_action,
                             success=effect.success, result=effect.result,
                             episode=effect.episode, episode_over=effect.episode_over,
                             end_reason=effect.end_reason or None, epoch=effect.epoch,
                             reply_to=effect.reply))

    def refused(self, effect: MdpRefused) -> None:
        effect.peer.send(Error(message=effect.message, code=effect.code,
                               in_reply_to=effect.in_reply_to,
                               step=effect.step, epoch=effect.epoch, reply_to=effect.reply))

    def refuse_seat(self, effect: SeatRefused) -> None:
        rospy.logwarn("hrc_human: a second MDP client (%r) was refused", effect.peer)
        effect.peer.send(Error(message=effect.message, code=ERR_SEAT_TAKEN))
        effect.peer.close(reason="an MDP process is already served")
