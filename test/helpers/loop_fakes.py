"""Helpers of the loop's tests (test_coordinator.py, test_runner.py): a hand driver for the
Sans-I/O Coordinator that plays whole steps with given answers, and fake interfaces (a
scripted world, a planner, an executor, an MDP that steps by itself, a report sink) for the
threaded LoopRunner; and (test_model_checks.py, test_positional_names.py) the one-line
refusal of a model. No ROS, no sockets."""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import pytest

from ros_hrc.errors import ModelError, SolverError
from ros_hrc.loop.coordinator import Coordinator, CoordinatorConfig
from ros_hrc.loop.effects import (ActHuman, ActRobot, Call, Decide, Decision, MdpRefused, MdpReset,
                                  MdpStepDone, ObserveWorld, Outcome, PublishStep, ResetPlanner,
                                  ResetWorld, SeatRefused, Snapshot, StepReport, StepRequest)
from ros_hrc.loop.runner import (ExecutorPort, LoopRunner, MdpPort, PlannerPort, ReportPort,
                                 WorldPort)

OK = Outcome(True, "done")
DEFAULT = object()   # play_step: the default answer


def snap(*names: str, sim_time: float = 0.0, holder: str = "none",
         left_belt: bool = False) -> Snapshot:
    """A snapshot in which the named predicates (``is_ov`` ...) hold."""
    return Snapshot({name: True for name in names}, sim_time=sim_time, holder=holder,
                    left_belt=left_belt)


def of(effects: Sequence[Any], kind: type, **fields: Any) -> List[Any]:
    """The effects of ``kind`` whose fields equal ``fields``."""
    return [e for e in effects if isinstance(e, kind)
            and all(getattr(e, k) == v for k, v in fields.items())]


def one(effects: Sequence[Any], kind: type, **fields: Any) -> Any:
    found = of(effects, kind, **fields)
    assert len(found) == 1, f"expected one {kind.__name__} {fields or ''} in {effects}"
    return found[0]


def calls(effects: Sequence[Any]) -> List[Call]:
    return [e for e in effects if isinstance(e, Call)]


@dataclass
class Played:
    """What one step did: the calls made (in order), every effect, the report and answer."""
    calls: List[Call] = field(default_factory=list)
    effects: List[Any] = field(default_factory=list)
    request: Optional[StepRequest] = None

    @property
    def report(self) -> Optional[StepReport]:
        found = of(self.effects, PublishStep)
        return found[-1].report if found else None

    @property
    def done(self) -> Optional[MdpStepDone]:
        found = of(self.effects, MdpStepDone)
        return found[-1] if found else None

    @property
    def refused(self) -> Optional[MdpRefused]:
        found = of(self.effects, MdpRefused)
        return found[-1] if found else None


class Driver:
    """Drives a Coordinator by hand: events in, effects out, calls answered one by one."""

    def __init__(self, config: Optional[CoordinatorConfig] = None, peer: Any = "mdp") -> None:
        self.c = Coordinator(config or CoordinatorConfig())
        self.peer = peer
        self.log: List[Any] = []          # every effect taken, in order
        self.last_request: Optional[StepRequest] = None
        self._replies = 0
        #: finish_reset closes the window in which a reset asked for is the finished one
        self.let_time_pass = True

    # -- plumbing ------------------------------------------------------------------------------
    def take(self) -> List[Any]:
        out = self.c.effects()
        self.log.extend(out)
        return out

    def answer(self, call: Call, result: Any) -> List[Any]:
        self.c.call_done(call.id, result)
        return self.take()

    # -- the seat and resets -------------------------------------------------------------------
    def connect(self, peer: Any = None) -> List[Any]:
        self.c.mdp_connected(self.peer if peer is None else peer)
        return self.take()

    def finish_reset(self, effects: Sequence[Any], world: Any = OK, planner: Any = OK,
                     start: Any = None) -> List[Any]:
        """Answer the reset's ResetWorld and ResetPlanner found in ``effects`` (the world's
        first), then its episode-start snapshot; all effects that followed."""
        rw = one(effects, ResetWorld, interrupt=False)
        rp = one(effects, ResetPlanner)
        out = self.answer(rw, world) + self.answer(rp, planner)
        starts = of(out, ObserveWorld, purpose="episode_start")
        if starts:
            out += self.answer(starts[0], snap(sim_time=1.5) if start is None else start)
            if self.let_time_pass:
                self.close_join_window()
        return out

    def close_join_window(self) -> None:
        """Let ``reset_join_window`` pass after a reset finished: a reset asked for from now
        on is a new one (the tests that ask for one at once mean a new one)."""
        if self.c.resets.join_timer is not None:
            self.c.timer_fired(self.c.resets.join_timer)

    def ready(self, peer: Any = None) -> MdpReset:
        """Connect (seat) the MDP and complete its first reset: the MdpReset it got."""
        out = self.finish_reset(self.connect(peer))
        return one(out, MdpReset)

    def reset(self, token: Any = "token", reason: str = "asked") -> List[Any]:
        self.c.reset_requested(reason, token)
        return self.take()

    # -- steps ---------------------------------------------------------------------------------
    def request(self, action: str = "lookAround", state: str = "evaluating",
                step: Optional[int] = None, epoch: Any = "current", reward: float = 0.0) -> StepRequest:
        self._replies += 1
        return StepRequest(epoch=self.c.epoch if epoch == "current" else epoch,
                           step=self.c.expected_step if step is None else step,
                           action=action, state=state,
                           reward=reward, reply=f"r{self._replies}")

    def start_step(self, peer: Any = None, **request: Any) -> List[Any]:
        self.last_request = self.request(**request)
        self.c.step_requested(self.peer if peer is None else peer, self.last_request)
        return self.take()

    def play_step(self, action: str = "lookAround", state: str = "evaluating",
                  human: Any = OK, observe: Any = DEFAULT, decision: Any = DEFAULT,
                  robot: Any = OK, outcome: Any = DEFAULT, until: Optional[str] = None,
                  **request: Any) -> Played:
        """Play one step, answering each call with the given result (``observe`` and
        ``outcome`` default to a plain snapshot, ``decision`` to rPoint_obj). ``until``:
        stop before answering the call of that stage (human, observe, decide, robot,
        outcome); ``played.calls[-1]`` is then the call left outstanding."""
        answers = {"human": human,
                   "observe": snap("is_ov") if observe is DEFAULT else observe,
                   "decide": Decision("rPoint_obj") if decision is DEFAULT else decision,
                   "robot": robot,
                   "outcome": snap("is_ov") if outcome is DEFAULT else outcome}
        played = Played()
        effects = self.start_step(action=action, state=state, **request)
        played.request = self.last_request
        played.effects += effects
        while True:
            step_calls = [c for c in calls(effects) if c.step is not None]
            if not step_calls:
                return played
            assert len(step_calls) == 1, effects
            call = step_calls[0]
            played.calls.append(call)
            stage = stage_of(call)
            if stage == until:
                return played
            effects = self.answer(call, answers[stage])
            played.effects += effects


def stage_of(call: Call) -> str:
    if isinstance(call, ActHuman):
        return "human"
    if isinstance(call, ObserveWorld):
        return {"observe": "observe", "outcome": "outcome"}.get(call.purpose, call.purpose)
    if isinstance(call, Decide):
        return "decide"
    if isinstance(call, ActRobot):
        return "robot"
    return type(call).__name__


# -- fakes for the LoopRunner ---------------------------------------------------------------------

class Log:
    """One ordered record of what the loop's thread carried out (thread-safe appends)."""

    def __init__(self) -> None:
        self.items: List[Tuple[str, Any]] = []
        self._lock = threading.Lock()

    def add(self, kind: str, what: Any) -> None:
        with self._lock:
            self.items.append((kind, what))

    def snapshot(self) -> List[Tuple[str, Any]]:
        with self._lock:
            return list(self.items)

    def of(self, kind: str) -> List[Any]:
        return [w for k, w in self.snapshot() if k == kind]


class Hooks:
    """Failures scripted into a fake: ``fail[name] = [exc, ...]`` raises them in turn."""

    def __init__(self) -> None:
        self.fail: Dict[str, List[BaseException]] = {}
        self._lock = threading.Lock()

    def maybe_raise(self, name: str) -> None:
        with self._lock:
            pending = self.fail.get(name)
            exc = pending.pop(0) if pending else None
        if exc is not None:
            raise exc


# What each human service makes the world's predicates read (a small scripted world).
_PREDICATES = {
    None: ("is_ov",),
    "attempt_grasp": ("is_ov", "is_oir", "is_a0"),
    "look_around": ("is_ov",),
    "idle": ("is_ov", "is_oir", "is_a2"),
    "walk_away": (),
    "warn_robot": ("is_ov", "is_h4"),
    "grasp": ("is_ov", "is_oir", "is_ho"),
}


class FakeWorld(WorldPort):
    """A scripted world: predicates follow the human's last action. ``block_act(n)``: the
    n-th human action (counted from 1) blocks until an interrupting reset arrives."""

    def __init__(self) -> None:
        self.hooks = Hooks()
        self.calls: List[Tuple[Any, ...]] = []
        self._lock = threading.Lock()
        self._last: Optional[str] = None
        self._holder = "none"
        self._time = 0.0
        self._acts = 0
        self._block_at: Optional[int] = None
        self.blocked = threading.Event()      # a human action is blocked
        self.released = threading.Event()     # an interrupting reset arrived
        self.episodes: List[int] = []

    def block_act(self, n: int) -> None:
        self._block_at = n

    def act_human(self, service: str) -> Outcome:
        with self._lock:
            self._acts += 1
            block = self._acts == self._block_at
            self.calls.append(("act", service))
        self.hooks.maybe_raise("act")
        if block:
            self.blocked.set()
            interrupted = self.released.wait(10)   # safety net only
            with self._lock:
                self.calls.append(("act_returned", service, interrupted))
            return Outcome(False, "interrupted by a reset" if interrupted else "timed out")
        with self._lock:
            self._last = service
            if service == "grasp":
                self._holder = "human"
        return Outcome(True, f"{service} done")

    def snapshot(self) -> Snapshot:
        with self._lock:
            self.calls.append(("snapshot",))
        self.hooks.maybe_raise("snapshot")
        with self._lock:
            self._time += 0.1
            return snap(*_PREDICATES[self._last], sim_time=round(self._time, 3),
                        holder=self._holder)

    def reset(self, interrupt: bool, episode: int = 0) -> Outcome:
        with self._lock:
            self.calls.append(("reset", interrupt))
            if not interrupt:
                self.episodes.append(episode)   # the episodes the world was reset into
        if interrupt:
            self.released.set()
            return Outcome(True, "actions stopped")
        self.hooks.maybe_raise("reset")
        with self._lock:
            self._last, self._holder = None, "none"
        return Outcome(True, "world reset")

    def close(self) -> None:
        self.released.set()


class FakePlanner(PlannerPort):
    """Decides by a fixed cycle of actions; refuses to decide in an epoch it was not reset
    into (like a restarted solver). ``down(n)``: the next n calls raise ConnectionError (a
    dead process). ``hold(step)``: the next decision of that step waits until ``release``
    is set (a slow planner)."""

    ACTIONS = ("rIdle", "rPoint_obj", "rIdle", "rStop_all", "rGrasp_obj")

    def __init__(self) -> None:
        self.hooks = Hooks()
        self.calls: List[Tuple[Any, ...]] = []
        self.epoch: Optional[int] = None
        self._lock = threading.Lock()
        self._down = 0
        self._hold: Optional[int] = None
        self.holding = threading.Event()
        self.release = threading.Event()

    def down(self, calls: int) -> None:
        with self._lock:
            self._down = calls

    def hold(self, step: int) -> None:
        self._hold = step

    def _check_up(self) -> None:
        with self._lock:
            if self._down > 0:
                self._down -= 1
                raise ConnectionError("the planner process is gone")

    def decide(self, epoch: int, step: int, observation: str, bits: int, state: str,
               elapsed=None) -> Decision:
        with self._lock:
            self.calls.append(("decide", epoch, step))
        self._check_up()
        self.hooks.maybe_raise("decide")
        if epoch != self.epoch:
            raise SolverError(f"not reset into epoch {epoch}")
        if self._hold == step:
            self._hold = None
            self.holding.set()
            self.release.wait(10)   # safety net only
        with self._lock:
            self.calls.append(("decided", epoch, step))
        return Decision(self.ACTIONS[step % len(self.ACTIONS)], belief=(0.5, 0.5),
                        belief_states=("S0", "S2"), decision_ms=1.0)

    def reset(self, epoch: int, episode: int) -> Outcome:
        with self._lock:
            self.calls.append(("reset", epoch, episode))
        self._check_up()
        self.hooks.maybe_raise("reset")
        self.epoch = epoch
        return Outcome(True, f"reset into epoch {epoch}")

    def close(self) -> None:
        self.release.set()


class FakeExecutor(ExecutorPort):
    def __init__(self) -> None:
        self.hooks = Hooks()
        self.calls: List[Tuple[Any, ...]] = []

    def act(self, epoch: int, step: int, action: str) -> Outcome:
        self.calls.append(("act", epoch, step, action))
        self.hooks.maybe_raise("act")
        return Outcome(True, f"{action} done")


# The human MDP's script: (action, next state) per step, none of which ends an episode.
MDP_SCRIPT = (("lookAround", "evaluating"), ("graspAttempt", "failed_to_grasp"),
              ("idle", "tired"), ("walkAway", "no_attention"), ("lookAround", "recovery"),
              ("warnRobot", "warningTheRobot"))


class FakeMdp(MdpPort):
    """Acts like the seated MDP: on MdpReset it asks for step 0 of that epoch, on each
    MdpStepDone (unless the episode is over) for the next step, through runner.step_requested
    (which only posts to the loop's queue). Records every answer in the shared log."""

    def __init__(self, log: Log, peer: Any = "mdp", script=MDP_SCRIPT) -> None:
        self.log = log
        self.peer = peer
        self.script = script
        self.runner: Optional[LoopRunner] = None
        self.stepping = True

    def _ask(self, epoch: int, step: int) -> None:
        if not self.stepping:
            return
        action, state = self.script[step % len(self.script)]
        self.runner.step_requested(self.peer, StepRequest(epoch, step, action, state,
                                                          reply=(epoch, step)))

    def reset(self, effect: MdpReset) -> None:
        self.log.add("mdp_reset", effect)
        self._ask(effect.epoch, 0)

    def step_done(self, effect: MdpStepDone) -> None:
        self.log.add("step_done", effect)
        if not effect.episode_over:
            self._ask(effect.epoch, effect.step + 1)

    def refused(self, effect: MdpRefused) -> None:
        self.log.add("refused", effect)

    def refuse_seat(self, effect: SeatRefused) -> None:
        self.log.add("seat_refused", effect)


class Reports(ReportPort):
    def __init__(self, log: Log) -> None:
        self.log = log

    def step(self, report: StepReport) -> None:
        self.log.add("report", report)

    def note(self, level: str, text: str) -> None:
        self.log.add("note", (level, text))


class Loop:
    """A LoopRunner with every fake, started; ``close()`` stops it and frees blocked fakes."""

    def __init__(self, config: Optional[CoordinatorConfig] = None, workers: int = 4) -> None:
        self.log = Log()
        self.world = FakeWorld()
        self.planner = FakePlanner()
        self.executor = FakeExecutor()
        self.mdp = FakeMdp(self.log)
        self.reports = Reports(self.log)
        self.coordinator = Coordinator(config or CoordinatorConfig(first_epoch=100))
        self.runner = LoopRunner(self.coordinator, self.world, self.planner, self.executor,
                                 self.mdp, self.reports, workers=workers)
        self.mdp.runner = self.runner
        self.runner.start()

    def close(self) -> None:
        self.mdp.stepping = False
        self.world.close()
        self.planner.close()
        self.runner.stop()

    # -- reading the record ----------------------------------------------------------------------
    def reports_of(self, epoch: int) -> List[StepReport]:
        return [r for r in self.log.of("report") if r.epoch == epoch]

    def last_reset(self) -> Optional[MdpReset]:
        resets = self.log.of("mdp_reset")
        return resets[-1] if resets else None

    def wait(self, predicate: Callable[[], bool], timeout: float = 10.0) -> bool:
        """Wait (polling; a safety net, not a measure) until ``predicate()`` holds."""
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                return False
            time.sleep(0.002)
        return True


def refusal(load, path) -> str:
    """The text of the ModelError ``load`` raises on ``path``: one line."""
    with pytest.raises(ModelError) as info:
        load(str(path))
    text = str(info.value)
    assert "\n" not in text
    return text
