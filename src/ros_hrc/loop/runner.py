"""Runs an episode coordinator against its four interfaces, with threads (no ROS, no sockets).

:class:`LoopRunner` owns one :class:`~ros_hrc.loop.coordinator.Coordinator` and is the only
code that touches it: every event (an MDP connected, a step, a reset request, a call's answer,
a timer) goes through one queue to one thread, which feeds the coordinator and carries out
its effects. Calls that block (the world, the planner, the executor) run on a small pool of
worker threads and come back as events, so a reset is taken while a step's action is still
under way; notices (answers to the MDP, published steps, lines) go to the adapters at once,
which must not block.

The interfaces are plain classes the adapters provide (:class:`WorldPort`,
:class:`PlannerPort`, :class:`ExecutorPort`, :class:`MdpPort`, :class:`ReportPort`): the ROS
nodes implement them with services and websockets, the unit tests with fakes. Any exception a
blocking call raises becomes a :class:`~ros_hrc.loop.effects.Fault` with its text: this
is the dispatch point, so nothing an interface does can stop the loop. Except the run's end:
a call that raises :class:`~ros_hrc.errors.StackEnding` (the world is shutting down) tells
the coordinator that the run ends (:meth:`~ros_hrc.loop.coordinator.Coordinator.run_ended`),
and once :meth:`LoopRunner.stop` is called (the node ends) nothing more is carried out: no
line, no step, no reset.
"""
from __future__ import annotations

import logging
import queue
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, Optional, Tuple

from ros_hrc.errors import HrcError, StackEnding
from ros_hrc.loop.coordinator import Coordinator
from ros_hrc.loop.effects import (ActHuman, ActRobot, Call, Decide, Decision, EndTask, Fault,
                                  MdpRefused, MdpReset, MdpStepDone, Note, ObserveWorld, Outcome,
                                  PublishStep, PublishTask, ReactionRequest, ResetDone,
                                  ResetPlanner, ResetWorld, SeatRefused, Snapshot, STEP_TIMINGS,
                                  StepReport, StepRequest, TaskAnswer, TaskStatusReport, Timer)

_log = logging.getLogger("ros_hrc.loop")


class WorldPort:
    """The world: the human's action, one atomic snapshot, a reset of everything."""

    def act_human(self, service: str) -> Outcome:
        raise NotImplementedError

    def snapshot(self) -> Snapshot:
        raise NotImplementedError

    def reset(self, interrupt: bool, episode: int) -> Outcome:
        """Everything back at its start for episode ``episode`` (the world's random stream is
        that episode's); ``interrupt``: only stop what is under way (a real reset follows)."""
        raise NotImplementedError


class PlannerPort:
    """The robot planner: a decision per observation, a reset into an epoch."""

    def decide(self, epoch: int, step: int, observation: str, bits: int, state: str,
               elapsed: Optional[float] = None) -> Decision:
        """``elapsed``: simulated seconds since the episode's start (None: unknown)."""
        raise NotImplementedError

    def reset(self, epoch: int, episode: int, task_index: Optional[int] = None,
              true_type: Optional[str] = None) -> Outcome:
        """Into ``epoch`` for ``episode``; in a sequence, it starts task ``task_index``
        (its human labelled ``true_type``)."""
        raise NotImplementedError

    def end_task(self, epoch: int, call: EndTask) -> TaskAnswer:
        """A task of the sequence ended (``call``: how): the robot process's report."""
        raise NotImplementedError("this planner knows no sequence of tasks")


class ExecutorPort:
    """The robot executor: carries out the robot's action."""

    def act(self, epoch: int, step: int, action: str) -> Outcome:
        raise NotImplementedError


class MdpPort:
    """The seated MDP's link (must not block: answers are queued)."""

    def reset(self, effect: MdpReset) -> None:
        raise NotImplementedError

    def step_done(self, effect: MdpStepDone) -> None:
        raise NotImplementedError

    def refused(self, effect: MdpRefused) -> None:
        raise NotImplementedError

    def refuse_seat(self, effect: SeatRefused) -> None:
        raise NotImplementedError


class ReportPort:
    """Where steps and lines go (the terminal, /hrc/status); must not block for long."""

    def step(self, report: StepReport) -> None:
        pass

    def task_ended(self, report: TaskStatusReport) -> None:
        """A task of a sequence ended: publish and print it."""

    def note(self, level: str, text: str) -> None:
        """A line of the loop's, at ``level``: error, warn, info, or debug (for the logs)."""
        {"error": _log.error, "warn": _log.warning, "debug": _log.debug}.get(level, _log.info)(
            text)


#: Calls whose wall time a step's report carries (see coordinator.STEP_TIMINGS).
_TIMED_CALLS = {ActHuman: "human", Decide: "decide", ActRobot: "robot"}


class _ResetAnswer:
    def __init__(self) -> None:
        self.done = threading.Event()
        self.result: Tuple[bool, str] = (False, "no answer")


class LoopRunner:
    """One coordinator, one event thread, a pool for blocking calls. Thread-safe entry points:
    :meth:`mdp_connected`, :meth:`mdp_disconnected`, :meth:`step_requested`,
    :meth:`reaction_received`, :meth:`reset`."""

    def __init__(self, coordinator: Coordinator, world: WorldPort, planner: PlannerPort,
                 executor: ExecutorPort, mdp: MdpPort, reports: Optional[ReportPort] = None,
                 workers: int = 4) -> None:
        self.coordinator = coordinator
        self.world = world
        self.planner = planner
        self.executor = executor
        self.mdp = mdp
        self.reports = reports or ReportPort()
        self._events: "queue.Queue[Optional[Callable[[], None]]]" = queue.Queue()
        self._pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="loop-call")
        self._thread: Optional[threading.Thread] = None
        self._timers: list = []
        self._stopped = threading.Event()
        self.idle = threading.Condition()   # notified after each event (tests wait on it)
        self.events_handled = 0
        # Wall times of the step under way (StepReport.timings_ms): one step runs at a time.
        self._step_started = time.perf_counter()
        self._timings: dict = {}

    # -- life ----------------------------------------------------------------------------------
    def start(self) -> "LoopRunner":
        self._thread = threading.Thread(target=self._run, name="loop", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop at once: events and effects not carried out yet are dropped (the node ends:
        what its peers do meanwhile, as they end too, is no news)."""
        self._stopped.set()
        self._events.put(None)
        for timer in self._timers:
            timer.cancel()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(5.0)
        self._pool.shutdown(wait=False, cancel_futures=True)

    # -- events in (any thread) -----------------------------------------------------------------
    def post(self, event: Callable[[], None]) -> None:
        """Run ``event()`` (a call on the coordinator) on the loop's thread."""
        if not self._stopped.is_set():
            self._events.put(event)

    def mdp_connected(self, peer: Any) -> None:
        self.post(lambda: self.coordinator.mdp_connected(peer))

    def mdp_disconnected(self, peer: Any, stopped: bool = False) -> None:
        """The MDP ``peer`` left; ``stopped``: it closed its link itself (it was asked to)."""
        self.post(lambda: self.coordinator.mdp_disconnected(peer, stopped))

    def step_requested(self, peer: Any, request: StepRequest) -> None:
        arrived = time.perf_counter()

        def event() -> None:
            self._step_started, self._timings = arrived, {}
            self.coordinator.step_requested(peer, request)
        self.post(event)

    def reaction_received(self, peer: Any, request: ReactionRequest) -> None:
        self.post(lambda: self.coordinator.reaction_received(peer, request))

    def reset(self, reason: str, timeout: Optional[float] = None) -> Tuple[bool, str]:
        """Ask for a reset and wait for its answer: (success, message)."""
        answer = _ResetAnswer()
        self.post(lambda: self.coordinator.reset_requested(reason, answer))
        if not answer.done.wait(timeout):
            return False, f"the reset did not finish within {timeout:g} s"
        return answer.result

    def request_reset(self, reason: str) -> None:
        """Ask for a reset without waiting for it."""
        self.post(lambda: self.coordinator.reset_requested(reason, None))

    # -- the loop's thread ------------------------------------------------------------------------
    def _run(self) -> None:
        while True:
            event = self._events.get()
            if event is None or self._stopped.is_set():
                return
            try:
                event()
                for effect in self.coordinator.effects():
                    if self._stopped.is_set():
                        return
                    self._carry_out(effect)
            except Exception:   # a bug here must not stop the loop: say it and go on
                _log.exception("the loop failed on an event")
            with self.idle:
                self.events_handled += 1
                self.idle.notify_all()

    def _carry_out(self, effect: Any) -> None:
        if isinstance(effect, Call):
            self._pool.submit(self._run_call, effect)
        elif isinstance(effect, PublishStep):
            effect.report.timings_ms = {
                "step": (time.perf_counter() - self._step_started) * 1000.0, **self._timings}
            self._safely(self.reports.step, effect.report)
        elif isinstance(effect, PublishTask):
            self._safely(self.reports.task_ended, effect.report)
        elif isinstance(effect, Note):
            self._safely(self.reports.note, effect.level, effect.text)
        elif isinstance(effect, MdpReset):
            self._safely(self.mdp.reset, effect)
        elif isinstance(effect, MdpStepDone):
            self._safely(self.mdp.step_done, effect)
        elif isinstance(effect, MdpRefused):
            self._safely(self.mdp.refused, effect)
        elif isinstance(effect, SeatRefused):
            self._safely(self.mdp.refuse_seat, effect)
        elif isinstance(effect, ResetDone):
            for token in effect.tokens:
                if isinstance(token, _ResetAnswer):
                    token.result = (effect.success, effect.message)
                    token.done.set()
        elif isinstance(effect, Timer):
            timer = threading.Timer(effect.seconds, self.post,
                                    args=(lambda: self.coordinator.timer_fired(effect.id),))
            timer.daemon = True
            self._timers = [t for t in self._timers if t.is_alive()] + [timer]
            timer.start()
        else:
            _log.error("the loop does not know the effect %r", effect)

    @staticmethod
    def _safely(fn: Callable, *args: Any) -> None:
        try:
            fn(*args)
        except Exception:   # an adapter's bug must not stop the loop
            _log.exception("%s failed", getattr(fn, "__qualname__", fn))

    def _run_call(self, call: Call) -> None:
        started = time.perf_counter()
        try:
            result = self._perform(call)
        except StackEnding as exc:
            why = str(exc)
            self.post(lambda: self.coordinator.run_ended(why))
            return
        except HrcError as exc:
            result = Fault(str(exc))
        except Exception as exc:   # the dispatch point: any failure is the call's fault
            _log.debug("call %r failed", call, exc_info=True)
            result = Fault(f"{type(exc).__name__}: {exc}")
        part = call.purpose if isinstance(call, ObserveWorld) else _TIMED_CALLS.get(type(call))
        elapsed = (time.perf_counter() - started) * 1000.0

        def done() -> None:
            if part in STEP_TIMINGS:
                self._timings[part] = elapsed
            self.coordinator.call_done(call.id, result)
        self.post(done)

    def _perform(self, call: Call) -> Any:
        if isinstance(call, ActHuman):
            return self.world.act_human(call.service)
        if isinstance(call, ObserveWorld):
            return self.world.snapshot()
        if isinstance(call, ResetWorld):
            return self.world.reset(call.interrupt, call.episode)
        if isinstance(call, Decide):
            return self.planner.decide(call.epoch, call.step, call.observation, call.bits,
                                       call.state, elapsed=call.elapsed)
        if isinstance(call, ResetPlanner):
            if call.task_index:
                return self.planner.reset(call.epoch, call.episode, task_index=call.task_index,
                                          true_type=call.true_type)
            return self.planner.reset(call.epoch, call.episode)
        if isinstance(call, EndTask):
            return self.planner.end_task(call.epoch, call)
        if isinstance(call, ActRobot):
            return self.executor.act(call.epoch, call.step, call.action)
        raise TypeError(f"unknown call {type(call).__name__}")

    # -- for tests and shutdown -----------------------------------------------------------------
    def wait_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Wait until ``predicate()`` (evaluated after each event) holds."""
        with self.idle:
            return self.idle.wait_for(predicate, timeout)
