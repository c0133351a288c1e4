"""The episode coordinator: the one owner of the loop's step (DESIGN §2), Sans-I/O.

It never calls anything: it is told what happened (an MDP connected, a step was asked for, a
call came back, a reset was asked for, a timer ran out) and answers with *effects*, what to do
next, which an adapter carries out and reports back (:mod:`ros_hrc.loop.runner` does this with
threads; the unit tests do it by hand). Like websockets' ``Connection``: events in through
methods, effects out through :meth:`Coordinator.effects`. What goes in and out (the answers it
takes, the calls and notices it emits, a step's report) is declared in
:mod:`ros_hrc.loop.effects`.

The coordinator is a composition of parts, each Sans-I/O, each with one job and tested alone,
which emit into one :class:`~ros_hrc.loop.outbox.Outbox`:

* :class:`~ros_hrc.loop.step.StepPipeline` (``loop/step.py``): one step, observe -> decide ->
  act, its report and its waits;
* :class:`~ros_hrc.loop.resets.Resets` (``loop/resets.py``): epochs and resets (drain, reset,
  start; joining; retrying);
* :class:`~ros_hrc.loop.schedule.Episodes` (``loop/schedule.py``): the episode schedule, which
  episode a reset starts and when one ends;
* :class:`~ros_hrc.loop.sequence.TaskSequence` (``loop/sequence.py``): a sequence of tasks.

What is its own: the MDP's seat (one client is seated and steps; a second is refused), the
loop's phase (idle, resetting, ready, stepping, episode over, broken, ended), whether a step
may start, and the routing between the parts: a step that fails starts a reset, an episode's
end waits, resets or goes on, a task's end resets into the next.

**The epoch.** Every reset mints a new epoch, and every call carries the epoch it was made in.
:meth:`Coordinator.call_done` is the one place where anything from an older epoch is dropped.
"""
from __future__ import annotations

from typing import Any, List, Optional, Sequence

from ros_hrc.loop.config import (EPISODE_END_POLICIES, MAX_RETRY_DELAY, RESET_JOIN_WINDOW,
                                 RETRY_DELAY, WAIT_NOTE_EVERY, WORLD_CALL_TIMEOUT,
                                 CoordinatorConfig)
from ros_hrc.loop.effects import (BUSY, EPISODE_IS_OVER, FAILED, INVALID, NOT_READY, SEAT_TAKEN,
                                  STALE, Call, Effect, EndTask, MdpRefused, MdpReset,
                                  ObserveWorld, ReactionRequest, ResetPlanner, ResetWorld,
                                  SeatRefused, StepReport, StepRequest)
from ros_hrc.loop.outbox import Outbox
from ros_hrc.loop.resets import RETRY, Resets
from ros_hrc.loop.schedule import RESET, WAIT, Episodes, episode_over_line
from ros_hrc.loop.sequence import TaskSequence, sequence_over_line
from ros_hrc.loop.step import (StepActed, StepComplete, StepFailed, StepPipeline,
                               reaction_refused, what_call)

__all__ = [
    "Coordinator", "CoordinatorConfig", "EPISODE_END_POLICIES", "RETRY_DELAY",
    "MAX_RETRY_DELAY", "RESET_JOIN_WINDOW", "WAIT_NOTE_EVERY", "WORLD_CALL_TIMEOUT",
    "IDLE", "RESETTING", "READY", "STEPPING", "EPISODE_OVER", "BROKEN", "ENDED",
    "STALE", "BUSY", "SEAT_TAKEN", "INVALID", "EPISODE_IS_OVER", "FAILED", "NOT_READY",
    "episode_over_line", "sequence_over_line"]

#: The phases of the loop (ENDED: the run is over, the world ends with it: nothing more).
IDLE, RESETTING, READY, STEPPING, EPISODE_OVER, BROKEN, ENDED = (
    "idle", "resetting", "ready", "stepping", "episode_over", "broken", "ended")


class Coordinator:
    """The loop's state machine; see the module docstring."""

    def __init__(self, config: Optional[CoordinatorConfig] = None) -> None:
        self.config = config or CoordinatorConfig()
        self.task = self.config.task
        self.phase = IDLE
        self.seat: Any = None
        self.dropped = 0                # results of an older epoch, dropped
        self.outbox = Outbox()
        self.resets = Resets(self.config, self.outbox)
        self.step = StepPipeline(self.config, self.outbox)
        self.episodes = Episodes(self.config)
        self.sequence = TaskSequence(self.config, self.outbox)

    # -- where the loop stands (the parts' own) ----------------------------------------------
    @property
    def epoch(self) -> Optional[int]:
        return self.resets.epoch

    @property
    def episode(self) -> int:
        return self.episodes.number

    @property
    def expected_step(self) -> int:
        return self.step.expected_step

    @property
    def tracker(self) -> Any:
        return self.step.tracker

    @property
    def tasks_done(self) -> int:
        return self.sequence.tasks_done

    @property
    def sequences_started(self) -> int:
        return self.sequence.sequences_started

    @property
    def task_index(self) -> int:
        return self.sequence.task_index

    @property
    def play(self) -> Any:
        return self.sequence.play

    # -- output -------------------------------------------------------------------------------
    def effects(self) -> List[Effect]:
        """Take the effects produced so far, in order."""
        return self.outbox.take()

    @property
    def outstanding(self) -> Sequence[Call]:
        """Calls made and not answered yet."""
        return tuple(self.outbox.outstanding.values())

    # -- the MDP's seat -------------------------------------------------------------------------
    def mdp_connected(self, peer: Any) -> None:
        """A client connected to the human MDP's port. The first one is seated (a reset
        starts its first episode); any other is refused while one is seated."""
        if self.phase == ENDED:
            return
        if self.seat is not None and self.seat != peer:
            self.outbox.emit(SeatRefused(peer, "refused: an MDP process is already served on "
                                               "this port; one MDP at a time (start the stack "
                                               "with start_mdp:=false to run your own)"))
            return
        if self.seat == peer:
            return
        self.seat = peer
        self.outbox.note("info", "an MDP process connected: it is served")
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
            self.outbox.note("debug", "the MDP process stopped: the next one to connect is "
                                      "served after a reset")
            if self.step.drop():
                self.phase = READY
            return
        self.outbox.note("warn", "the MDP process left: waiting for the next one")
        self._begin_reset("the MDP process left", None)

    def run_ended(self, why: str) -> None:
        """The run ends: the world is shutting down (its window was closed, the launch
        stops), ``why``. Not a fault: nothing is reported, retried or reset from now on; the
        step under way is dropped, a reset asked for is answered that none comes."""
        if self.phase == ENDED:
            return
        self.phase = ENDED
        self.step.drop()
        self.outbox.note("debug", f"the run ends: {why}")
        self.resets.run_ended(why)

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
            self.outbox.emit(MdpRefused(peer, request.reply, request.epoch, request.step, code,
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
            return refuse(BUSY, f"step {self.step.current.request.step} is still under way")
        if self.phase == EPISODE_OVER:
            return refuse(EPISODE_IS_OVER, "the episode is over: reset for a new one")
        if self.phase != READY:
            return refuse(NOT_READY, f"the loop is {self.phase}, not ready for a step")
        refused = self.step.start(peer, request, self.episode, self.episodes.start_time)
        if refused is not None:
            return refuse(*refused)
        self.phase = STEPPING

    def reaction_received(self, peer: Any, request: ReactionRequest) -> None:
        """A human who hears the robot tells his state after the robot acted in the step
        answered last: the step's report takes it (and its label) and the step is complete.
        A reaction from another client, of another epoch or for no step awaiting one is
        refused (the loop goes on); one naming a state the task does not have fails the step."""
        if peer != self.seat:
            return self.outbox.emit(reaction_refused(peer, request, SEAT_TAKEN,
                                                     "another MDP process is being served"))
        if request.epoch != self.epoch or self.epoch is None:
            return self.outbox.emit(reaction_refused(
                peer, request, STALE, f"epoch {request.epoch} is over (the loop was reset)"))
        done = self.step.react(peer, request)
        if isinstance(done, StepFailed):
            self._step_failed(done)
        elif isinstance(done, StepComplete):
            self._after_step(done.report, done.report.end_reason, done.played_out)

    # -- answers --------------------------------------------------------------------------------
    def call_done(self, call_id: int, result: Any) -> None:
        """A call came back with its result (or a :class:`Fault`). The one place where
        results of an older epoch are dropped."""
        call = self.outbox.answered(call_id)
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
            why = self.resets.part_reset(call, result)
            if why is not None:
                self._reset_failed(why)
        elif isinstance(call, ObserveWorld) and call.purpose == "episode_start":
            self._episode_started(result)
        elif self.step.current is not None and call.step == self.step.current.request.step:
            self._step_call_done(call, result)
        self._continue_reset()

    def _step_call_done(self, call: Call, result: Any) -> None:
        done = self.step.call_done(call, result)
        if isinstance(done, StepFailed):
            self._step_failed(done)
        elif isinstance(done, StepActed):
            self._finish_step(call, done.report)

    def _finish_step(self, call: Call, report: StepReport) -> None:
        """Both agents acted: does the episode end here? The MDP is answered."""
        try:
            reason = self.episodes.end_reason(report)
        except (AttributeError, TypeError, ValueError) as exc:
            # The outcome's snapshot is not what was asked for (its time is no number).
            return self._step_failed(self.step.fail(f"{what_call(call)} answered nonsense: "
                                                    f"{exc}"))
        self.sequence.count_step(report, self.step.current.decided_on)
        played_out, stops = self.episodes.step_ended(reason)
        complete = self.step.finish(reason, stops, played_out)
        if complete is not None:
            self._after_step(complete, reason, played_out)

    def _after_step(self, report: StepReport, reason: str, played_out: bool) -> None:
        """The step is complete: ready for the next, or the episode's end as configured."""
        self.phase = READY
        if not reason:
            return
        if self.config.tasks:
            self.sequence.end_task(report, reason, self.episodes.start_time)
            self.phase = EPISODE_OVER      # the MDP was told: it waits for the next reset
            return
        then, line = self.episodes.after_end(reason, report.step + 1, played_out)
        self.outbox.note("info", line)
        if then == WAIT:
            self.phase = EPISODE_OVER
        elif then == RESET:
            self._begin_reset(f"episode {self.episode} over ({reason})", None)

    def _task_reported(self, call: EndTask, result: Any) -> None:
        """The robot process answered a task's end: the task is published, then the next
        one starts (unless a reset came meanwhile, or it was the last)."""
        status = self.sequence.task_reported(call, result)
        if status is None:
            return
        if self.phase != EPISODE_OVER or call.epoch != self.epoch:
            return     # a reset came meanwhile: it starts the next task
        if not self.sequence.played:
            self._begin_reset(f"task {status.task_index} over ({status.outcome})", None)
            return
        goes_on = self.config.on_episode_end == "reset" and self.episodes.next() is not None
        self.outbox.note("info", sequence_over_line(self.config.tasks, goes_on))
        if goes_on:
            self._begin_reset(f"sequence {self.sequence.sequences_started} over", None)

    def _step_failed(self, failed: StepFailed) -> None:
        """The step failed (it said so): the loop recovers by a reset."""
        self.phase = BROKEN
        self._begin_reset(f"recovering from a failed step ({failed.why})", None)

    # -- resets ----------------------------------------------------------------------------------
    def reset_requested(self, reason: str, token: Any = None) -> None:
        """Someone asks for a reset (``token`` is answered by :class:`ResetDone`). One asked
        for while a reset is under way joins it; one asked for within ``reset_join_window``
        seconds after a reset finished, while the episode that reset started goes on, is
        that reset (answered at once) when it was asked for the same way (the same
        ``reason``: fifty /hrc/reset calls, not an Enter after an MDP connected) and its
        episode is not over: a burst of calls is one reset."""
        if self.phase in (READY, STEPPING) and self.resets.joins_finished(reason, token):
            return
        if self.phase != RESETTING:
            self.resets.asked_from_outside(reason)
        self._begin_reset(reason, token)

    def timer_fired(self, timer_id: int) -> None:
        """A :class:`Timer` ran out: say what a step waits for (or fail it when the world has
        not answered in time), retry the reset that failed, or close a reset to joiners."""
        if self.phase == ENDED:
            return
        if self.step.owns_timer(timer_id):
            failed = self.step.timer_fired(timer_id, self.epoch)
            if failed is not None:
                self._step_failed(failed)
            return
        if self.resets.timer_fired(timer_id) == RETRY and self.phase == BROKEN:
            self._begin_reset(self.resets.reason, None)   # the same reason, not nested

    def _begin_reset(self, reason: str, token: Any) -> None:
        if self.phase == ENDED:
            return self.resets.refuse(token, "no reset: the run ends (the world is shutting "
                                             "down)")
        if self.phase == RESETTING:
            # Joins the reset under way: nothing has stepped since it began.
            return self.resets.join(token)
        if self.episodes.next() is None:
            # The schedule is played out: nothing is left to reset into.
            return self.resets.refuse(token, "no reset: the episodes asked for "
                                             f"({self.config.episodes.text()}) are all played")
        self.sequence.reset_begins()
        self.resets.begin(reason, token)
        self.phase = RESETTING
        self.episodes.reset_begins()
        self.step.interrupt()
        self.resets.interrupt_motions()
        self._continue_reset()

    def _continue_reset(self) -> None:
        """The reset under way goes on once nothing of the old epoch is out: the world and
        the planner are reset into the new epoch, for the episode (and task) it starts."""
        if self.phase != RESETTING or not self.resets.drained():
            return
        self.step.new_episode()
        # The episode's number is taken when a reset succeeds: failed attempts take none.
        episode = self.episodes.next()
        task_index, true_type = 0, ""
        if self.config.tasks:
            if self.sequence.begin_task():
                self.step.new_human(self.sequence.play.nearest_type)
            task_index, true_type = self.sequence.task_index, self.sequence.play.true_type or ""
        self.resets.reset_parts(episode, task_index, true_type)

    def _episode_started(self, result: Any) -> None:
        """The world was read at the new episode's start: the loop is ready, the MDP told."""
        start, why = self.resets.start_time(result)
        if start is None:
            return self._reset_failed(why)
        episode = self.episodes.start(start)
        self.step.episode_started(episode)
        self.phase = READY
        tokens, text = self.resets.finished(episode)
        task = self.sequence.task_started() if self.config.tasks else ""
        self.outbox.note("info", f"RESET ({self.resets.reason}): episode {episode}, "
                                 f"epoch {self.epoch}{task}")
        if self.seat is not None:
            self.outbox.emit(MdpReset(self.seat, self.epoch, episode, self.resets.reason,
                                      **(self.sequence.mdp_fields() if self.config.tasks
                                         else {})))
        self.resets.answer(tokens, True, text)

    def _reset_failed(self, why: str) -> None:
        self.phase = BROKEN
        self.resets.failed(why)
