"""The PyBullet world: floor, conveyor, object, human and robot, stepped at a fixed rate.

Its bodies live in two PyBullet servers (:mod:`.stage`): the **physics** server simulates the
object on the belt; the **scene** server (``World.client``; the window with ``gui``) holds
every body as it is seen, and is never stepped.

One loop steps the world in control steps of ``substeps * time_step`` (1/60 s). Each control
step it (1) takes the requests that came in (a reset or a cancel interrupts at once; any other
action queues behind the agent's current one) and starts a queued action where the agent is
free, (2) moves the belt, (3) steps the physics, (4) puts a held object in its holder's hand
and the object's copy where the object is, (5) advances the human's and the robot's motions
to their next command, which finishes a motion whose last step has just been taken, and (6)
moves a carried object nearer the robot's tray and lets the belt's end take an object that
reached it (a task's own world: ``WorldConfig.belt_start`` and the facts after it, from
:func:`~.config.task_world_config`; the belt's speed in (2) follows ``belt_start`` too).
Actions are therefore only ever executed by the loop, between two steps, and every
PyBullet call happens under one lock: callers on other threads (ROS service handlers) submit a
request and wait for its :class:`~.tickets.Ticket` (:mod:`.tickets`: the queues and who goes
first), and predicate queries read the geometry under the lock. Nothing waits for anything
while holding the lock, so calls cannot deadlock. With ``gui`` the scene server is PyBullet's
window (:mod:`.window`); snapshots come from :mod:`.camera`.

Two ways to drive it:

* synchronously, without threads (tests, experiments)::

      world = World(WorldConfig(seed=1))
      outcome = world.run("human", "grasp")      # steps the physics until the grasp is over
      world.query("is_ho").value                 # -> True
      world.advance(2.0)                         # 2 s of simulated time (the belt moves)

* from threads: ``world.start(real_time_factor=1.0)`` runs the loop in a thread of its own;
  then ``world.run(...)`` (or ``world.submit(...).wait()``) blocks only its caller.
"""
from __future__ import annotations

import logging
import threading
import time
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Callable, Iterator, List, Optional, Sequence, Union

import numpy as np

from ..errors import SimulationError
from .. import settings, streams
from .camera import Matrices, camera_matrices, rgb, take_image, window_matrices
from .client import PhysicsClient
from .config import WorldConfig, default_model_dir
from .outcome import Outcome, Reading
from .stage import build_stage
from .tickets import ActionQueues, Channel, Ticket
from .window import View, Window, WindowClosed, window_options
from .x11 import WindowNamer

LOG = logging.getLogger(__name__)

#: Actions each agent knows (the seed's Table 3.2, plus the human's ``idle`` and the robot's
#: ``grasp_planning``, FABRIC's graspPlanning: the open gripper over the object, no grasp).
HUMAN_ACTIONS = ("walk_away", "look_around", "warn_robot", "attempt_grasp", "grasp", "idle", "reset")
ROBOT_ACTIONS = ("point_to_obj", "grasp", "cancel_action", "reset", "grasp_planning")
#: The human predicates (seed Table 3.2), answered by :meth:`World.query`.
PREDICATES = ("is_ov", "is_oir", "is_ho", "is_a0", "is_a2", "is_h4")
#: A synchronous run() gives up after this much simulated time (no action lasts that long).
_MAX_ACTION_TIME = 60.0


class World:
    """The scene and its stepping loop. See the module docstring for the two ways to drive it."""

    def __init__(self, config: Optional[WorldConfig] = None,
                 model_dir: Optional[Union[str, Path]] = None) -> None:
        self.config = config or WorldConfig()
        self.model_dir = Path(model_dir) if model_dir else default_model_dir()
        for name in ("human.urdf", "pr2_like.urdf"):
            if not (self.model_dir / name).is_file():
                raise SimulationError(f"model {name} not found in {self.model_dir}")
        if self.config.substeps < 1:
            raise SimulationError(f"substeps must be at least 1, got {self.config.substeps}")
        self.time_step = self.config.time_step
        self.control_period = self.config.time_step * self.config.substeps
        self.step_count = 0   # physics steps
        self.sim_time = 0.0
        # The world's draws (a fumbled grasp's miss) come from the stream of (seed, episode,
        # "world"), episode 0 until reseed() names another (the loop's node does at each reset).
        self.episode = 0
        self.seed = self.config.seed     # the run's seed (reseed() may bring another)
        self.rng = streams.generator(self.seed, self.episode, "world")
        self._lock = threading.RLock()
        self._waiters = 0
        self._waiters_lock = threading.Lock()
        self._work = threading.Event()
        self._stop = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._listeners: List[Callable[[float], None]] = []
        cfg = self.config
        # Made before PyBullet's window opens, closed once it is named (WindowNamer says why).
        namer = WindowNamer() if cfg.gui else None
        options = window_options(cfg.window.width, cfg.window.height, cfg.window.background)
        try:
            self.client = PhysicsClient(cfg.gui, options)   # the scene: never stepped
        except BaseException:
            if namer is not None:
                namer.close()
            raise
        self._window = Window(self.client, cfg.window)   # used with gui only
        self._window.add_closed_listener(self._abandon_actions)   # first: then the others
        try:
            if namer is not None:
                try:
                    self._window.open(namer)
                finally:
                    namer.close()
            self.physics = PhysicsClient(False)
            stage = build_stage(self.client, self.physics, cfg, self.model_dir, self.control_period,
                                self.rng, self._predicted_object, self._window if cfg.gui else None)
            self.floor_id, self.scenery, self.conveyor, self.object, self.human, self.robot = stage
            # The task's clock (belt_start counts from it): the physics step of the last reset
            # that put the object back at its start. Kept in steps: a difference of two clock
            # readings carries rounding from the clock's size, and the world's clock runs on
            # across episodes (and a warm stack's cells), so a task would see its belt start a
            # step earlier or later on an older world.
            self._task_start_step = 0
            self._belt_speed = self._running_speed()
            self._actions = ActionQueues({"human": self.human, "robot": self.robot})
            if cfg.gui:
                self._window.show(self.floor_id)
        except BaseException:
            self.close_clients()
            raise

    # --- context manager ---------------------------------------------------------------------
    def __enter__(self) -> "World":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # --- the loop ------------------------------------------------------------------------------
    @contextmanager
    def _locked(self) -> Iterator[None]:
        # Callers from other threads announce themselves, so the loop steps aside for them
        # between two steps (a plain lock lets the loop re-take it at once, starving them).
        with self._waiters_lock:
            self._waiters += 1
        try:
            with self._lock:
                if self.client.client_id < 0:
                    raise SimulationError("the world is closed")
                self._check_window()
                try:
                    yield
                except self.client.error:
                    if self.config.gui:   # the window went during the call: say so
                        self._check_window(settle=0.2)
                    raise
        finally:
            with self._waiters_lock:
                self._waiters -= 1

    def _check_window(self, settle: float = 0.0) -> None:
        """Raise :class:`WindowClosed` if the window (the scene server) is gone (under the
        lock; ``settle``: see :meth:`.Window.vanished`)."""
        if self.config.gui or self._window.closed:
            self._window.check(settle)

    def _abandon_actions(self) -> None:
        """The window is gone: every pending action ends with :class:`WindowClosed`."""
        error = WindowClosed()
        for ticket in self._actions.pending():
            ticket.fail(error, self.sim_time)

    def _step_locked(self) -> None:
        if self.config.gui:
            self._check_window()
            try:
                self._step_scene()
                self._window.follow_view()
            except Exception:
                self._check_window(settle=0.2)   # the window went during the step: say so
                raise
        else:
            self._step_scene()

    def _step_scene(self) -> None:
        self._take_requests()
        for channel in self._actions.channels.values():
            if channel.motion is None:
                self._advance(channel)   # start a queued action: its first command
        self.conveyor.speed = self._belt_now()
        self.conveyor.before_step()
        self.physics.stepSimulation()
        self.object.after_step()
        self.step_count += self.config.substeps
        self.sim_time = self.step_count * self.time_step
        # The next command of each motion, right after the step: a motion of n steps is over
        # n steps after it began (its last command has had its step), not one step later.
        for channel in self._actions.channels.values():
            if channel.motion is not None:
                self._advance(channel)
        self.robot.deliver(self.control_period)
        if self.config.end_tray and not self.object.gone and self._at_belt_end():
            self.object.gone = "the object has left the belt: it lies in the tray at the belt's end"

    def _running_speed(self) -> float:
        """The belt's speed once it runs: belt_speed, or with belt_run the speed that brings the
        object from its start to the belt's end in belt_run seconds."""
        cfg = self.config
        if cfg.belt_run <= 0:
            return cfg.belt_speed
        distance = self.conveyor.end_x(cfg.work_object.size / 2) - self.object.start_position[0]
        return max(0.0, distance) / cfg.belt_run

    def _belt_now(self) -> float:
        """The belt's speed at this step: still for belt_start seconds of the task, then running."""
        if (self.step_count - self._task_start_step) * self.time_step < self.config.belt_start:
            return 0.0
        return self._belt_speed

    def _at_belt_end(self) -> bool:
        """Nobody holds the object, and it is off the belt or at its end."""
        position = self.object.position()
        # (A plain bool: ROS messages refuse numpy's.)
        return bool(self.object.holder == "none" and (
            not self.conveyor.is_on_belt(position)
            or self.conveyor.at_end(position, self.object.config.size / 2)))

    def _take_requests(self) -> None:
        """Queue the actions asked for since the last step; carry out resets and cancels at once."""
        for ticket in self._actions.take(self.sim_time):
            ticket.started_at = self.sim_time
            ticket.finish(self._carry_out(ticket), self.sim_time)

    def _carry_out(self, ticket: Ticket) -> Outcome:
        """A reset or a cancel: it interrupts the agent's motion and queue (both agents' for
        the world's reset) and takes effect at once."""
        actions, now = self._actions, self.sim_time
        if ticket.agent == "world":
            for agent in actions.channels:
                actions.interrupt(agent, "reset", now)
            self.object.reset()
            self.human.reset()
            self.robot.reset()
            self._task_start_step = self.step_count
            return Outcome(True, "world reset: human, robot and object back at their start")
        if ticket.agent == "human":
            actions.interrupt("human", "reset", now)
            self.object.reset()  # the seed's /human/reset puts the object back too
            self._task_start_step = self.step_count
            outcome = self.human.reset()
            return replace(outcome, message=outcome.message + "; object back at the start of the belt")
        if ticket.action == "reset":
            actions.interrupt("robot", "reset", now)
            if self.object.holder == "robot":
                self.object.reset()  # a released object would drop anywhere: put it back
            return self.robot.reset()
        return self.robot.cancel(actions.interrupt("robot", "cancel_action", now))

    def _advance(self, channel: Channel) -> None:
        # Loop: a motion may end at its first step (e.g. "already away"), letting the next start.
        while True:
            if channel.motion is None:
                if not channel.queue:
                    return
                channel.start_next(self.sim_time)
            try:
                next(channel.motion)
                if not channel.answered and channel.ticket.name in self.config.async_actions:
                    # Answered as it starts (FABRIC's robot grasps on a thread of its own):
                    # the caller goes on while the motion does.
                    channel.answer_early(Outcome(True, f"{channel.ticket.action} under way (the "
                                                       "call is answered as it starts; a cancel "
                                                       "stops it)"), self.sim_time)
                return
            except StopIteration as stop:
                outcome = stop.value or Outcome(True, f"{channel.ticket.name} done")
            except WindowClosed:
                raise
            except (SimulationError, self.client.error) as error:
                if self.config.gui:   # a PyBullet error may be the window going, not the action
                    self._check_window(settle=0.0 if isinstance(error, SimulationError) else 0.2)
                outcome = Outcome(False, f"{channel.ticket.name} failed: {error}")
            except Exception as error:  # a bug must not kill the loop: report it and carry on
                if self.config.gui:
                    self._check_window(settle=0.2)   # PyBullet answers some calls with None once it is gone
                LOG.exception("%s raised", channel.ticket.name)
                outcome = Outcome(False, f"{channel.ticket.name} failed with an internal error: {error!r}")
            name, answered = channel.ticket.name, channel.answered
            channel.end(outcome, self.sim_time)
            if answered:
                LOG.info("%s (answered as it started) ended: %s", name, outcome.message)

    def _notify(self) -> None:
        for listener in self._listeners:
            try:
                listener(self.sim_time)
            except Exception:  # a listener's bug must not stop the physics
                LOG.exception("step listener %r failed", listener)

    def _loop(self, real_time_factor: float, pause_when_idle: bool) -> None:
        try:
            self._run_loop(real_time_factor, pause_when_idle)
        except WindowClosed:
            pass   # logged once, pending actions ended: the thread stops (window_closed says why)

    def _run_loop(self, real_time_factor: float, pause_when_idle: bool) -> None:
        anchor_wall, anchor_sim = time.monotonic(), self.sim_time
        while not self._stop.is_set():
            if pause_when_idle and not self._actions.busy():
                self._work.clear()
                if not self._actions.busy():
                    self._work.wait(0.05)
                if self.config.gui:   # idle, the window may still be closed, or looked round
                    with self._lock:
                        self._check_window()
                        self._window.follow_view()
                anchor_wall, anchor_sim = time.monotonic(), self.sim_time
                continue
            with self._lock:
                self._step_locked()
            self._notify()
            if self._waiters:
                time.sleep(0.0002)
            if real_time_factor > 0:
                ahead = anchor_wall + (self.sim_time - anchor_sim) / real_time_factor - time.monotonic()
                if ahead > 0:
                    self._stop.wait(ahead)
                elif ahead < -0.1:
                    # Fell behind (a slow step, a snapshot): carry on from now, do not sprint.
                    anchor_wall, anchor_sim = time.monotonic(), self.sim_time

    # --- driving it ----------------------------------------------------------------------------------
    @property
    def running(self) -> bool:
        """True while the stepping thread runs."""
        return self._thread is not None and self._thread.is_alive()

    def start(self, real_time_factor: float = settings.default("real_time_factor"),
              pause_when_idle: bool = False) -> None:
        """Step the physics in a thread of its own.

        ``real_time_factor``: simulated seconds per wall second (0: as fast as possible).
        ``pause_when_idle``: freeze simulated time while no action runs, so a run depends only on
        the actions asked for, not on how long the callers take between them.
        """
        if real_time_factor < 0:
            raise SimulationError(f"real_time_factor must be >= 0, got {real_time_factor}")
        if self.running:
            raise SimulationError("the world's stepping loop is already running")
        self._stop.clear()
        self._thread = threading.Thread(target=self._loop, args=(real_time_factor, pause_when_idle),
                                        name="world-physics", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the stepping thread (motions in progress stay where they are)."""
        self._stop.set()
        self._work.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)   # (called from the loop itself: it ends on its own)
        self._thread = None

    def close(self) -> None:
        """Stop the loop, end every pending action, disconnect from PyBullet."""
        self.stop()
        with self._lock:
            for ticket in self._actions.pending():
                ticket.finish(Outcome(False, f"{ticket.name} abandoned: the world was closed"), self.sim_time)
            self.close_clients()

    def close_clients(self) -> None:
        """Disconnect from both PyBullet servers (safe to call twice)."""
        self.client.disconnect()
        physics = getattr(self, "physics", None)
        if physics is not None:
            physics.disconnect()

    def add_step_listener(self, listener: Callable[[float], None]) -> None:
        """Call ``listener(sim_time)`` after every physics step (on the stepping thread)."""
        self._listeners.append(listener)

    # --- the window ------------------------------------------------------------------------------
    @property
    def window_closed(self) -> bool:
        """True once PyBullet's window has been closed with Esc (False without ``gui``).

        The scene went with it: the stepping thread has stopped, pending actions ended with
        :class:`~.window.WindowClosed`, and every later call raises it. Checked at every step
        and, when idle, every 50 ms; reading this property checks too. (The window manager's
        close button is another matter: PyBullet's window does not take part in its close
        protocol, so the window manager cuts its X connection and Xlib ends the whole process,
        exit status 1.)
        """
        if self.config.gui and not self._window.closed and self.client.client_id >= 0 \
                and not self.client.connected:
            with self._lock:
                self._window.mark_closed()
        return self._window.closed

    def add_window_closed_listener(self, listener: Callable[[], None]) -> None:
        """Call ``listener()`` once when the window is found closed, on the thread that found
        it (the stepping thread, or a caller's) with the world's lock held: keep it short (set a
        flag, ask the process to shut down); it may call :meth:`close`."""
        self._window.add_closed_listener(listener)

    def show_overlay(self, lines: Sequence[str]) -> None:
        """Show ``lines`` at the window's top-left corner, wrapped to the window's width, in
        place of what was shown: all at once, never a mix of the old lines and the new (no-op
        without ``gui``).

        Each line is one debug text of PyBullet's, replaced in place (``replaceItemUniqueId``)
        and only if it changed, with the window's rendering held meanwhile
        (:meth:`.Window.show_overlay`): a frame or two of the window (tens of ms with software
        rendering), holding the world's lock. The lines are placed for the view as it is; when
        the user moves the view or resizes the window and lets it rest, the stepping loop puts
        them back in the corner. Thread-safe; raises :class:`~.window.WindowClosed` once the
        window is gone.
        """
        if not self.config.gui:
            return
        with self._locked():
            self._window.show_overlay([str(line) for line in lines])

    def overlay(self) -> List[str]:
        """The lines the overlay shows now, as wrapped (empty without ``gui``)."""
        with self._locked():
            return self._window.lines()

    def gui_camera(self) -> View:
        """The window's initial view as PyBullet takes it: distance, yaw, pitch (degrees), target."""
        return self.config.window.view()

    def step(self, count: int = 1) -> None:
        """Advance the world by ``count`` control steps on the calling thread (no stepping thread)."""
        if self.running:
            raise SimulationError("the stepping thread is running: use run() or submit() instead of step()")
        for _ in range(count):
            with self._locked():
                self._step_locked()
            self._notify()

    def advance(self, seconds: float) -> None:
        """Advance ``seconds`` of simulated time on the calling thread."""
        self.step(max(0, int(round(seconds / self.control_period))))

    def finish_motions(self) -> None:
        """Step on the calling thread until no motion is under way, those answered as they
        started (``WorldConfig.async_actions``) included."""
        limit = int(_MAX_ACTION_TIME / self.control_period)
        for _ in range(limit):
            if not any(channel.motion is not None for channel in self._actions.channels.values()):
                return
            self.step()
        raise SimulationError(f"motions still under way after {_MAX_ACTION_TIME:.0f} s of "
                              "simulated time")

    def submit(self, agent: str, action: str, caller: str = "", driver: bool = False) -> Ticket:
        """Ask ``agent`` ("human", "robot" or "world") to carry out ``action``; returns at once.

        ``caller`` names who asks (for messages). Requests queue per agent, in order; a reset
        or a cancel interrupts the agent's motion and queue. The agents have one *driver*
        (``driver=True``: the loop), who never waits behind other callers:

        * a driver's action goes first: it interrupts another caller's action of that agent
          under way (that caller's outcome says so, the driver's names what it cut short) and
          cancels the others' actions queued behind it;
        * while a driver's request for an agent is under way or waiting, another caller's
          request for that agent (for "world": for either agent) is refused at once: the
          ticket comes back done and ``refused``, its outcome ``busy: ...``.

        Without a driver's request in the world, every caller is served as it comes.
        """
        known = {"human": HUMAN_ACTIONS, "robot": ROBOT_ACTIONS, "world": ("reset",)}
        if action not in known.get(agent, ()):
            raise SimulationError(f"unknown action {agent}/{action}; known: " + ", ".join(
                f"{a}/{x}" for a, xs in known.items() for x in xs))
        ticket = Ticket(agent, action, caller, driver)
        with self._locked():
            if not self._actions.submit(ticket, self.sim_time):
                return ticket   # refused: a driver's request holds the agent
        self._work.set()
        return ticket

    def run(self, agent: str, action: str, timeout: Optional[float] = None,
            caller: str = "", driver: bool = False) -> Outcome:
        """Carry out an action and return its outcome once it is over (``caller`` and
        ``driver`` as for :meth:`submit`).

        With the stepping thread running this waits (``timeout`` in wall seconds); without it,
        it steps the physics itself until the action is over.
        """
        ticket = self.submit(agent, action, caller, driver)
        if ticket.done():
            return ticket.outcome
        if self.running:
            return ticket.wait(timeout)
        limit = int(_MAX_ACTION_TIME / self.control_period)
        for _ in range(limit):
            if ticket.done():
                return ticket.outcome
            self.step()
        raise SimulationError(f"{ticket.name} still running after {_MAX_ACTION_TIME:.0f} s of simulated time")

    def reset(self, timeout: Optional[float] = None) -> Outcome:
        """Everything back to the start: human, robot and object (the belt keeps its speed)."""
        return self.run("world", "reset", timeout)

    def query(self, predicate: str) -> Reading:
        """A human predicate (``is_ov``, ``is_oir``, ``is_ho``, ``is_a0``, ``is_a2``, ``is_h4``)."""
        if predicate not in PREDICATES:
            raise SimulationError(f"unknown predicate {predicate!r}; known: {', '.join(PREDICATES)}")
        with self._locked():
            return getattr(self.human, predicate)()

    def reseed(self, episode: int, seed: Optional[int] = None) -> None:
        """Draw from episode ``episode``'s world stream from now on (:mod:`ros_hrc.streams`),
        from its start: the coordinator's node calls this as it resets the world for that
        episode, so the episode's draws are the same whichever episodes came before it.
        ``seed``: the run's seed from now on (a warm stack's next cell; None: as it was)."""
        if seed is not None:
            self.seed = int(seed)
        fresh = streams.generator(self.seed, episode, "world")
        with self._locked():
            # In place: the human holds the same generator.
            self.rng.bit_generator.state = fresh.bit_generator.state
            self.episode = episode

    def set_belt_speed(self, speed: float) -> None:
        """Change the belt speed (m/s, downstream positive) from the next step on."""
        with self._locked():
            self._belt_speed = self.conveyor.speed = float(speed)

    def predict_object(self, seconds: float) -> np.ndarray:
        """Where the object will be in ``seconds`` of simulated time if nobody touches it: the
        belt carries it at its speed and the end stop holds it; held or off the belt, it is
        where it is."""
        with self._locked():
            return self._predicted_object(seconds)

    def _predicted_object(self, seconds: float) -> np.ndarray:
        # (Under the lock: the robot asks from inside its motion, on the stepping thread.)
        position = self.object.position()
        if self.object.holder != "none" or not self.conveyor.is_on_belt(position):
            return position
        return self.conveyor.carry(position, self.object.config.size / 2, seconds)

    def state(self) -> dict:
        """A snapshot of the world as plain data (JSON-ready)."""
        with self._locked():
            position, orientation = self.object.pose()
            on_belt = self.conveyor.is_on_belt(position)
            # Nobody took it before the belt's end (a real belt drops it there), or it fell off.
            left_belt = bool(self.object.gone) or self._at_belt_end()
            # Who has taken it: a hand holds it; the robot's (delivery_time) once it lies in
            # the robot's tray, not while the robot carries it there ("carrying").
            carrying = self.robot.carrying
            return {
                "sim_time": self.sim_time,
                "step": self.step_count,
                "belt_speed": self.conveyor.speed,
                "object": {"position": list(position), "orientation": list(orientation),
                           "holder": "none" if carrying else self.object.holder,
                           "carried_by": "robot" if carrying else "none",
                           "on_belt": on_belt, "left_belt": left_belt},
                "human": {"action": self.human.activity, "moving": self.human.moving,
                          "at_station": self.human.at_station()},
                "robot": {"action": self.robot.activity, "moving": self.robot.moving,
                          "can_reach_object": self.robot.can_reach()},
                "predicates": {name: getattr(self.human, name)().value for name in PREDICATES},
            }

    def camera_matrices(self, width: Optional[int] = None, height: Optional[int] = None,
                        window_view: bool = False) -> Matrices:
        """View and projection matrices (PyBullet's, column-major) of the snapshot camera, or
        with ``window_view`` of the window's initial view (its camera and 90 deg lens)."""
        lens = self.config.window if window_view else self.config.camera
        matrices = window_matrices if window_view else camera_matrices
        return matrices(self.client, lens, width or lens.width, height or lens.height)

    def render(self, width: Optional[int] = None, height: Optional[int] = None,
               window_view: bool = False) -> np.ndarray:
        """An RGB image ``(height, width, 3)`` from the fixed camera (software renderer: works
        headless); with ``window_view``, of what the window shows at first."""
        lens = self.config.window if window_view else self.config.camera
        width, height = width or lens.width, height or lens.height
        with self._locked():
            pixels = take_image(self.client, self.camera_matrices(width, height, window_view), width, height)
        return rgb(pixels, width, height)

    def snapshot(self, path: Union[str, Path], width: Optional[int] = None,
                 height: Optional[int] = None) -> Path:
        """Write a PNG of the scene from the fixed camera to ``path``; returns the path."""
        from PIL import Image   # on first use: few runs take a snapshot

        path = Path(path)
        image = Image.fromarray(np.ascontiguousarray(self.render(width, height), np.uint8), "RGB")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            image.save(path, format="PNG")
        except OSError as error:
            raise SimulationError(f"cannot write the snapshot {path}: {error}") from error
        return path

    def frames(self) -> dict:
        """Where everything is, for /tf and joint states (plain data): per agent its URDF file,
        root link, base pose and movable joints' positions; the object's and the belt's poses
        (position, quaternion x y z w); the simulated time."""
        with self._locked():
            out: dict = {"sim_time": self.sim_time}
            out["human"], out["robot"] = self.human.frames(), self.robot.frames()
            out["object"] = self.object.pose()
            out["belt"] = self.conveyor.surface_pose
            return out

    def describe(self) -> Sequence[str]:
        """One line per body: what the world holds (for logs)."""
        cfg = self.config
        still = f", still for the first {cfg.belt_start:g} s of a task" if cfg.belt_start else ""
        end = ", its end a tray (what falls in is gone)" if cfg.end_tray else ""
        return [f"belt x {cfg.conveyor.start_x:+.2f}..{cfg.conveyor.end_x:+.2f} m at "
                f"{self._belt_speed:.3f} m/s{still}{end}",
                "object start ({:+.2f}, {:+.2f}, {:.3f}) m".format(*self.object.start_position),
                f"human at {cfg.human.station}, robot at {cfg.robot.position}"]
