"""The PyBullet world: floor, conveyor, object, human and robot, stepped at a fixed rate.

Two PyBullet servers, because only the object needs dynamics:

* the **physics** server simulates what contact matters for: the floor, the belt (which
  carries the object by friction), its rails and end stop, and the object. It steps at
  ``time_step`` (240 Hz), ``substeps`` physics steps per control step.
* the **scene** server (``World.client``; the window with ``gui``) holds every body as it is
  seen: the same scenery, a copy of the object, the human and the robot. It is never stepped:
  the agents' joints are set along their scripted motions (they touch nothing: holding is
  done by the world, not by contact), and the object's copy is put where the physics put the
  object. Rays (line of sight), images and the agents' geometry are read here.

One loop steps the world in control steps of ``substeps * time_step`` (1/60 s). Each control
step it (1) takes the requests that came in (a reset or a cancel interrupts at once; any other
action queues behind the agent's current one) and starts a queued action where the agent is
free, (2) moves the belt, (3) steps the physics, (4) puts a held object in its holder's hand
and the object's copy where the object is, (5) advances the human's and the robot's motions
to their next command, which finishes a motion whose last step has just been taken.
Actions are therefore only ever executed by the loop, between two steps, and every
PyBullet call happens under one lock: callers on other threads (ROS service handlers) submit a
request and wait for its :class:`Ticket`, and predicate queries read the geometry under the
lock. Nothing waits for anything while holding the lock, so calls cannot deadlock.

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
from collections import deque
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Deque, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from ..errors import SimulationError
from .. import settings, streams
from .body import ArticulatedBody, Motion
from .client import PhysicsClient
from .conveyor import STATIC_GROUP, STATIC_MASK, Conveyor, ConveyorConfig
from .human import Human, HumanConfig
from .object import ObjectConfig, WorkObject
from .outcome import Outcome, Reading
from .png import write_png
from .robot import Robot, RobotConfig
from .window import WINDOW_TITLE, WindowClosed, bullet_windows, name_window, screen_points, window_options

LOG = logging.getLogger(__name__)

#: Actions each agent knows (the seed's Table 3.2, plus the human's ``idle`` and the robot's
#: ``grasp_planning``, FABRIC's graspPlanning: the open gripper over the object, no grasp).
HUMAN_ACTIONS = ("walk_away", "look_around", "warn_robot", "attempt_grasp", "grasp", "idle", "reset")
ROBOT_ACTIONS = ("point_to_obj", "grasp", "cancel_action", "reset", "grasp_planning")
#: The human predicates (seed Table 3.2), answered by :meth:`World.query`.
PREDICATES = ("is_ov", "is_oir", "is_ho", "is_a0", "is_a2", "is_h4")
#: Requests that take effect at once and interrupt the agent's motion and queue.
_INTERRUPTING = {("human", "reset"), ("robot", "reset"), ("robot", "cancel_action"), ("world", "reset")}
#: A synchronous run() gives up after this much simulated time (no action lasts that long).
_MAX_ACTION_TIME = 60.0
#: PyBullet's window draws with a fixed vertical field of view (its projection matrix has
#: 1/tan(fov/2) = 1), whatever the window's size.
GUI_FOV_DEG = 90.0
#: Named in the window's overlay.
_PACKAGE = "ros_hrc"
#: Specular colour of every body in the window (PyBullet's default glares on large faces).
_SPECULAR = (0.08, 0.08, 0.08)
#: The overlay: lines from the window's top-left corner, in pixels; their size and colour.
_OVERLAY_MARGIN = (14.0, 26.0)
_OVERLAY_LINE_PX = 22.0
_OVERLAY_TEXT_SIZE = 1.3
_OVERLAY_COLOUR = (0.05, 0.06, 0.12)
#: How often the stepping loop looks whether the user moved the window's view, s.
_LOOK_PERIOD = 0.3
#: An unheld object whose downstream face is this close to the belt's end stop has reached
#: the end: it is missed.
_AT_END_STOP_M = 0.02


def default_model_dir() -> Path:
    """``models/urdf`` of the source tree this module sits in."""
    return Path(__file__).resolve().parents[3] / "models" / "urdf"


@dataclass(frozen=True)
class CameraConfig:
    """The fixed camera of snapshots (:meth:`World.render`, ``/hrc/camera/image``).

    It looks as the window does (:class:`WindowConfig`), from further back through its
    narrower lens: the belt, both agents and both working arms are in view, and the human
    stays in it all the way through a walk-away.
    """

    eye: Tuple[float, float, float] = (-3.31, 1.30, 3.12)
    target: Tuple[float, float, float] = (-0.5, -0.6, 1.0)
    fov_deg: float = 50.0
    width: int = 800
    height: int = 600


@dataclass(frozen=True)
class WindowConfig:
    """PyBullet's window (``gui``): its size, the colour of its sky, its initial view.

    The view is PyBullet's camera (distance, yaw, pitch in degrees, target): PyBullet's window
    sees 90 deg vertically, much wider than the snapshots' 50, so it has a view of its own. It
    looks from above the belt's upstream end, behind the robot's shoulder, across the belt
    towards the human: the robot on the left, the human on the right, the belt between them,
    and room on the right for where the human's walk-away ends (1.5 m from the belt), so
    both agents stay in frame whatever they do (test_world_window checks every link).
    """

    width: int = 1024
    height: int = 768
    background: Tuple[float, float, float] = (0.86, 0.88, 0.91)
    distance: float = 1.85
    yaw_deg: float = -124.0
    pitch_deg: float = -35.0
    target: Tuple[float, float, float] = (-0.5, -0.6, 1.0)


@dataclass(frozen=True)
class WorldConfig:
    """Everything that defines a world; the defaults are the scene of docs/world.md."""

    gui: bool = settings.default("gui")
    seed: int = settings.default("seed")
    time_step: float = 1.0 / 240.0   # physics step, s
    substeps: int = 4                # physics steps per control step (motions, clock, requests)
    # The physics server holds one dynamic body (the object on the belt): 10 iterations carry
    # it exactly as 20 or PyBullet's 50 do (docs/performance.md), at half the cost of 20.
    solver_iterations: int = 10
    belt_speed: float = settings.default("belt_speed")  # m/s, downstream (+x)
    conveyor: ConveyorConfig = field(default_factory=ConveyorConfig)
    work_object: ObjectConfig = field(default_factory=ObjectConfig)
    human: HumanConfig = field(default_factory=HumanConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    #: Load the agents in colour layers (see .visuals): None = only in the window, which
    #: otherwise draws each link in one colour.
    split_visuals: Optional[bool] = None
    window: WindowConfig = field(default_factory=WindowConfig)


class Ticket:
    """A submitted action: wait for it to get its :class:`Outcome`.

    ``caller`` names who asked (for messages); ``driver``: the agents' driver asked (the
    loop), whose actions go first (see :meth:`World.submit`)."""

    def __init__(self, agent: str, action: str, caller: str = "", driver: bool = False) -> None:
        self.agent = agent
        self.action = action
        self.caller = caller
        self.driver = driver
        self.submitted_at: Optional[float] = None  # simulated time it was asked for
        self.started_at: Optional[float] = None   # simulated time the motion began
        self.outcome: Optional[Outcome] = None
        self.error: Optional[SimulationError] = None   # raised by wait(): the world failed
        self.refused = False                      # answered at once: the agent was busy
        self.preempted: List[str] = []            # other callers' actions this one cut short
        self._done = threading.Event()

    @property
    def name(self) -> str:
        """``agent/action``, as in the service names."""
        return f"{self.agent}/{self.action}"

    def asked_by(self) -> str:
        """``agent/action`` and who asked, for messages."""
        return self.name + (f" (asked by {self.caller})" if self.caller else "")

    def done(self) -> bool:
        """True once the action is over (finished, failed or interrupted)."""
        return self._done.is_set()

    def wait(self, timeout: Optional[float] = None) -> Outcome:
        """Block until the action is over and return its outcome (``timeout`` in wall seconds)."""
        if not self._done.wait(timeout):
            raise SimulationError(f"{self.name} did not finish within {timeout:.0f} s of wall-clock time "
                                  "(is the world's stepping loop running?)")
        if self.error is not None:
            raise self.error
        return self.outcome

    def finish(self, outcome: Outcome, now: float) -> None:
        """Record the outcome (with its simulated duration) and wake the waiters."""
        started = self.started_at if self.started_at is not None else now
        if self.preempted:   # say why the agent did not start from where the step left it
            outcome = replace(outcome, message=outcome.message + "; it first interrupted "
                              + ", ".join(self.preempted))
        self.outcome = replace(outcome, duration=now - started)
        self._done.set()

    def refuse(self, message: str, now: float) -> None:
        """Answer at once that the action will not run (the agent is busy for its driver)."""
        self.refused = True
        self.finish(Outcome(False, message), now)

    def fail(self, error: SimulationError, now: float) -> None:
        """End the action because the world cannot go on: the waiters get ``error``."""
        self.error = error
        self.finish(Outcome(False, f"{self.name} abandoned: {error}"), now)


class _Channel:
    """One agent's current motion and the actions queued behind it."""

    def __init__(self, body: ArticulatedBody) -> None:
        self.body = body
        self.motion: Optional[Motion] = None
        self.ticket: Optional[Ticket] = None
        self.queue: Deque[Ticket] = deque()


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
        self.rng = streams.generator(self.config.seed, self.episode, "world")
        self._lock = threading.RLock()
        self._waiters = 0
        self._waiters_lock = threading.Lock()
        self._requests: Deque[Ticket] = deque()
        self._work = threading.Event()
        self._stop = threading.Event()
        self._thread: Optional[threading.Thread] = None
        self._listeners: List[Callable[[float], None]] = []
        self._closed_listeners: List[Callable[[], None]] = []
        self._window_closed = False
        self._overlay: List[Tuple[int, str, Tuple[float, ...]]] = []   # (item id, text, where)
        self._overlay_view: Tuple[float, ...] = ()   # the window's view the overlay was placed for
        self._view_seen: Tuple[float, ...] = ()      # the view at the last look
        self._next_look = 0.0                        # when to look at the view again (monotonic s)
        cfg = self.config
        # The windows PyBullet had open before this one: the new one is ours, to be named.
        others = bullet_windows() if cfg.gui else set()
        options = window_options(cfg.window.width, cfg.window.height, cfg.window.background)
        self.client = PhysicsClient(cfg.gui, options)   # the scene: never stepped
        try:
            if cfg.gui:
                self._open_window(others)
            self.physics = PhysicsClient(False)
            self._build()
            if cfg.gui:
                self._show_window()
        except BaseException:
            self.close_clients()
            raise

    def _build(self) -> None:
        c, physics, cfg = self.client, self.physics, self.config
        # One stepSimulation() is a control step of `substeps` physics steps of `time_step`.
        physics.setTimeStep(self.control_period)
        # Pyramid friction instead of the friction cone: a third cheaper, and on a belt that
        # pulls along x the object's path is the same to 0.1 mm (docs/performance.md).
        physics.setPhysicsEngineParameter(numSolverIterations=cfg.solver_iterations,
                                          numSubSteps=cfg.substeps, enableConeFriction=0)
        physics.setGravity(0, 0, -9.81)
        self.floor_id = self._floor(c)
        if cfg.gui:
            self._hold_window()
        self._floor(physics)
        self.scenery = Conveyor(c, cfg.conveyor, 0.0)   # as seen (and as it blocks a line of sight)
        self.conveyor = Conveyor(physics, cfg.conveyor, cfg.belt_speed)
        self.object = WorkObject(c, physics, cfg.work_object, cfg.conveyor.surface_height)
        self.human = Human(c, str(self.model_dir / "human.urdf"), cfg.human, self.control_period,
                           self.object, self.rng, cfg.split_visuals)
        self.robot = Robot(c, str(self.model_dir / "pr2_like.urdf"), cfg.robot, self.control_period,
                           self.object, cfg.split_visuals, self._predicted_object)
        self._channels: Dict[str, _Channel] = {"human": _Channel(self.human), "robot": _Channel(self.robot)}

    @staticmethod
    def _floor(client: PhysicsClient) -> int:
        plane = client.createCollisionShape(client.GEOM_PLANE)
        # Wide: from the window's camera the floor, not the sky, fills the background.
        look = client.createVisualShape(client.GEOM_BOX, halfExtents=[15, 15, 0.005],
                                        rgbaColor=[0.80, 0.80, 0.78, 1], visualFramePosition=[0, 0, -0.005])
        floor = client.createMultiBody(0, plane, look)
        client.setCollisionFilterGroupMask(floor, -1, STATIC_GROUP, STATIC_MASK)
        return floor

    # --- the window (gui) ------------------------------------------------------------------------
    # PyBullet's window draws from the moment it opens, before connect() returns: its first
    # frames show PyBullet's default scene and panels. Then, with rendering off, it shows the
    # last frame drawn. So: panels off and the camera set at once (an empty scene draws in no
    # time); the floor and a "loading" line drawn; rendering off while the rest loads (ten
    # times faster: no frame per shape, no body appearing one by one); rendering on.
    def _open_window(self, others: set) -> None:
        """Right after the window opened: its title, PyBullet's panels off, light and camera."""
        c = self.client
        if not name_window(WINDOW_TITLE, others):
            LOG.info("PyBullet's window keeps PyBullet's title (no X11 window found to rename)")
        for flag in (c.COV_ENABLE_GUI, c.COV_ENABLE_RGB_BUFFER_PREVIEW, c.COV_ENABLE_DEPTH_BUFFER_PREVIEW,
                     c.COV_ENABLE_SEGMENTATION_MARK_PREVIEW, c.COV_ENABLE_MOUSE_PICKING):
            c.configureDebugVisualizer(flag, 0)
        # Light from above, behind the camera's left, as in the snapshots; shadows sized to
        # the scene.
        c.configureDebugVisualizer(lightPosition=[-3.0, -2.0, 6.0], shadowMapWorldSize=6,
                                   shadowMapResolution=1024, shadowMapIntensity=0.35)
        self._aim_gui_camera()

    def _hold_window(self) -> None:
        """With the floor in place: a frame with it and a "loading" line, then rendering off."""
        c = self.client
        c.changeVisualShape(self.floor_id, -1, specularColor=[0.0, 0.0, 0.0])   # no glare on it
        self._show_overlay_locked([f"{_PACKAGE}: loading the scene ..."])
        c.configureDebugVisualizer(c.COV_ENABLE_RENDERING, 0)

    def _show_window(self) -> None:
        """The scene is complete: matt bodies, the first overlay, rendering on."""
        c = self.client
        for body in (c.getBodyUniqueId(i) for i in range(c.getNumBodies())):
            if body != self.floor_id:
                for link in range(-1, c.getNumJoints(body)):
                    c.changeVisualShape(body, link, specularColor=list(_SPECULAR))
        self._show_overlay_locked([f"{_PACKAGE}: the scene is ready; waiting for the first step"])
        c.configureDebugVisualizer(c.COV_ENABLE_RENDERING, 1)

    def gui_camera(self) -> Tuple[float, float, float, Tuple[float, float, float]]:
        """The window's initial view as PyBullet takes it: distance, yaw, pitch (degrees), target."""
        w = self.config.window
        return w.distance, w.yaw_deg, w.pitch_deg, tuple(float(x) for x in w.target)

    def _aim_gui_camera(self) -> None:
        distance, yaw, pitch, target = self.gui_camera()
        self.client.resetDebugVisualizerCamera(distance, yaw, pitch, list(target))

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
                yield
        finally:
            with self._waiters_lock:
                self._waiters -= 1

    def _check_window(self, settle: float = 0.0) -> None:
        """Raise :class:`WindowClosed` if the window (the scene server) is gone (under the lock).

        ``settle``: after a PyBullet call failed, give the closing window this long (s) to show
        it is gone (its threads end first, the connection a moment later): a failure when the
        window closes is not the action's.
        """
        gone = self._window_closed or (self.config.gui and not self.client.connected)
        deadline = time.monotonic() + settle
        while not gone and self.config.gui and time.monotonic() < deadline:
            time.sleep(0.01)
            gone = not self.client.connected
        if gone:
            self._on_window_closed()
            raise WindowClosed("the PyBullet window was closed: the scene is gone, the world stops")

    def _on_window_closed(self) -> None:
        """Once: end every pending action with :class:`WindowClosed`, tell the listeners."""
        if self._window_closed:
            return
        self._window_closed = True
        LOG.info("the PyBullet window was closed: the world stops")
        error = WindowClosed("the PyBullet window was closed: the scene is gone, the world stops")
        for ticket in self._pending():
            ticket.fail(error, self.sim_time)
        for listener in self._closed_listeners:
            try:
                listener()
            except Exception:  # a listener's bug must not hide the closing
                LOG.exception("window-closed listener %r failed", listener)

    def _pending(self) -> List[Ticket]:
        """Take every request, running action and queued action out of the world."""
        pending = list(self._requests)
        self._requests.clear()
        for channel in self._channels.values():
            if channel.ticket is not None:
                pending.append(channel.ticket)
            pending.extend(channel.queue)
            channel.queue.clear()
            channel.motion, channel.ticket = None, None
        return pending

    def _step_locked(self) -> None:
        if self.config.gui:
            self._check_window()
            try:
                self._step_scene()
                self._follow_view()
            except Exception:
                self._check_window(settle=0.2)   # the window went during the step: say so
                raise
        else:
            self._step_scene()

    def _follow_view(self) -> None:
        """A few times a second: once the user has moved the window's view and let it rest,
        the overlay goes back to the window's corner (not while the view moves: each line
        placed costs a frame)."""
        now = time.monotonic()
        if now < self._next_look:
            return
        self._next_look = now + _LOOK_PERIOD
        view = tuple(self.client.getDebugVisualizerCamera()[2])
        if self._overlay and view != self._overlay_view and view == self._view_seen:
            self._show_overlay_locked([text for _, text, _ in self._overlay])
        self._view_seen = view

    def _step_scene(self) -> None:
        self._take_requests()
        for channel in self._channels.values():
            if channel.motion is None:
                self._advance(channel)   # start a queued action: its first command
        self.conveyor.before_step()
        self.physics.stepSimulation()
        self.object.after_step()
        self.step_count += self.config.substeps
        self.sim_time = self.step_count * self.time_step
        # The next command of each motion, right after the step: a motion of n steps is over
        # n steps after it began (its last command has had its step), not one step later.
        for channel in self._channels.values():
            if channel.motion is not None:
                self._advance(channel)

    def _take_requests(self) -> None:
        while self._requests:
            ticket = self._requests.popleft()
            if (ticket.agent, ticket.action) not in _INTERRUPTING:
                channel = self._channels[ticket.agent]
                if ticket.driver:
                    self._preempt(channel, ticket)
                channel.queue.append(ticket)
                continue
            ticket.started_at = self.sim_time
            if ticket.agent == "world":
                for agent in self._channels:
                    self._interrupt(agent, "reset")
                self.object.reset()
                self.human.reset()
                self.robot.reset()
                outcome = Outcome(True, "world reset: human, robot and object back at their start")
            elif ticket.agent == "human":
                self._interrupt("human", "reset")
                self.object.reset()  # the seed's /human/reset puts the object back too
                outcome = self.human.reset()
                outcome = replace(outcome, message=outcome.message + "; object back at the start of the belt")
            elif ticket.action == "reset":
                self._interrupt("robot", "reset")
                if self.object.holder == "robot":
                    self.object.reset()  # a released object would drop anywhere: put it back
                outcome = self.robot.reset()
            else:
                outcome = self.robot.cancel(self._interrupt("robot", "cancel_action"))
            ticket.finish(outcome, self.sim_time)

    def _interrupt(self, agent: str, by: str) -> Optional[str]:
        """Stop ``agent``'s motion and drop its queue; return the interrupted action's name."""
        channel = self._channels[agent]
        interrupted = None
        if channel.motion is not None:
            channel.motion.close()
            interrupted = channel.ticket.action
            channel.ticket.finish(Outcome(False, f"{channel.ticket.name} interrupted by {agent}/{by} after "
                                                 f"{self.sim_time - channel.ticket.started_at:.1f} s"),
                                  self.sim_time)
            channel.motion, channel.ticket = None, None
            channel.body.moving = False   # its joints stay where the last step put them
        while channel.queue:
            channel.queue.popleft().finish(
                Outcome(False, f"cancelled by {agent}/{by} before it started"), self.sim_time)
        return interrupted

    def _preempt(self, channel: _Channel, by: Ticket) -> None:
        """The driver's ``by`` goes first: another caller's action under way on ``channel``
        is interrupted, those queued are cancelled (the driver's own stay in order)."""
        running = channel.ticket
        if running is not None and not running.driver:
            if channel.motion is not None:
                channel.motion.close()
            running.finish(Outcome(False, f"{running.name} interrupted by {by.asked_by()} after "
                                          f"{self.sim_time - running.started_at:.1f} s"),
                           self.sim_time)
            by.preempted.append(running.asked_by())
            channel.motion, channel.ticket = None, None
            channel.body.moving = False   # its joints stay where the last step put them
        kept: Deque[Ticket] = deque()
        for queued in channel.queue:
            if queued.driver:
                kept.append(queued)
            else:
                queued.finish(Outcome(False, f"cancelled by {by.asked_by()} before it started"),
                              self.sim_time)
        channel.queue = kept

    def _advance(self, channel: _Channel) -> None:
        # Loop: a motion may end at its first step (e.g. "already away"), letting the next start.
        while True:
            if channel.motion is None:
                if not channel.queue:
                    return
                channel.ticket = channel.queue.popleft()
                channel.ticket.started_at = self.sim_time
                channel.motion = getattr(channel.body, channel.ticket.action)()
                channel.body.moving = True
            try:
                next(channel.motion)
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
            channel.ticket.finish(outcome, self.sim_time)
            channel.motion, channel.ticket = None, None
            channel.body.moving = False

    def _busy(self) -> bool:
        return bool(self._requests) or any(ch.motion is not None or ch.queue for ch in self._channels.values())

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
            if pause_when_idle and not self._busy():
                self._work.clear()
                if not self._busy():
                    self._work.wait(0.05)
                if self.config.gui:   # idle, the window may still be closed, or looked round
                    with self._lock:
                        self._check_window()
                        self._follow_view()
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
            for ticket in self._pending():
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
        if self.config.gui and not self._window_closed and self.client.client_id >= 0 \
                and not self.client.connected:
            with self._lock:
                self._on_window_closed()
        return self._window_closed

    def add_window_closed_listener(self, listener: Callable[[], None]) -> None:
        """Call ``listener()`` once when the window is found closed, on the thread that found
        it (the stepping thread, or a caller's) with the world's lock held: keep it short (set a
        flag, ask the process to shut down); it may call :meth:`close`."""
        self._closed_listeners.append(listener)

    def show_overlay(self, lines: Sequence[str]) -> None:
        """Show ``lines`` at the window's top-left corner, replacing what was shown (no-op
        without ``gui``).

        Each line is one debug text of PyBullet's, replaced in place (``replaceItemUniqueId``),
        and only if it changed: each change waits for one frame of the window (tens of ms with
        software rendering), holding the world's lock. The lines are placed for the view as it
        is; when the user moves the view and lets it rest, the stepping loop puts them back in
        the corner. Thread-safe; raises :class:`~.window.WindowClosed` once the window is gone.
        """
        if not self.config.gui:
            return
        with self._locked():
            self._show_overlay_locked([str(line) for line in lines])

    def overlay(self) -> List[str]:
        """The lines the overlay shows now (empty without ``gui``)."""
        with self._locked():
            return [text for _, text, _ in self._overlay]

    def _show_overlay_locked(self, lines: List[str]) -> None:
        c = self.client
        camera = c.getDebugVisualizerCamera()
        self._overlay_view = self._view_seen = tuple(camera[2])
        x, y = _OVERLAY_MARGIN
        places = screen_points(camera, [(x, y + i * _OVERLAY_LINE_PX) for i in range(len(lines))])
        shown: List[Tuple[int, str, Tuple[float, ...]]] = []
        for i, (text, place) in enumerate(zip(lines, places)):
            where = tuple(round(v, 4) for v in place)
            old = self._overlay[i] if i < len(self._overlay) else None
            if old is not None and old[1] == text and old[2] == where:
                shown.append(old)
                continue
            replace_id = old[0] if old is not None else -1
            item = c.addUserDebugText(text, list(where), list(_OVERLAY_COLOUR), textSize=_OVERLAY_TEXT_SIZE,
                                      replaceItemUniqueId=replace_id)
            shown.append((item, text, where))
        for item, _, _ in self._overlay[len(lines):]:
            c.removeUserDebugItem(item)
        self._overlay = shown

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
            ticket.submitted_at = self.sim_time
            busy = None if driver else self._driven(agent)
            if busy is not None:
                doing = "resetting" if busy.agent == "world" else f"doing {busy.action}"
                ticket.refuse(f"busy: the {busy.agent} is {doing} for "
                              f"{busy.caller or 'its driver'}, which drives it; call again "
                              "when that is done", self.sim_time)
                return ticket
            self._requests.append(ticket)
        self._work.set()
        return ticket

    def _driven(self, agent: str) -> Optional[Ticket]:
        """The driver's request that holds ``agent`` (any agent for "world"): under way,
        queued or just submitted; None if none does. (Under the lock.)"""
        agents = tuple(self._channels) if agent == "world" else (agent,)
        for ticket in self._requests:
            if ticket.driver and (agent == "world" or ticket.agent in (agent, "world")):
                return ticket
        for name in agents:
            channel = self._channels[name]
            if channel.ticket is not None and channel.ticket.driver:
                return channel.ticket
            for ticket in channel.queue:
                if ticket.driver:
                    return ticket
        return None

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

    def reseed(self, episode: int) -> None:
        """Draw from episode ``episode``'s world stream from now on (:mod:`ros_hrc.streams`),
        from its start: the coordinator's node calls this as it resets the world for that
        episode, so the episode's draws are the same whichever episodes came before it."""
        fresh = streams.generator(self.config.seed, episode, "world")
        with self._locked():
            # In place: the human holds the same generator.
            self.rng.bit_generator.state = fresh.bit_generator.state
            self.episode = episode

    def set_belt_speed(self, speed: float) -> None:
        """Change the belt speed (m/s, downstream positive) from the next step on."""
        with self._locked():
            self.conveyor.speed = float(speed)

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
        half = self.object.config.size / 2
        x = position[0] + self.conveyor.speed * max(0.0, seconds)
        x = min(x, max(position[0], self.conveyor.stop_x - half))   # the stop holds it
        x = max(x, min(position[0], self.config.conveyor.start_x + half))
        return np.array([x, position[1], position[2]])

    def state(self) -> dict:
        """A snapshot of the world as plain data (JSON-ready)."""
        with self._locked():
            position, orientation = self.object.pose()
            on_belt = self.conveyor.is_on_belt(position)
            # Nobody took it before the belt's end (a real belt drops it there), or it fell off.
            # The object rests against the stop with its centre half its size upstream of it.
            front = position[0] + self.object.config.size / 2
            left_belt = self.object.holder == "none" and (
                not on_belt or front >= self.conveyor.stop_x - _AT_END_STOP_M)
            return {
                "sim_time": self.sim_time,
                "step": self.step_count,
                "belt_speed": self.conveyor.speed,
                "object": {"position": list(position), "orientation": list(orientation),
                           "holder": self.object.holder,
                           "on_belt": on_belt, "left_belt": left_belt},
                "human": {"action": self.human.activity, "moving": self.human.moving,
                          "at_station": self.human.at_station()},
                "robot": {"action": self.robot.activity, "moving": self.robot.moving,
                          "can_reach_object": self.robot.can_reach()},
                "predicates": {name: getattr(self.human, name)().value for name in PREDICATES},
            }

    def camera_matrices(self, width: Optional[int] = None, height: Optional[int] = None,
                        window_view: bool = False) -> Tuple[Sequence[float], Sequence[float]]:
        """View and projection matrices (PyBullet's, column-major) of the snapshot camera, or
        with ``window_view`` of the window's initial view (its camera and 90 deg lens)."""
        if window_view:
            w = self.config.window
            width, height = width or w.width, height or w.height
            distance, yaw, pitch, target = self.gui_camera()
            view = self.client.computeViewMatrixFromYawPitchRoll(list(target), distance, yaw, pitch, 0.0, 2)
            return view, self.client.computeProjectionMatrixFOV(GUI_FOV_DEG, width / height, 0.01, 100.0)
        cam = self.config.camera
        width, height = width or cam.width, height or cam.height
        view = self.client.computeViewMatrix(list(cam.eye), list(cam.target), [0, 0, 1])
        return view, self.client.computeProjectionMatrixFOV(cam.fov_deg, width / height, 0.05, 20.0)

    def render(self, width: Optional[int] = None, height: Optional[int] = None,
               window_view: bool = False) -> np.ndarray:
        """An RGB image ``(height, width, 3)`` from the fixed camera (software renderer: works
        headless); with ``window_view``, of what the window shows at first."""
        if window_view:
            width, height = width or self.config.window.width, height or self.config.window.height
        else:
            width, height = width or self.config.camera.width, height or self.config.camera.height
        with self._locked():
            c = self.client
            view, projection = self.camera_matrices(width, height, window_view)
            image = c.getCameraImage(width, height, view, projection, shadow=1,
                                     lightDirection=[-1.0, -2.0, 4.0], renderer=c.ER_TINY_RENDERER)
        pixels = np.reshape(np.asarray(image[2], dtype=np.uint8), (height, width, 4))
        return pixels[:, :, :3]

    def snapshot(self, path: Union[str, Path], width: Optional[int] = None,
                 height: Optional[int] = None) -> Path:
        """Write a PNG of the scene from the fixed camera to ``path``; returns the path."""
        path = Path(path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_png(path, self.render(width, height))
        except OSError as error:
            raise SimulationError(f"cannot write the snapshot {path}: {error}") from error
        return path

    def frames(self) -> dict:
        """Where everything is, for /tf and joint states (plain data): per agent its URDF file,
        root link, base pose and movable joints' positions; the object's and the belt's poses
        (position, quaternion x y z w); the simulated time."""
        with self._locked():
            out: dict = {"sim_time": self.sim_time}
            for name, body in (("human", self.human), ("robot", self.robot)):
                c = body.client
                out[name] = {"urdf": body.urdf_path,
                             "root": c.getBodyInfo(body.body_id)[0].decode(),
                             "base": c.getBasePositionAndOrientation(body.body_id),
                             "joints": body.positions(body.joints)}
            out["object"] = self.object.pose()
            out["belt"] = self.conveyor.surface_pose
            return out

    def describe(self) -> Sequence[str]:
        """One line per body: what the world holds (for logs)."""
        cfg = self.config
        return [f"belt x {cfg.conveyor.start_x:+.2f}..{cfg.conveyor.end_x:+.2f} m at {self.conveyor.speed:.3f} m/s",
                "object start ({:+.2f}, {:+.2f}, {:.3f}) m".format(*self.object.start_position),
                f"human at {cfg.human.station}, robot at {cfg.robot.position}"]
