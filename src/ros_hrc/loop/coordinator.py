"""The episode coordinator: the one owner of the loop's step (DESIGN §2), Sans-I/O.

It holds the step number, the epoch, the order of a step, episode ends and resets, and
nothing else does. It never calls anything: it is told what happened (an MDP connected, a
step was asked for, a call came back, a reset was asked for) and answers with *effects*, what
to do next, which an adapter carries out and reports back (:mod:`ros_hrc.loop.runner` does
this with threads; the unit tests do it by hand). Like websockets' ``Connection``: events in
through methods, effects out through :meth:`Coordinator.effects`. What goes in and out (the
answers it takes, the calls and notices it emits, a step's report) is declared in
:mod:`ros_hrc.loop.effects`; this module is the machine.

The four interfaces it sees, through the calls it emits:

* the **world**: :class:`ActHuman` (the human's action), :class:`ObserveWorld` (one atomic
  snapshot: the six predicates and where the object is), :class:`ResetWorld`;
* the **human MDP**: one client is *seated* and steps; its steps come in through
  :meth:`Coordinator.step_requested`, answers go out as :class:`MdpStepDone`,
  :class:`MdpRefused`, :class:`MdpReset`; a second client is refused (:class:`SeatRefused`);
* the **robot planner**: :class:`Decide` (observation in, decision back), :class:`ResetPlanner`;
* the **robot executor**: :class:`ActRobot`.

One step, in this order (observe -> decide -> act)::

    MDP step(epoch, n, action, state) -> ActHuman -> ObserveWorld -> Decide -> ActRobot
        -> ObserveWorld (the outcome) -> StepReport published, MdpStepDone, episode end?

A human who hears the robot (a task with reaction rules) steps with the state he acts in
(a grasp's outcome drawn first); his answer is ``MdpStepDone`` (the robot's action, the end),
and only his reaction (:meth:`Coordinator.reaction_received`: his state after the robot
acted) completes the step: the report shows that state, labelled, and is published then::

    ... -> ObserveWorld (the outcome) -> MdpStepDone -> the MDP's reaction -> StepReport
        published, episode end?

**The epoch.** Every reset mints a new epoch, and every call carries the epoch it was made in.
:meth:`Coordinator.call_done` is the one place where anything from an older epoch is dropped.
A reset first waits for the calls still out (a world action under way is interrupted by an
early world reset), then resets the world and the planner into the new epoch, and only then
tells the MDP, so nothing of the old epoch can act in the new one. Resets asked for while one
is under way join it (a burst of fifty is one reset).

**Episode numbers.** An episode's number names its random streams (:mod:`ros_hrc.streams`:
the MDP, the world and the planner reseed from (seed, episode) at its reset), so it is the
study's number, not a count of resets. Without a schedule (a live launch) every reset that
succeeds starts the next number, 1, 2, 3 ... With one (``CoordinatorConfig.episodes``, an
experiment cell's episodes, e.g. 5 and 7 only) the episodes are the schedule's, in order: the
next one starts only after an episode *ended* (success, the object left the belt, the step
limit, the goal); a reset before that (a failed step, a process that restarted) plays the same
episode again from its start, so every scheduled episode is played whole, on its own streams.
After the schedule's last episode ended the loop waits: no reset starts another.

**The task.** What the loop knows of the collaboration task (the human's states and
actions, the world service of each action, the bits -> observation map, the robot's true
state, the observation noise) is the configuration's :class:`~ros_hrc.tasks.definition.Task`
(the seed's by default); the coordinator names none. A task with observation noise draws it
from the stream of (``seed``, episode, "observation") (:mod:`ros_hrc.streams`),
restarted at each episode's start, so an episode's noise is its own whatever ran before it.

**A sequence of tasks** (``CoordinatorConfig.tasks`` N > 0; docs/sequences.md). Each task
is an episode, played by the human the schedule names (``CoordinatorConfig.schedule``; the
``human_model`` every task without one); its reset tells the planner the task's number and
true type and the MDP its human model (and drift). A task ends as an episode does, or when
``task_timeout`` simulated seconds have passed since its start (``task_timeout``); then the
coordinator measures its :class:`~ros_hrc.tasks.utility.TaskOutcome` (the human's warnings,
the robot's pre-emption: it took the object while the human's true state, as the robot
decided, was not one that needs help), asks the robot process for its part
(:class:`EndTask`, answered with its selector's report), publishes the task
(:class:`PublishTask`) and resets into the next task by itself, whatever
``on_episode_end`` says. After the N-th task it says the sequence is over; a reset then starts
a new sequence from its first task (the robot process makes a fresh selector), at once with
``on_episode_end:=reset`` (while the ``episodes`` asked for last), else on Enter. A task cut
short (a failed step, a reset asked for) is played again, under the same number.

**Failures.** A call that fails (a fault: the service or process is gone, or answered
nonsense) fails its step visibly (the report's ``fault``), and the loop recovers by a reset,
retried every ``retry_delay`` seconds until it succeeds (a respawned process comes back). A
world action that is *refused* (a grasp out of reach) is not a fault: it is what happened.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Sequence, Tuple

from ros_hrc.loop.display import counted
from ros_hrc.loop.effects import (BUSY, DECISION_IN_REPORT, EPISODE_IS_OVER, FAILED, INVALID,
                                  NOT_READY, SEAT_TAKEN, STALE, ActHuman, ActRobot, Call,
                                  Decide, Effect, EndTask, Fault, MdpRefused, MdpReset,
                                  MdpStepDone, Note, ObserveWorld, Outcome, PublishStep,
                                  PublishTask, ReactionRequest, ResetDone, ResetPlanner,
                                  ResetWorld, SeatRefused, Snapshot, StepReport, StepRequest,
                                  TaskAnswer, TaskStatusReport, Timer)
from ros_hrc import settings
from ros_hrc.streams import EpisodeSchedule, generator
from ros_hrc.tasks.definition import Task
from ros_hrc.tasks.schedule import Schedule, TaskPlay, type_name
from ros_hrc.tasks.seed import SEED
from ros_hrc.tasks.utility import TaskOutcome, sim_span, task_utility


#: Episode policies after an episode ends (the ``on_episode_end`` setting).
EPISODE_END_POLICIES = settings.SETTINGS["on_episode_end"].choices

#: The phases of the loop (ENDED: the run is over, the world ends with it: nothing more).
IDLE, RESETTING, READY, STEPPING, EPISODE_OVER, BROKEN, ENDED = (
    "idle", "resetting", "ready", "stepping", "episode_over", "broken", "ended")

#: Seconds before the first retry of a failed reset; each retry doubles it up to
#: :data:`MAX_RETRY_DELAY`.
RETRY_DELAY = 1.0
MAX_RETRY_DELAY = 10.0
#: Seconds after a reset finished during which a reset asked for from outside is that reset.
RESET_JOIN_WINDOW = 1.0
#: Seconds between the lines that say what a step waits for.
WAIT_NOTE_EVERY = 5.0
#: Seconds a step waits for one call to the world before it fails.
WORLD_CALL_TIMEOUT = 30.0
#: A call to the robot executor is normal for this many of the task's robot actions
#: (``Task.robot_action_seconds``, simulated, at the default real-time factor 1): it may wait
#: behind the robot's previous action still under way (FABRIC's grasp is answered as it
#: starts, then plans and carries on) and then take its own. Its first wait line comes after
#: that, or after ``wait_note_every`` when that is longer (docs/loop.md).
ROBOT_WAIT_ACTIONS = 2


@dataclass(frozen=True)
class CoordinatorConfig:
    """How episodes end and how the loop recovers.

    ``max_steps``: end an episode after this many steps (0: no limit). ``end_on_goal``: also
    end it when the human MDP reaches ``goal_state`` (the seed's end), besides the world's
    ends (someone holds the object, or it left the belt). ``on_episode_end``: ``wait`` for a
    reset, ``reset`` at once, or ``continue`` stepping. ``retry_delay``: seconds between
    attempts to recover by a reset (doubling up to ``max_retry_delay``). ``first_epoch``: the
    first epoch minted (adapters give a random one, so a restarted coordinator never reuses
    an epoch of its predecessor). ``reset_join_window``: a reset asked for from outside
    (``reset_requested``) the same way as the reset that finished, less than this many
    seconds after it or after the latest request that joined it, while the loop steps, is that
    reset (a burst of calls is one reset, however long it is spread). ``wait_note_every``: while a
    step's call is out, say every this many seconds what the step waits for.
    ``world_call_timeout``: a step whose call to the world (the human's action, a snapshot)
    has not come back after this many seconds fails, naming the call. ``episodes``: the
    episode numbers to play, in order (None: 1, 2, 3 ...; see the module docstring).
    ``task``: the collaboration task (the seed's by default); ``goal_state`` None is the
    task's goal. ``seed``: the run's seed, whose (seed, episode) stream the task's
    observation noise draws from. ``human_model``: the human model's name or path, for the
    task's labels of the robot's true state (fabric: a tired human's). ``tasks``: play a
    sequence of this many tasks (0: none; see the module docstring), ``schedule`` says who
    plays each (None: ``human_model`` every task), ``task_timeout``: simulated seconds after
    which a task of the sequence ends with outcome timeout."""

    max_steps: int = settings.default("max_steps")
    end_on_goal: bool = settings.default("end_on_goal")
    goal_state: Optional[str] = None
    on_episode_end: str = settings.default("on_episode_end")
    retry_delay: float = RETRY_DELAY
    max_retry_delay: float = MAX_RETRY_DELAY
    first_epoch: int = 1
    reset_join_window: float = RESET_JOIN_WINDOW
    wait_note_every: float = WAIT_NOTE_EVERY
    world_call_timeout: float = WORLD_CALL_TIMEOUT
    episodes: Optional[EpisodeSchedule] = None
    task: Task = SEED
    seed: int = settings.default("seed")
    human_model: str = ""
    tasks: int = 0
    schedule: Optional[Schedule] = None
    task_timeout: Optional[float] = None

    def __post_init__(self) -> None:
        if self.goal_state is None:
            object.__setattr__(self, "goal_state", self.task.goal_state)
        if self.task_timeout is None:
            object.__setattr__(self, "task_timeout", self.task.task_timeout)
        if self.tasks < 0 or not self.task_timeout > 0:
            raise ValueError("tasks >= 0 and task_timeout > 0 are required")
        if self.on_episode_end not in EPISODE_END_POLICIES:
            raise ValueError(f"on_episode_end must be one of {', '.join(EPISODE_END_POLICIES)}, "
                             f"not {self.on_episode_end!r}")
        if self.max_steps < 0 or self.retry_delay <= 0 or self.first_epoch < 0:
            raise ValueError("max_steps >= 0, retry_delay > 0 and first_epoch >= 0 are required")
        if (self.reset_join_window < 0 or self.wait_note_every <= 0
                or self.world_call_timeout <= 0):
            raise ValueError("reset_join_window >= 0, wait_note_every > 0 and "
                             "world_call_timeout > 0 are required")


@dataclass
class _StepContext:
    request: StepRequest
    peer: Any
    report: StepReport
    stage: str = "human"   # human -> observe -> decide -> robot -> outcome (-> react)
    played_out: bool = False   # (react) no episode of the schedule is left after this one
    react_timer: Optional[int] = None
    decided_on: str = ""       # the robot's true state when it decided (pre-emptions)


class Coordinator:
    """The loop's state machine; see the module docstring."""

    def __init__(self, config: Optional[CoordinatorConfig] = None) -> None:
        self.config = config or CoordinatorConfig()
        self.phase = IDLE
        self.epoch: Optional[int] = None
        self.episode = 0
        self.seat: Any = None
        self.expected_step = 0
        self.task = self.config.task
        self.tracker = self.task.new_tracker(self.config.human_model)
        self._observation_map = self.task.observation_map()
        self._noise_rng = None          # the episode's "observation" stream (noise, labels)
        self._next_epoch = self.config.first_epoch
        self._ids = itertools.count(1)
        self._effects: List[Effect] = []
        self._outstanding: Dict[int, Call] = {}
        self._step: Optional[_StepContext] = None
        self._episode_ended = False     # with on_episode_end=continue: report the end once
        self._episode_done = False      # the current episode ended (not only cut short)
        self._started_any = False       # an episode has started since this coordinator began
        self._episode_start_time = 0.0
        # the reset under way
        self._reset_tokens: List[Any] = []
        self._reset_reason = ""
        self._reset_stage = ""          # draining -> resetting -> starting
        self._reset_calls: Dict[int, str] = {}
        self._reset_problems: List[str] = []
        self._reset_parts_done: List[str] = []
        self._retry_timer: Optional[int] = None
        self._retry_delay = self.config.retry_delay
        self._join_timer: Optional[int] = None   # runs while a finished reset can be joined
        self._join_reason = ""          # how that reset was asked for
        self._reset_asked = ""          # how the reset under way was asked for from outside
        self._last_reset_text = ""
        self._wait_timers: Dict[int, Tuple[int, float]] = {}   # timer -> (call id, waited s)
        self._react_waits: Tuple[Optional[int], float] = (None, 0.0)   # (timer, waited s)
        self.dropped = 0                # results of an older epoch, dropped
        # a sequence of tasks (config.tasks > 0)
        self.tasks_done = 0             # tasks of the sequence that ended
        self.sequences_started = 1      # sequences begun since the start (a reset after a
                                        # sequence's last task begins the next)
        self.task_index = 0             # the task under way (0: none yet)
        self.play: Optional[TaskPlay] = None   # who plays it
        self._task_warnings = 0
        #: Grasps and points while a warning was in force in this task (Task.warning_in_force).
        self._task_against_warning = 0
        self._task_warning_in_force = False
        self._task_preempted = False
        self._task_ending: Optional[Tuple[int, TaskStatusReport]] = None   # (call id, report)

    # -- output -------------------------------------------------------------------------------
    def effects(self) -> List[Effect]:
        """Take the effects produced so far, in order."""
        out, self._effects = self._effects, []
        return out

    @property
    def outstanding(self) -> Sequence[Call]:
        """Calls made and not answered yet."""
        return tuple(self._outstanding.values())

    def _emit(self, effect: Effect) -> None:
        self._effects.append(effect)

    def _call(self, kind, step: Optional[int], **fields) -> Call:
        call = kind(id=next(self._ids), epoch=self.epoch, step=step, **fields)
        self._outstanding[call.id] = call
        self._emit(call)
        if step is not None:
            self._arm_wait_timer(call.id, 0.0)
        return call

    def _arm_wait_timer(self, call_id: int, waited: float) -> None:
        """Look at a step's call again after the next ``wait_note_every`` seconds (or at the
        world's timeout, if that comes first)."""
        call = self._outstanding[call_id]
        every = self.config.wait_note_every
        if isinstance(call, (ActHuman, ObserveWorld)):
            every = min(every, self.config.world_call_timeout - waited)
        elif isinstance(call, ActRobot) and not waited:
            every = max(every, self._normal_robot_wait())
        timer = next(self._ids)
        self._wait_timers[timer] = (call_id, waited + every)
        self._emit(Timer(timer, every))

    def _normal_robot_wait(self) -> float:
        """The longest normal wait for the robot executor, s (:data:`ROBOT_WAIT_ACTIONS`)."""
        return ROBOT_WAIT_ACTIONS * self.task.robot_action_seconds

    def _note(self, level: str, text: str) -> None:
        self._emit(Note(level, text))

    # -- the MDP's seat -------------------------------------------------------------------------
    def mdp_connected(self, peer: Any) -> None:
        """A client connected to the human MDP's port. The first one is seated (a reset
        starts its first episode); any other is refused while one is seated."""
        if self.phase == ENDED:
            return
        if self.seat is not None and self.seat != peer:
            self._emit(SeatRefused(peer, "refused: an MDP process is already served on this "
                                         "port; one MDP at a time (start the stack with "
                                         "start_mdp:=false to run your own)"))
            return
        if self.seat == peer:
            return
        self.seat = peer
        self._note("info", "an MDP process connected: it is served")
        self._begin_reset("an MDP process connected", None)

    def mdp_disconnected(self, peer: Any, stopped: bool = False) -> None:
        """A client of the MDP's port left. If it was the seated one, the seat is free and
        the loop resets (the next MDP to connect is served after a reset of its own).

        ``stopped``: it closed its link itself (it was asked to stop, as every process is
        when the launch stops): nothing to report and nothing to recover from; its step
        under way, if any, is dropped unreported, and the next MDP to connect is served
        after its reset, as always."""
        if peer != self.seat:
            return
        self.seat = None
        if self.phase == ENDED:
            return
        if stopped:
            self._note("debug", "the MDP process stopped: the next one to connect is served "
                                "after a reset")
            if self._step is not None:
                self._step = None
                self.phase = READY
            return
        self._note("warn", "the MDP process left: waiting for the next one")
        self._begin_reset("the MDP process left", None)

    def run_ended(self, why: str) -> None:
        """The run ends: the world is shutting down (its window was closed, the launch
        stops), ``why``. Not a fault: nothing is reported, retried or reset from now on; the
        step under way is dropped, a reset asked for is answered that none comes."""
        if self.phase == ENDED:
            return
        self.phase = ENDED
        self._step = None
        self._retry_timer = self._join_timer = None
        self._note("debug", f"the run ends: {why}")
        tokens, self._reset_tokens = tuple(self._reset_tokens), []
        if tokens:
            self._emit(ResetDone(tokens, False, f"no reset: the run ends ({why})"))

    # -- steps ---------------------------------------------------------------------------------
    def step_requested(self, peer: Any, request: StepRequest) -> None:
        """The MDP asks for a step. Refused (with a code and a reason) unless it comes from
        the seated MDP, in the current epoch, with the expected number, while the loop is
        ready; otherwise the step starts with the human's action."""
        def refuse(code: str, message: str) -> None:
            # The protocol's word: after a refused step the MDP waits for the next reset. A
            # reset under way (not_ready, failed) or the episode's end (episode_over: the
            # reset comes when asked for) brings one; for the others this one does.
            resets = (peer == self.seat and code in (STALE, BUSY, INVALID)
                      and self.phase in (READY, STEPPING))
            if resets:
                message += "; the loop resets: wait for the reset message"
            self._emit(MdpRefused(peer, request.reply, request.epoch, request.step, code,
                                  message))
            if resets:
                self._begin_reset(f"the MDP's step {request.step} was refused ({code}: "
                                  f"{message.split(';')[0]})", None)

        if self.phase == ENDED:
            return refuse(NOT_READY, "the run ends: the world is shutting down")
        if peer != self.seat:
            return refuse(SEAT_TAKEN, "another MDP process is being served")
        if request.epoch != self.epoch or self.epoch is None:
            return refuse(STALE, f"epoch {request.epoch} is over (the loop was reset): wait "
                                 "for the reset message and start again from step 0")
        if self.phase == STEPPING:
            return refuse(BUSY, f"step {self._step.request.step} is still under way")
        if self.phase == EPISODE_OVER:
            return refuse(EPISODE_IS_OVER, "the episode is over: reset for a new one")
        if self.phase != READY:
            return refuse(NOT_READY, f"the loop is {self.phase}, not ready for a step")
        if request.step != self.expected_step:
            return refuse(INVALID, f"expected step {self.expected_step}, not {request.step}")
        if request.state not in self.task.human_states:
            return refuse(INVALID, f"unknown human state {request.state!r}")
        try:
            service = self.task.human_service_for(request.action, request.state)
        except ValueError as exc:
            return refuse(INVALID, str(exc))
        report = StepReport(epoch=self.epoch, episode=self.episode, step=request.step,
                            human_action=request.action, human_state=request.state,
                            human_state_index=self.task.human_states.index(request.state),
                            human_reward=request.reward,
                            episode_start_time=self._episode_start_time)
        self._step = _StepContext(request, peer, report)
        self.phase = STEPPING
        self._call(ActHuman, request.step, service=service)

    def reaction_received(self, peer: Any, request: ReactionRequest) -> None:
        """A human who hears the robot tells his state after the robot acted in the step
        answered last: the step's report takes it (and its label) and the step is complete.
        A reaction from another client, of another epoch or for no step awaiting one is
        refused (the loop goes on); one naming a state the task does not have fails the step."""
        def refuse(code: str, message: str) -> None:
            self._emit(MdpRefused(peer, request.reply, request.epoch, request.step, code,
                                  message, in_reply_to="reaction"))

        ctx = self._step
        if peer != self.seat:
            return refuse(SEAT_TAKEN, "another MDP process is being served")
        if request.epoch != self.epoch or self.epoch is None:
            return refuse(STALE, f"epoch {request.epoch} is over (the loop was reset)")
        if ctx is None or ctx.stage != "react" or request.step != ctx.request.step:
            awaited = f"step {ctx.request.step} awaits one" if ctx is not None and \
                ctx.stage == "react" else "no step awaits one"
            return refuse(INVALID, f"no reaction expected for step {request.step} ({awaited})")
        if request.state not in self.task.human_states:
            refuse(INVALID, f"unknown human state {request.state!r}")
            return self._fail_step(f"the human's reaction names an unknown state "
                                   f"{request.state!r}", answered=True)
        report = ctx.report
        report.human_state = request.state
        report.human_state_index = self.task.human_states.index(request.state)
        report.human_reward = request.reward
        report.reaction = "manual" if request.manual else (request.rule or "?")
        report.robot_state = self.tracker.update(request.state, report.human_action)
        self._step = None
        self.expected_step = report.step + 1
        self._emit(PublishStep(report))
        self._after_step(report, report.end_reason, ctx.played_out)

    def _arm_react_timer(self, ctx: _StepContext, waited: float = 0.0) -> None:
        every = self.config.wait_note_every
        ctx.react_timer = next(self._ids)
        self._react_waits = (ctx.react_timer, waited + every)
        self._emit(Timer(ctx.react_timer, every))

    # -- answers --------------------------------------------------------------------------------
    def call_done(self, call_id: int, result: Any) -> None:
        """A call came back with its result (or a :class:`Fault`). The one place where
        results of an older epoch are dropped."""
        call = self._outstanding.pop(call_id, None)
        if call is None or self.phase == ENDED:
            return   # unknown or answered twice, or the run ended: nothing to do
        if isinstance(call, EndTask):
            # The task ended for good: reported even when a reset came meanwhile.
            self._task_reported(call, result)
            self._continue_reset()
            return
        if call.epoch != self.epoch:
            self.dropped += 1
            self._continue_reset()   # a reset may be waiting for this call
            return
        if isinstance(call, (ResetWorld, ResetPlanner)):
            self._reset_call_done(call, result)
        elif isinstance(call, ObserveWorld) and call.purpose == "episode_start":
            self._episode_started(result)
        elif self._step is not None and call.step == self._step.request.step:
            self._step_call_done(call, result)
        self._continue_reset()

    def _step_call_done(self, call: Call, result: Any) -> None:
        ctx = self._step
        report = ctx.report
        if isinstance(result, Fault):
            return self._fail_step(f"{_what(call)} failed: {result.message}")
        try:
            if isinstance(call, ActHuman):
                report.human_acted = bool(result.success)
                report.human_result = result.message
                ctx.stage = "observe"
                self._call(ObserveWorld, call.step, purpose="observe")
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
                self._call(Decide, call.step, observation=report.robot_observation, bits=raw,
                           state=report.robot_state,
                           elapsed=sim_span(self._episode_start_time, result.sim_time))
            elif isinstance(call, Decide):
                if result.action not in self.task.robot_action_services:
                    return self._fail_step(f"the robot planner answered an unknown action "
                                           f"{result.action!r}")
                for name, reported_as in DECISION_IN_REPORT.items():
                    setattr(report, reported_as, getattr(result, name))
                ctx.stage = "robot"
                if self.task.robot_action_services[result.action] is None:
                    report.robot_result = "the robot stays idle and keeps observing"
                    ctx.stage = "outcome"
                    self._call(ObserveWorld, call.step, purpose="outcome")
                else:
                    self._call(ActRobot, call.step, action=result.action)
            elif isinstance(call, ActRobot):
                report.robot_acted = bool(result.success)
                report.robot_result = result.message
                ctx.stage = "outcome"
                self._call(ObserveWorld, call.step, purpose="outcome")
            elif isinstance(call, ObserveWorld) and call.purpose == "outcome":
                report.sim_time = result.sim_time
                report.object_holder = result.holder
                report.object_left_belt = bool(result.left_belt)
                self._finish_step()
        except (AttributeError, TypeError, ValueError) as exc:
            # The interface answered something that is not what was asked for.
            self._fail_step(f"{_what(call)} answered nonsense: {exc}")

    def _finish_step(self) -> None:
        ctx = self._step
        report = ctx.report
        reason = "" if self._episode_ended else self._end_reason(report)
        report.episode_over = bool(reason)
        report.end_reason = reason
        if report.human_action == self.task.human_warning_action:
            self._task_warnings += 1
        self._task_warning_in_force = self.task.warning_in_force(
            self._task_warning_in_force, int(report.observation_bits))
        if self._task_warning_in_force and report.robot_action in self.task.helping_actions:
            self._task_against_warning += 1
        if report.object_holder == "robot" and ctx.decided_on not in self.task.needs_help_states:
            self._task_preempted = True   # it took the object from a human who needed no help
        reacts = self.task.reacts
        if not reacts:
            self._step = None
            self.expected_step = report.step + 1
            self._emit(PublishStep(report))
        if reason:
            self._episode_done = True
        # No episode of the schedule is left after this one: the loop stops here.
        played_out = bool(reason) and self._next_episode() is None
        # The MDP's episode_over means "stop: a reset comes next"; with on_episode_end
        # continue the end is reported (end_reason) and stepping goes on.
        stops = bool(reason) and (self.config.on_episode_end != "continue" or played_out
                                  or self.config.tasks > 0)
        self._emit(MdpStepDone(ctx.peer, ctx.request.reply, self.epoch, report.step,
                               report.robot_action, report.robot_acted, report.robot_result,
                               self.episode, stops, reason))
        if reacts:
            # The step is complete when the human tells his state after the robot acted.
            ctx.stage, ctx.played_out = "react", played_out
            self._arm_react_timer(ctx)
            return
        self._after_step(report, reason, played_out)

    def _after_step(self, report: StepReport, reason: str, played_out: bool) -> None:
        """The step is complete: ready for the next, or the episode's end as configured."""
        self.phase = READY
        if not reason:
            return
        if self.config.tasks:
            return self._end_task(report, reason)
        policy = self.config.on_episode_end
        self._note("info", episode_over_line(self.episode, reason, report.step + 1, policy,
                                             self.config.episodes if played_out else None))
        if played_out:
            self.phase = EPISODE_OVER
        elif policy == "wait":
            self.phase = EPISODE_OVER
        elif policy == "reset":
            self._begin_reset(f"episode {self.episode} over ({reason})", None)
        else:
            self._episode_ended = True

    def _end_reason(self, report: StepReport) -> str:
        if report.object_holder in ("human", "robot"):
            return "success"
        if report.object_left_belt:
            return "object_left_belt"
        if self.config.end_on_goal and report.human_state == self.config.goal_state:
            return "human_goal"
        if self.config.tasks and (sim_span(self._episode_start_time, report.sim_time)
                                  >= self.config.task_timeout):
            return "task_timeout"
        if self.config.max_steps and report.step + 1 >= self.config.max_steps:
            return "step_limit"
        return ""

    def _fail_step(self, why: str, answered: bool = False) -> None:
        """The step failed: published with its fault, refused to the MDP (unless it was
        ``answered`` already: a reacting human's step), the loop recovers by a reset."""
        ctx, self._step = self._step, None
        report = ctx.report
        report.fault = why
        self._emit(PublishStep(report))
        if not answered:
            self._emit(MdpRefused(ctx.peer, ctx.request.reply, self.epoch, report.step, FAILED,
                                  f"step {report.step} failed: {why}"))
        self.phase = BROKEN
        self._note("error", f"step {report.step} failed: {why}; the loop starts again "
                            "from a reset")
        self._begin_reset(f"recovering from a failed step ({why})", None)

    # -- resets ----------------------------------------------------------------------------------
    def reset_requested(self, reason: str, token: Any = None) -> None:
        """Someone asks for a reset (``token`` is answered by :class:`ResetDone`). One asked
        for while a reset is under way joins it; one asked for within ``reset_join_window``
        seconds after a reset finished, while the episode that reset started goes on, is
        that reset (answered at once) when it was asked for the same way (the same
        ``reason``: fifty /hrc/reset calls, not an Enter after an MDP connected) and its
        episode is not over: a burst of calls is one reset."""
        if (self._join_timer is not None and self.phase in (READY, STEPPING)
                and reason == self._join_reason):
            if token is not None:
                self._emit(ResetDone((token,), True, f"{self._last_reset_text} (this request "
                                                     "joined it: it came as it finished)"))
            # The burst goes on: the window runs from its latest request.
            self._join_timer = next(self._ids)
            self._emit(Timer(self._join_timer, self.config.reset_join_window))
            return
        if self.phase != RESETTING:
            self._reset_asked = reason
        self._begin_reset(reason, token)

    def timer_fired(self, timer_id: int) -> None:
        """A :class:`Timer` ran out: retry the reset that failed, say what a step waits for
        (or fail it when the world has not answered in time), or close a reset to joiners."""
        if self.phase == ENDED:
            return
        if timer_id in self._wait_timers:
            return self._step_waits(*self._wait_timers.pop(timer_id))
        ctx = self._step
        if ctx is not None and ctx.stage == "react" and timer_id == ctx.react_timer:
            waited = self._react_waits[1]
            self._note("warn", f"step {ctx.request.step} waits for the human's reaction to the "
                               f"robot's {ctx.report.robot_action} (the MDP process: in manual "
                               f"mode, a state to be typed): {waited:g} s so far")
            return self._arm_react_timer(ctx, waited)
        if timer_id == self._join_timer:
            self._join_timer = None
            return
        if timer_id != self._retry_timer:
            return
        self._retry_timer = None
        if self.phase == BROKEN:
            self._begin_reset(self._reset_reason, None)   # the same reason, not nested

    def _step_waits(self, call_id: int, waited: float) -> None:
        """A step's call has been out for ``waited`` seconds: say so, or fail the step when
        it is a call to the world and the world's timeout has passed."""
        call = self._outstanding.get(call_id)
        ctx = self._step
        if call is None or ctx is None or call.epoch != self.epoch or \
                call.step != ctx.request.step:
            return
        world = isinstance(call, (ActHuman, ObserveWorld))
        if world and waited >= self.config.world_call_timeout:
            return self._fail_step(
                f"{_what(call)} has not answered in {waited:g} s (world_call_timeout): the "
                "world may be serving other callers of its services first")
        normal = self._normal_robot_wait() if isinstance(call, ActRobot) else 0.0
        past = (f" (more than {ROBOT_WAIT_ACTIONS} of the task's robot actions take: "
                f"{normal:g} s simulated)") if normal > self.config.wait_note_every else ""
        self._note("warn", f"step {call.step} waits for {_what(call)}: {waited:g} s so far{past}")
        self._arm_wait_timer(call_id, waited)

    def _next_episode(self) -> Optional[int]:
        """The number of the episode the next reset starts; None when the schedule's last
        episode has ended."""
        schedule = self.config.episodes
        if schedule is None:
            return self.episode + 1
        if not self._started_any:
            return schedule.first()
        if not self._episode_done:
            return self.episode     # cut short: played again, whole, on its own streams
        return schedule.after(self.episode)

    def _begin_reset(self, reason: str, token: Any) -> None:
        if self.phase == ENDED:
            if token is not None:
                self._emit(ResetDone((token,), False, "no reset: the run ends (the world is "
                                                      "shutting down)"))
            return
        if self.phase == RESETTING:
            # Joins the reset under way: nothing has stepped since it began.
            if token is not None:
                self._reset_tokens.append(token)
            return
        if self._next_episode() is None:
            # The schedule is played out: nothing is left to reset into.
            if token is not None:
                self._emit(ResetDone((token,), False, "no reset: the episodes asked for "
                                     f"({self.config.episodes.text()}) are all played"))
            return
        if self.config.tasks and self.tasks_done >= self.config.tasks:
            # The sequence is played: this reset starts a new one, from its first task (the
            # robot process makes a fresh selector for a first task). One stack can so play
            # many sequences: an experiment's cell plays all of its own on one launch.
            self.tasks_done = 0
            self.sequences_started += 1
        self._retry_timer = None
        self.epoch = self._next_epoch
        self._next_epoch += 1
        self.phase = RESETTING
        self._reset_reason = reason
        self._reset_tokens = [token] if token is not None else []
        self._reset_problems = []
        self._reset_parts_done: List[str] = []
        self._reset_calls = {}
        self._reset_stage = "draining"
        self._episode_ended = False
        if self._step is not None:
            ctx, self._step = self._step, None
            if ctx.stage != "react":   # (a reacting human's step was answered already)
                self._emit(MdpRefused(ctx.peer, ctx.request.reply, ctx.request.epoch,
                                      ctx.request.step, STALE,
                                      f"step {ctx.request.step} was interrupted by a reset"))
        if any(isinstance(c, (ActHuman, ActRobot)) for c in self._outstanding.values()):
            # Stop the motions under way now, so the calls waiting on them come back soon.
            self._call(ResetWorld, None, interrupt=True)
        self._continue_reset()

    def _continue_reset(self) -> None:
        if self.phase != RESETTING or self._reset_stage != "draining":
            return
        if any(c.epoch != self.epoch for c in self._outstanding.values()):
            return   # calls of the old epoch still out: they could act after the reset
        if any(isinstance(c, ResetWorld) and c.interrupt for c in self._outstanding.values()):
            return
        self._reset_stage = "resetting"
        self.tracker.reset()
        self.expected_step = 0
        # The episode's number is taken when a reset succeeds: failed attempts take none.
        episode = self._next_episode()
        task_index = true_type = None
        if self.config.tasks:
            self._begin_task()
            task_index, true_type = self.task_index, self.play.true_type
        world = self._call(ResetWorld, None, episode=episode)
        planner = self._call(ResetPlanner, None, episode=episode, task_index=task_index or 0,
                             true_type=true_type or "")
        self._reset_calls = {world.id: "world", planner.id: "robot planner"}

    def _reset_call_done(self, call: Call, result: Any) -> None:
        if isinstance(call, ResetWorld) and call.interrupt:
            return
        what = self._reset_calls.pop(call.id, None)
        if what is None:
            return
        if isinstance(result, Fault):
            self._reset_problems.append(f"{what}: {result.message}")
        elif isinstance(result, Outcome) and not result.success:
            self._reset_problems.append(f"{what}: {result.message}")
        else:
            self._reset_parts_done.append(what)
        if self._reset_calls:
            return
        if self._reset_problems:
            done = ", ".join(self._reset_parts_done) or "nothing"
            return self._reset_failed(f"not reset: {'; '.join(self._reset_problems)}; reset: "
                                      f"{done}; the human MDP is told when all are")
        self._reset_stage = "starting"
        self._call(ObserveWorld, None, purpose="episode_start")

    def _episode_started(self, result: Any) -> None:
        if isinstance(result, Fault):
            return self._reset_failed(f"world: {result.message}")
        if not isinstance(result, Snapshot) or not isinstance(result.sim_time, (int, float)):
            return self._reset_failed(f"world: the snapshot at the episode's start is "
                                      f"{result!r}")
        self._episode_start_time = float(result.sim_time)
        self.episode = self._next_episode()
        self._observation_map = self.task.observation_map()
        self._noise_rng = generator(self.config.seed, self.episode, "observation")
        begin = getattr(self.tracker, "begin_episode", None)
        if begin is not None:
            begin(self._noise_rng)
        self._started_any = True
        self._episode_done = False
        self.phase = READY
        self._retry_delay = self.config.retry_delay
        tokens, self._reset_tokens = tuple(self._reset_tokens), []
        text = (f"world, robot belief and human MDP reset ({self._reset_reason}): episode "
                f"{self.episode}")
        if self._reset_asked and self.config.reset_join_window > 0:
            # Asked for from outside: for a while, more requests asked the same way are it
            # (resets the loop makes itself in between, e.g. at an episode's end, do not
            # close the window).
            self._last_reset_text = text
            self._join_reason, self._reset_asked = self._reset_asked, ""
            self._join_timer = next(self._ids)
            self._emit(Timer(self._join_timer, self.config.reset_join_window))
        task = ""
        if self.config.tasks:
            task = f", task {self.task_index}/{self.config.tasks} ({self.play.true_type})"
            self._task_warnings, self._task_preempted = 0, False
            self._task_against_warning, self._task_warning_in_force = 0, False
        self._note("info", f"RESET ({self._reset_reason}): episode {self.episode}, "
                           f"epoch {self.epoch}{task}")
        if self.seat is not None:
            play = self.play if self.config.tasks else None
            self._emit(MdpReset(self.seat, self.epoch, self.episode, self._reset_reason,
                                **({} if play is None else dict(
                                    task_index=self.task_index, true_type=play.true_type,
                                    human_model=play.human_model, drift_to=play.drift_to,
                                    drift=play.drift))))
        if tokens:
            self._emit(ResetDone(tokens, True, text))

    # -- a sequence of tasks -----------------------------------------------------------------
    def _begin_task(self) -> None:
        """The reset under way starts the next task of the sequence (a task cut short: the
        same one again): who plays it, and his labeller of the robot's true state."""
        self.task_index = self.tasks_done + 1
        schedule = self.config.schedule
        play = schedule.play(self.task_index) if schedule is not None else \
            TaskPlay(self.config.human_model)
        if self.play is None or play.nearest_type != self.play.nearest_type:
            self.tracker = self.task.new_tracker(play.nearest_type)
            self.tracker.reset()
        self.play = play

    def _end_task(self, report: StepReport, reason: str) -> None:
        """Task ``task_index`` ended at the step ``report`` (``reason``: the loop's end
        reason): its outcome measured, the robot process asked for its part."""
        holder = report.object_holder if report.object_holder in ("human", "robot") else ""
        if reason in ("success", "human_goal"):
            outcome, who = "success", holder or "human"
        elif reason == "object_left_belt":
            outcome, who = "fail", ""
        else:   # task_timeout, step_limit
            outcome, who = "timeout", ""
        duration = sim_span(self._episode_start_time, report.sim_time)
        measured = TaskOutcome(outcome, who, self._task_warnings, int(self._task_preempted),
                               duration, self.config.task_timeout)
        utility = task_utility(measured)
        self.tasks_done += 1
        self.phase = EPISODE_OVER      # the MDP was told: it waits for the next reset
        status = TaskStatusReport(
            task_index=self.task_index, tasks=self.config.tasks, episode=self.episode,
            epoch=self.epoch, human_model=type_name(self.play.human_model),
            true_type=self.play.true_type, outcome=outcome, who_succeeded=who,
            warnings=measured.warnings, preemptions=measured.preemptions,
            against_warning=self._task_against_warning,
            steps=report.step + 1, duration=duration, utility=utility, end_reason=reason)
        call = self._call(EndTask, None, task_index=self.task_index, outcome=measured,
                          steps=status.steps, utility=utility)
        self._task_ending = (call.id, status)

    def _task_reported(self, call: EndTask, result: Any) -> None:
        """The robot process answered a task's end: the task is published, then the next
        one starts (unless a reset came meanwhile, or it was the last)."""
        pending, self._task_ending = self._task_ending, None
        if pending is None or pending[0] != call.id:
            return
        status = pending[1]
        if isinstance(result, TaskAnswer):
            for name in ("selector", "policy", "robot_model", "type_names", "type_belief",
                         "signature", "total_disc_reward", "learnt_name", "learnt_value",
                         "learnt_spread"):
                setattr(status, name, getattr(result, name))
            if status.type_belief:
                best = max(range(len(status.type_belief)), key=status.type_belief.__getitem__)
                status.estimation_correct = status.type_names[best] == self.play.nearest_type
        else:
            why = result.message if isinstance(result, Fault) else repr(result)
            status.robot_problem = f"the robot process sent no task report: {why}"
            self._note("warn", f"task {status.task_index}: {status.robot_problem}")
        self._emit(PublishTask(status))
        if self.phase != EPISODE_OVER or call.epoch != self.epoch:
            return     # a reset came meanwhile: it starts the next task
        if self.tasks_done < self.config.tasks:
            self._begin_reset(f"task {status.task_index} over ({status.outcome})", None)
            return
        goes_on = self.config.on_episode_end == "reset" and self._next_episode() is not None
        self._note("info", sequence_over_line(self.config.tasks, goes_on))
        if goes_on:
            self._begin_reset(f"sequence {self.sequences_started} over", None)

    def _reset_failed(self, why: str) -> None:
        self.phase = BROKEN
        tokens, self._reset_tokens = tuple(self._reset_tokens), []
        self._note("error", f"reset failed: {why}; retrying in {self._retry_delay:g} s")
        if tokens:
            self._emit(ResetDone(tokens, False, f"reset failed: {why}; retried in "
                                                f"{self._retry_delay:g} s (then every up to "
                                                f"{self.config.max_retry_delay:g} s) until it "
                                                "works"))
        self._retry_timer = next(self._ids)
        self._emit(Timer(self._retry_timer, self._retry_delay))
        self._retry_delay = min(self._retry_delay * 2, self.config.max_retry_delay)


def episode_over_line(episode: int, reason: str, steps: int, policy: str,
                      played: Optional[EpisodeSchedule] = None) -> str:
    """What the terminal says, once, when an episode ends: how, after how many steps, and
    what happens next by ``policy`` (the ``on_episode_end`` setting), or that the episodes
    asked for (``played``) are all played."""
    over = f"episode {episode} over ({reason}) after {counted(steps, 'step')}"
    if played is not None:
        return (f"{over}: the episodes asked for ({played.text()}) are all played: no reset "
                "starts another")
    if policy == "wait":
        return (f"{over}: Enter (or `rosservice call /hrc/reset`) resets and starts the next, "
                "or on_episode_end:=reset to go on by itself")
    if policy == "reset":
        return f"{over}: the next starts now (on_episode_end:=reset)"
    return f"{over}: stepping goes on (on_episode_end:=continue)"


def sequence_over_line(tasks: int, goes_on: bool = False) -> str:
    """What the terminal says once the sequence's last task ended: and what comes next, a new
    sequence at once (``goes_on``: ``on_episode_end:=reset``) or on Enter."""
    over = (f"the sequence is over: its {counted(tasks, 'task')} are played (/hrc/task_status "
            "has one message each)")
    if goes_on:
        return f"{over}; the next sequence starts now, with a fresh selector (on_episode_end:=reset)"
    return (f"{over}; Enter (or `rosservice call /hrc/reset`) starts a new sequence with a "
            "fresh selector, Ctrl-C ends the launch")


def _what(call: Call) -> str:
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
