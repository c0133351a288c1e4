"""One step of the loop (Sans-I/O): observe -> decide -> act, its report, and its waits.

One step, in this order::

    MDP step(epoch, n, action, state) -> ActHuman -> ObserveWorld -> Decide -> ActRobot
        -> ObserveWorld (the outcome) -> StepReport published, MdpStepDone

A human who hears the robot (a task with reaction rules) steps with the state he acts in
(a grasp's outcome drawn first); his answer is ``MdpStepDone`` (the robot's action, the end),
and only his reaction (:meth:`StepPipeline.react`: his state after the robot acted) completes
the step: the report shows that state, labelled, and is published then::

    ... -> ObserveWorld (the outcome) -> MdpStepDone -> the MDP's reaction -> StepReport
        published

**The task.** What a step knows of the collaboration task (the human's states and actions,
the world service of each action, the bits -> observation map, the robot's true state, the
observation noise) is the configuration's :class:`~ros_hrc.tasks.definition.Task`; the step
names none. A task with observation noise draws it from the stream of (``seed``, episode,
"observation") (:mod:`ros_hrc.streams`), restarted at each episode's start, so an episode's
noise is its own whatever ran before it.

**Failures.** A call that fails (a fault: the service or process is gone, or answered
nonsense) fails its step visibly (the report's ``fault``), and the caller recovers by a
reset. A world action that is *refused* (a grasp out of reach) is not a fault: it is what
happened. While a step's call is out, every ``wait_note_every`` seconds a line says what the
step waits for; a call to the world that has not answered after ``world_call_timeout`` fails
the step.

Whether a step may start at all (the MDP's seat, the epoch, the loop's phase) and what its
end means for the episode are the coordinator's to say; this part runs the step it is given.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, Optional, Tuple

from ros_hrc.loop.config import ROBOT_WAIT_ACTIONS, CoordinatorConfig
from ros_hrc.loop.effects import (DECISION_IN_REPORT, FAILED, INVALID, STALE, ActHuman,
                                  ActRobot, Call, Decide, Fault, MdpRefused, MdpStepDone,
                                  ObserveWorld, PublishStep, ReactionRequest, StepReport,
                                  StepRequest)
from ros_hrc.loop.outbox import Outbox
from ros_hrc.streams import generator
from ros_hrc.tasks.utility import sim_span


@dataclass
class StepUnderWay:
    """The step under way: what the MDP asked for (``request``, from ``peer``), its report
    so far, and where it stands."""
    request: StepRequest
    peer: Any
    report: StepReport
    stage: str = "human"   # human -> observe -> decide -> robot -> outcome (-> react)
    played_out: bool = False   # (react) no episode of the schedule is left after this one
    react_timer: Optional[int] = None
    decided_on: str = ""       # the robot's true state when it decided (pre-emptions)


@dataclass(frozen=True)
class StepFailed:
    """The step failed (``why``): published with its fault and refused to the MDP; the loop
    recovers by a reset."""
    why: str


@dataclass(frozen=True)
class StepActed:
    """Both agents acted and the outcome is read: ``report`` is ready for the episode's say
    (:meth:`StepPipeline.finish`)."""
    report: StepReport


@dataclass(frozen=True)
class StepComplete:
    """A reacting human's step is complete (:meth:`StepPipeline.react`): ``report``, ended
    for ``report.end_reason``; ``played_out`` as the step's end said."""
    report: StepReport
    played_out: bool


def reaction_refused(peer: Any, request: ReactionRequest, code: str, message: str
                     ) -> MdpRefused:
    """The MDP's reaction ``request`` is refused (``code``, ``message``)."""
    return MdpRefused(peer, request.reply, request.epoch, request.step, code, message,
                      in_reply_to="reaction")


class StepPipeline:
    """Runs one step at a time (``current``: the step under way, None between steps) and
    keeps what steps carry from one to the next: the number the MDP's next step must have
    (``expected_step``), the labeller of the robot's true state (``tracker``) and the
    episode's observation noise. See the module docstring."""

    def __init__(self, config: CoordinatorConfig, outbox: Outbox) -> None:
        self.config = config
        self.task = config.task
        self.outbox = outbox
        self.expected_step = 0
        self.tracker = self.task.new_tracker(config.human_model)
        self.current: Optional[StepUnderWay] = None
        self._observation_map = self.task.observation_map()
        self._noise_rng = None          # the episode's "observation" stream (noise, labels)
        self._wait_timers: Dict[int, Tuple[int, float]] = {}   # timer -> (call id, waited s)
        self._react_waits: Tuple[Optional[int], float] = (None, 0.0)   # (timer, waited s)

    # -- between episodes ----------------------------------------------------------------------
    def new_episode(self) -> None:
        """A reset resets the world: the next step is step 0, of a human with no history."""
        self.tracker.reset()
        self.expected_step = 0

    def new_human(self, nearest_type: str) -> None:
        """The next episode's human is of type ``nearest_type``: his labeller."""
        self.tracker = self.task.new_tracker(nearest_type)
        self.tracker.reset()

    def episode_started(self, episode: int) -> None:
        """Episode ``episode`` started: its observation noise restarts on its own stream."""
        self._observation_map = self.task.observation_map()
        self._noise_rng = generator(self.config.seed, episode, "observation")
        begin = getattr(self.tracker, "begin_episode", None)
        if begin is not None:
            begin(self._noise_rng)

    def interrupt(self) -> None:
        """A reset cuts the step under way short: the MDP is told (unless it was answered
        already: a reacting human's step)."""
        if self.current is None:
            return
        ctx, self.current = self.current, None
        if ctx.stage != "react":
            self.outbox.emit(MdpRefused(ctx.peer, ctx.request.reply, ctx.request.epoch,
                                        ctx.request.step, STALE,
                                        f"step {ctx.request.step} was interrupted by a reset"))

    def drop(self) -> bool:
        """The step under way is dropped unreported (the run ends, the MDP stopped); whether
        there was one."""
        had, self.current = self.current is not None, None
        return had

    # -- the step --------------------------------------------------------------------------------
    def start(self, peer: Any, request: StepRequest, episode: int, start_time: float
              ) -> Optional[Tuple[str, str]]:
        """The seated MDP's step ``request`` in the current epoch, while the loop is ready,
        in episode ``episode`` (started at ``start_time``): the step starts with the human's
        action; or (code, why) it is refused."""
        if request.step != self.expected_step:
            return INVALID, f"expected step {self.expected_step}, not {request.step}"
        if request.state not in self.task.human_states:
            return INVALID, f"unknown human state {request.state!r}"
        try:
            service = self.task.human_service_for(request.action, request.state)
        except ValueError as exc:
            return INVALID, str(exc)
        report = StepReport(epoch=request.epoch, episode=episode, step=request.step,
                            human_action=request.action, human_state=request.state,
                            human_state_index=self.task.human_states.index(request.state),
                            human_reward=request.reward, episode_start_time=start_time)
        self.current = StepUnderWay(request, peer, report)
        self._call(ActHuman, service=service)
        return None

    def call_done(self, call: Call, result: Any) -> Optional[Any]:
        """A call of the step under way came back (``call.step`` is its): the next call, or
        :class:`StepActed` when the outcome is read, or :class:`StepFailed`."""
        ctx = self.current
        report = ctx.report
        if isinstance(result, Fault):
            return self.fail(f"{what_call(call)} failed: {result.message}")
        try:
            if isinstance(call, ActHuman):
                report.human_acted = bool(result.success)
                report.human_result = result.message
                ctx.stage = "observe"
                self._call(ObserveWorld, purpose="observe")
            elif isinstance(call, ObserveWorld) and call.purpose == "observe":
                raw = self.task.raw_bits(result)
                if self.task.noise is not None:
                    raw, report.observation_noise = self.task.noise(raw, self._noise_rng)
                bits, report.robot_observation = self._observation_map(raw)
                report.human_observation = self.task.predicates_text(result.predicates)
                report.observation_bits = bits
                if self.task.reacts:
                    # His state after this step follows the robot's action: labelled then.
                    # The planner's log gets the true state as he acts.
                    report.robot_state = self.tracker.label
                else:
                    report.robot_state = self.tracker.update(report.human_state,
                                                             report.human_action)
                ctx.stage = "decide"
                ctx.decided_on = report.robot_state
                self._call(Decide, observation=report.robot_observation, bits=raw,
                           state=report.robot_state,
                           elapsed=sim_span(report.episode_start_time, result.sim_time))
            elif isinstance(call, Decide):
                if result.action not in self.task.robot_action_services:
                    return self.fail(f"the robot planner answered an unknown action "
                                     f"{result.action!r}")
                for name, reported_as in DECISION_IN_REPORT.items():
                    setattr(report, reported_as, getattr(result, name))
                ctx.stage = "robot"
                if self.task.robot_action_services[result.action] is None:
                    report.robot_result = "the robot stays idle and keeps observing"
                    ctx.stage = "outcome"
                    self._call(ObserveWorld, purpose="outcome")
                else:
                    self._call(ActRobot, action=result.action)
            elif isinstance(call, ActRobot):
                report.robot_acted = bool(result.success)
                report.robot_result = result.message
                ctx.stage = "outcome"
                self._call(ObserveWorld, purpose="outcome")
            elif isinstance(call, ObserveWorld) and call.purpose == "outcome":
                report.sim_time = result.sim_time
                report.object_holder = result.holder
                report.object_left_belt = bool(result.left_belt)
                return StepActed(report)
        except (AttributeError, TypeError, ValueError) as exc:
            # The interface answered something that is not what was asked for.
            return self.fail(f"{what_call(call)} answered nonsense: {exc}")
        return None

    def finish(self, reason: str, stops: bool, played_out: bool) -> Optional[StepReport]:
        """The step's outcome is read and the episode said whether it ends (``reason``; the
        MDP ``stops`` stepping; ``played_out``: no episode is left after it): the MDP is
        answered. The report, published, when the step is complete; None when a human who
        hears the robot is still to react (:meth:`react` completes it)."""
        ctx = self.current
        report = ctx.report
        report.episode_over = bool(reason)
        report.end_reason = reason
        reacts = self.task.reacts
        if not reacts:
            self.current = None
            self.expected_step = report.step + 1
            self.outbox.emit(PublishStep(report))
        self.outbox.emit(MdpStepDone(ctx.peer, ctx.request.reply, report.epoch, report.step,
                                     report.robot_action, report.robot_acted,
                                     report.robot_result, report.episode, stops, reason))
        if reacts:
            # The step is complete when the human tells his state after the robot acted.
            ctx.stage, ctx.played_out = "react", played_out
            self._arm_react_timer(ctx)
            return None
        return report

    def react(self, peer: Any, request: ReactionRequest) -> Optional[Any]:
        """The seated MDP's reaction of the current epoch: the step awaiting it takes its
        state (and label) and is complete (:class:`StepComplete`); refused when no step
        awaits it (None); one naming a state the task does not have fails the step
        (:class:`StepFailed`)."""
        ctx = self.current
        if ctx is None or ctx.stage != "react" or request.step != ctx.request.step:
            awaited = f"step {ctx.request.step} awaits one" if ctx is not None and \
                ctx.stage == "react" else "no step awaits one"
            self.outbox.emit(reaction_refused(peer, request, INVALID,
                                              f"no reaction expected for step {request.step} "
                                              f"({awaited})"))
            return None
        if request.state not in self.task.human_states:
            self.outbox.emit(reaction_refused(peer, request, INVALID,
                                              f"unknown human state {request.state!r}"))
            return self.fail(f"the human's reaction names an unknown state "
                             f"{request.state!r}", answered=True)
        report = ctx.report
        report.human_state = request.state
        report.human_state_index = self.task.human_states.index(request.state)
        report.human_reward = request.reward
        report.reaction = "manual" if request.manual else (request.rule or "?")
        report.robot_state = self.tracker.update(request.state, report.human_action)
        self.current = None
        self.expected_step = report.step + 1
        self.outbox.emit(PublishStep(report))
        return StepComplete(report, ctx.played_out)

    def fail(self, why: str, answered: bool = False) -> StepFailed:
        """The step under way failed: published with its fault, refused to the MDP (unless
        it was ``answered`` already: a reacting human's step), and said."""
        ctx, self.current = self.current, None
        report = ctx.report
        report.fault = why
        self.outbox.emit(PublishStep(report))
        if not answered:
            self.outbox.emit(MdpRefused(ctx.peer, ctx.request.reply, report.epoch, report.step,
                                        FAILED, f"step {report.step} failed: {why}"))
        self.outbox.note("error", f"step {report.step} failed: {why}; the loop starts again "
                                  "from a reset")
        return StepFailed(why)

    # -- waits -----------------------------------------------------------------------------------
    def _call(self, kind: type, **fields: Any) -> Call:
        ctx = self.current
        call = self.outbox.call(kind, ctx.report.epoch, ctx.request.step, **fields)
        self._arm_wait_timer(call.id, 0.0)
        return call

    def _arm_wait_timer(self, call_id: int, waited: float) -> None:
        """Look at a step's call again after the next ``wait_note_every`` seconds (or at the
        world's timeout, if that comes first)."""
        call = self.outbox.outstanding[call_id]
        every = self.config.wait_note_every
        if isinstance(call, (ActHuman, ObserveWorld)):
            every = min(every, self.config.world_call_timeout - waited)
        elif isinstance(call, ActRobot) and not waited:
            every = max(every, self._normal_robot_wait())
        self._wait_timers[self.outbox.timer(every)] = (call_id, waited + every)

    def _normal_robot_wait(self) -> float:
        """The longest normal wait for the robot executor, s (:data:`ROBOT_WAIT_ACTIONS`)."""
        return ROBOT_WAIT_ACTIONS * self.config.task.robot_action_seconds

    def _arm_react_timer(self, ctx: StepUnderWay, waited: float = 0.0) -> None:
        every = self.config.wait_note_every
        ctx.react_timer = self.outbox.timer(every)
        self._react_waits = (ctx.react_timer, waited + every)

    def owns_timer(self, timer_id: int) -> bool:
        ctx = self.current
        return timer_id in self._wait_timers or (
            ctx is not None and ctx.stage == "react" and timer_id == ctx.react_timer)

    def timer_fired(self, timer_id: int, epoch: Optional[int]) -> Optional[StepFailed]:
        """A timer of the step's (:meth:`owns_timer`) ran out: say what the step waits for,
        or fail it (:class:`StepFailed`) when the world has not answered in time."""
        if timer_id in self._wait_timers:
            return self._step_waits(*self._wait_timers.pop(timer_id), epoch)
        ctx = self.current
        waited = self._react_waits[1]
        self.outbox.note("warn", f"step {ctx.request.step} waits for the human's reaction to "
                                 f"the robot's {ctx.report.robot_action} (the MDP process: in "
                                 f"manual mode, a state to be typed): {waited:g} s so far")
        self._arm_react_timer(ctx, waited)
        return None

    def _step_waits(self, call_id: int, waited: float, epoch: Optional[int]
                    ) -> Optional[StepFailed]:
        """A step's call has been out for ``waited`` seconds: say so, or fail the step when
        it is a call to the world and the world's timeout has passed."""
        call = self.outbox.outstanding.get(call_id)
        ctx = self.current
        if call is None or ctx is None or call.epoch != epoch or \
                call.step != ctx.request.step:
            return None
        world = isinstance(call, (ActHuman, ObserveWorld))
        if world and waited >= self.config.world_call_timeout:
            return self.fail(
                f"{what_call(call)} has not answered in {waited:g} s (world_call_timeout): "
                "the world may be serving other callers of its services first")
        normal = self._normal_robot_wait() if isinstance(call, ActRobot) else 0.0
        past = (f" (more than {ROBOT_WAIT_ACTIONS} of the task's robot actions take: "
                f"{normal:g} s simulated)") if normal > self.config.wait_note_every else ""
        self.outbox.note("warn", f"step {call.step} waits for {what_call(call)}: {waited:g} s "
                                 f"so far{past}")
        self._arm_wait_timer(call_id, waited)
        return None


def what_call(call: Call) -> str:
    """What a call was, for a failed step's line."""
    if isinstance(call, ActHuman):
        return f"the human's action (/human/{call.service})"
    if isinstance(call, ObserveWorld):
        return "the world's snapshot"
    if isinstance(call, Decide):
        return "the robot planner"
    if isinstance(call, ActRobot):
        return f"the robot executor ({call.action})"
    return type(call).__name__
