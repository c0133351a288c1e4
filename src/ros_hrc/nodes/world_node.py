"""hrc_world: the PyBullet world (ros_hrc.world) served over ROS.

Every service is a ``std_srvs/Trigger`` adapter around one call of the world; actions return
when their motion is over (``success``: it did what was asked; ``message``: what happened),
predicates answer in ``success`` and explain in ``message``. A fault of the world (it closed,
an action did not finish in time) is a service error, never a ``false``.

The loop's node (~loop_nodes: hrc_human, which calls /human/<action>, /robot/<action> and
/hrc/world/reset) drives the agents and is served first: their action
interrupts another caller's action of that agent under way and cancels those queued, and while
it runs another caller's call for that agent gets ``success=false``, ``busy: the human is
doing grasp for /hrc_human, ...`` at once (docs/world.md, "Who is served first"). The caller
is the node named in the call's connection header.

Services (names as in the seed's Table 3.2, plus ``/human/idle``, ``/robot/grasp_planning``
and the snapshot):
  /human/walk_away, /human/look_around, /human/warn_robot, /human/attempt_grasp, /human/grasp,
  /human/reset (human and object back to the start), /human/idle (relax and do nothing: the
  MDP's idle action), /human/is_ov, /human/is_oir, /human/is_ho, /human/is_a0, /human/is_a2,
  /human/is_h4, /robot/point_to_obj, /robot/grasp, /robot/cancel_action, /robot/reset,
  /robot/grasp_planning (the open gripper to the pre-grasp pose over where the belt brings
  the object, no grasp: the fabric task's graspPlanning),
  /hrc/world/snapshot (writes a PNG of the scene; ``message`` is its path)
  /hrc/world/reset (human, robot and object back at their start at once, interrupting any
                    action under way: the coordinator's reset; the world's random stream
                    restarts as the one of episode /hrc/world/episode when that parameter is
                    set: hrc_human sets it to the episode that starts, ros_hrc.streams)
  /hrc/world/state (ros_hrc/GetWorldState: the state now, as /hrc/world_state publishes it)

Topics published:
  /hrc/world_state (ros_hrc/WorldState)  object pose, holder, whether it left the belt (the
                                         task's end: nobody took it before the belt's end),
                                         both agents' actions (the robot's by the task's
                                         names, as the step block shows them: rGrasp_obj,
                                         not /robot/grasp), predicates,
                                         at ~publish_rate Hz of wall-clock time, while anyone
                                         subscribes
  /clock (rosgraph_msgs/Clock)           the world's simulated time, when /use_sim_time is true
  /human/joint_states, /robot/joint_states (sensor_msgs/JointState)  each agent's movable
                                         joints, and /tf: world -> each agent's root link
                                         (``human/...``, ``robot/...``), world -> object,
                                         world -> object_floor (the floor under the object,
                                         turned as the world: hrc_viz's label over it),
                                         world -> belt; at ~tf_rate Hz (wall clock) when
                                         ~viz. robot_state_publisher (one per agent, in
                                         its namespace) turns the joint states into the links'
                                         frames from /human/robot_description and
                                         /robot/robot_description, which the launch sets from
                                         hrc_description: each agent's URDF with its links
                                         prefixed by its name (ros_hrc.commands.description).
  /hrc/camera/image (sensor_msgs/Image)  the snapshot renderer's view, at ~camera_rate Hz
                                         (0: off, the default) while anyone subscribes
  /hrc/caption (std_msgs/String, latched) with ~gui or ~viz: the caption of the step being
                                         played (ros_hrc.loop.display.StepCaption: the action
                                         under way, then its outcome, then the step's report;
                                         cleared on reset), one message per change; the GUI
                                         window's overlay shows the same lines

Subscribed (with ~gui or ~viz): /hrc/status (the loop's steps), for the caption.

Closing the window (Esc) logs one line and asks the roslaunch that started the node to stop,
as Ctrl-C does (the node ends with status 0). From the moment the world ends (the window
closed, or the node was asked to stop), every call, and every call still waiting for its action,
is answered at once with a service error that says so, ``the world is shutting down: <why>``
(:data:`ros_hrc.errors.WORLD_ENDING`, which hrc_human reads as the run's end, not as a fault),
without a traceback; on the node's shutdown the threads that read the world (frames, states,
camera) stop before PyBullet is disconnected, so none of them meets a dead physics server.

The world is the task's: a task with world facts of its own (``task.world_facts``, fabric's:
the belt still for 45 s of a task and then 7 s to a tray at its end, the robot's 4 s of
planning, its grasp answered as it starts and counted once the object lies in the robot's
tray; ros_hrc.world.config.task_world_config) gets them; fabric's belt_run sets the running
belt's speed, so ~belt_speed is not used there.

Parameters (read once at start-up, nodes.common.read_config): the launch settings ~gui,
~task (whose names the robot's action goes by in /hrc/world_state, and whose world it is), ~seed, ~belt_speed, ~away_time (auto: 0), ~real_time_factor, ~pause_when_idle (auto: when
real_time_factor is 0), ~publish_rate, ~snapshot_dir (empty: $ROS_HOME/hrc_snapshots; file
names carry the run's start time and a counter: never overwritten), ~viz (joint states and
/tf, above), ~camera_rate (0: /hrc/camera/image not published) and /use_sim_time (publish
/clock from the simulated time), each with its default and checks from ros_hrc.settings
(docs/settings.md). world.launch's pre-flight (hrc_check --world) sets them; under
hrc.launch, whose pre-flight checked and resolved them with the rest of the launch's settings,
they are read from that resolved configuration instead (~checked_config names it:
hrc/config), and no second pre-flight runs (both include launch/world_nodes.launch). And the
node's own:
  ~action_timeout (float, 120.0)  wall seconds a service call waits for its action
  ~tf_rate (float, 30.0)          the rate of the joint states and /tf, Hz (wall clock)
  ~model_dir (str, <package>/models/urdf)       where the URDF models are
  ~loop_nodes (list, [hrc_human])   the nodes whose calls drive the agents (names
                                  relative to this node's namespace)
"""
from __future__ import annotations

import itertools
import os
import signal
import threading
import time
from dataclasses import dataclass, replace
from typing import Any, Callable, Dict, List, Optional, Tuple

import rospkg
import rospy
import tf2_ros
from geometry_msgs.msg import TransformStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import String
from std_srvs.srv import Trigger, TriggerRequest, TriggerResponse

from ros_hrc.errors import WORLD_ENDING, HrcError, SimulationError
from ros_hrc import settings, tasks
from ros_hrc.loop.display import StepCaption
from ros_hrc.streams import WORLD_EPISODE_PARAM, WORLD_SEED_PARAM
from ros_hrc.msg import Status, WorldState
from ros_hrc.nodes.common import ParamReader, init_node, parameter, read_config
from ros_hrc.nodes.guard import is_guard
from ros_hrc.nodes.viz_node import OBJECT_FLOOR_FRAME
from ros_hrc.process_tree import is_roslaunch, parent_of
from ros_hrc.srv import GetWorldState, GetWorldStateRequest, GetWorldStateResponse
from ros_hrc.world.config import task_world_config
from ros_hrc.world.human import HumanConfig
from ros_hrc.world import HUMAN_ACTIONS, PREDICATES, ROBOT_ACTIONS, WindowClosed, World

#: /clock is published at most this often (wall clock): enough for any rospy.Rate, and cheap
#: when the world runs much faster than real time.
_CLOCK_MAX_RATE = 1000.0


@dataclass(frozen=True)
class WorldNodeConfig:
    """The node's parameters (module docstring), read by :meth:`from_params`; a launch
    setting's default is the table's (:mod:`ros_hrc.settings`)."""

    gui: bool = settings.default("gui")
    task: str = settings.default("task")
    seed: int = settings.default("seed")
    belt_speed: float = settings.default("belt_speed")
    #: Not given (world.launch alone, an older launch): no time, the default task's.
    away_time: Optional[float] = settings.default("away_time")
    real_time_factor: float = settings.default("real_time_factor")
    #: None (not given, or auto): decided by :func:`ros_hrc.settings.resolve`.
    pause_when_idle: Optional[bool] = settings.default("pause_when_idle")
    publish_rate: float = settings.default("publish_rate")
    action_timeout: float = 120.0
    snapshot_dir: str = settings.default("snapshot_dir")   # empty: $ROS_HOME/hrc_snapshots
    model_dir: str = ""                                     # empty: the package's models/urdf
    use_sim_time: bool = parameter(settings.default("use_sim_time"), "/use_sim_time")
    viz: bool = settings.default("viz")
    tf_rate: float = 30.0
    camera_rate: float = settings.default("camera_rate")
    loop_nodes: Tuple[str, ...] = ("hrc_human",)

    @classmethod
    def from_params(cls, get_param: Optional[ParamReader] = None) -> "WorldNodeConfig":
        """Read the parameters once (:func:`ros_hrc.nodes.common.read_config`), then decide
        what they leave open: the automatic pause_when_idle, the default paths."""
        read = rospy.get_param if get_param is None else get_param
        given = read_config(cls, read, checked_config(read))
        # resolve() decides an automatic pause_when_idle (when real_time_factor is 0) and the
        # snapshots' default folder.
        pace = settings.resolve({"real_time_factor": given.real_time_factor,
                                 "pause_when_idle": given.pause_when_idle})
        config = replace(
            given, away_time=given.away_time or 0.0,
            pause_when_idle=pace["pause_when_idle"],
            snapshot_dir=given.snapshot_dir or pace["snapshot_dir"],   # $ROS_HOME's
            model_dir=given.model_dir or os.path.join(rospkg.RosPack().get_path("ros_hrc"),
                                                      "models", "urdf"))
        if config.action_timeout <= 0 or config.tf_rate <= 0:
            raise ValueError(f"~action_timeout and ~tf_rate must be > 0; got {config}")
        return config


def checked_config(read: ParamReader) -> Optional[Dict[str, Any]]:
    """The launch's resolved configuration that ``~checked_config`` names (hrc.launch's
    pre-flight put it there, having checked the world's settings with the rest), or None
    when it names none (world.launch alone: its own pre-flight gave the private parameters).
    Raises HrcError when it names one that is not there."""
    name = read("~checked_config", "")
    if not name:
        return None
    config = read(name, None)
    if not isinstance(config, dict):
        raise HrcError(f"~checked_config: no resolved configuration at {name} (hrc.launch's "
                       "pre-flight puts it there)")
    return config


def stop_parent_launch(parent: Optional[int] = None) -> bool:
    """Ask the roslaunch that started this process (through its guard, hrc_guard) to stop, as
    Ctrl-C does (SIGINT). False, and nothing sent, when that is not a roslaunch (a node run by
    hand, or by rostest)."""
    parent = os.getppid() if parent is None else parent
    if is_guard(parent):
        parent = parent_of(parent) or 0
    if parent <= 1 or not is_roslaunch(parent):
        return False
    try:
        os.kill(parent, signal.SIGINT)
    except OSError:
        return False
    return True


def snapshot_name(run: str, number: int, sim_time: float) -> str:
    """``world_<run>_<number>_<sim time>s.png``: the run's start (wall clock) and a counter make
    names unique across runs and within one; the simulated time says when in the run."""
    return f"world_{run}_{number:04d}_{sim_time:09.3f}s.png"


# A world fault (the world closed, an action that never finished) is raised, so that rospy
# answers the caller with a service *error*: a fault never reads as "false" (a predicate that
# does not hold, an action the world refused).

class WorldEnd:
    """Whether the world ends with the run, and why ("" while it runs): the PyBullet window
    was closed, or the node was asked to stop. Set once; read by every service handler."""

    def __init__(self) -> None:
        self._why = ""
        self._lock = threading.Lock()

    @property
    def why(self) -> str:
        """Why the world ends; "" while it runs."""
        return self._why

    def begin(self, why: str) -> None:
        """The world ends, because ``why`` (the first reason given stays)."""
        with self._lock:
            if not self._why:
                self._why = why

    def error(self) -> rospy.ServiceException:
        """The service error every call gets from now on: ``the world is shutting down: why``
        (rospy answers a ServiceException without a traceback)."""
        return rospy.ServiceException(f"{WORLD_ENDING}: {self._why}")


#: Why the world ends, as :class:`WorldEnd` says it.
WINDOW_CLOSED = "the PyBullet window was closed"
NODE_STOPPING = "the node was asked to stop"


def until_the_end(handler: Callable[[Any], Any], end: WorldEnd) -> Callable[[Any], Any]:
    """``handler``, answering while the world runs; once it ends (``end``) every call, and
    a call whose action the end cut short, gets ``end``'s service error: no answer made by a
    world that is going is taken for the world's. A closed window met during a call is the
    end too (the world's own listener may not have said so yet)."""
    def handle(request: Any) -> Any:
        if end.why:
            raise end.error()
        try:
            response = handler(request)
        except WindowClosed as error:
            end.begin(WINDOW_CLOSED)
            raise end.error() from error
        except Exception as error:
            if end.why:   # a world going away under the call: PyBullet's own errors too
                raise end.error() from error
            raise
        if end.why:   # e.g. an action abandoned because the world was closed
            raise end.error()
        return response
    return handle


def caller_of(request: Any) -> str:
    """The node that made a service call (its connection header's ``callerid``), or ""."""
    header = getattr(request, "_connection_header", None) or {}
    return str(header.get("callerid", ""))


def action_handler(world: World, agent: str, action: str, timeout: float,
                   board: Optional["CaptionBoard"] = None,
                   loop_nodes: frozenset = frozenset()) -> Callable[[TriggerRequest], TriggerResponse]:
    """Trigger handler running ``agent``'s ``action`` in the world and waiting for its outcome;
    ``board`` (if any) is told when it starts and how it ended. A call from one of
    ``loop_nodes`` is the driver's (:meth:`ros_hrc.world.World.submit`): it goes first, and
    other callers are answered ``busy`` while it runs."""
    def handle(request: TriggerRequest) -> TriggerResponse:
        caller = caller_of(request)
        ticket = world.submit(agent, action, caller, caller in loop_nodes)
        if ticket.refused:   # busy for the loop: a normal answer, nothing was shown or done
            return TriggerResponse(False, ticket.outcome.message)
        if board is not None:
            board.action_started(agent, action)
        try:
            outcome = ticket.wait(timeout)   # SimulationError: a service error
        except SimulationError as error:
            if board is not None:
                board.action_finished(agent, action, False, str(error))
            raise
        if board is not None:
            board.action_finished(agent, action, outcome.success, outcome.message)
        return TriggerResponse(outcome.success, outcome.message)
    return handle


class CaptionBoard:
    """The caption of the step being played (:class:`ros_hrc.loop.display.StepCaption`), fed
    by the world's actions and /hrc/status, shown over PyBullet's window (``show``) and
    published on ``/hrc/caption`` for RViz's text (``publish``; latched). Thread-safe: service
    handlers and the status subscriber call it at once; one change is shown at a time, in order.
    Each change is one step's whole caption, handed to both as the same lines: the window
    swaps all of them at once and wraps them to its width (:meth:`ros_hrc.world.World.show_overlay`);
    the topic carries them unwrapped, one per line, and hrc_viz wraps them for RViz."""

    def __init__(self, show: Optional[Callable[[List[str]], None]],
                 publish: Optional[Callable[[str], None]]) -> None:
        self._caption = StepCaption()
        self._show, self._publish = show, publish
        self._lock = threading.Lock()

    def lines(self) -> List[str]:
        with self._lock:
            return self._caption.lines()

    def action_started(self, agent: str, action: str) -> None:
        self._change(lambda caption: caption.action_started(agent, action))

    def action_finished(self, agent: str, action: str, success: bool, message: str) -> None:
        if agent == "world" and action == "reset":
            self._change(lambda caption: caption.reset())
        else:
            self._change(lambda caption: caption.action_finished(agent, action, success, message))

    def step_done(self, status: Status) -> None:
        self._change(lambda caption: caption.step_done(status))

    def _change(self, change: Callable[[StepCaption], List[str]]) -> None:
        with self._lock:
            before = self._caption.lines()
            lines = change(self._caption)
            if lines == before:
                return
            if self._show is not None:
                try:
                    self._show(lines)
                except SimulationError as error:   # the window went: the node is ending
                    rospy.logdebug("hrc_world: no overlay: %s", error)
            if self._publish is not None:
                self._publish("\n".join(lines))


def reseeding(world: World, reset: Callable[[TriggerRequest], TriggerResponse]
              ) -> Callable[[TriggerRequest], TriggerResponse]:
    """The world's reset handler ``reset``, first reseeding the world for the episode that
    starts (the ``/hrc/world/episode`` parameter, which hrc_human sets just before it resets
    the world, with the run's seed in ``/hrc/world/seed``: a warm stack's next cell brings
    another); without the parameter (the world alone) the stream goes on as it was."""
    def handle(request: TriggerRequest) -> TriggerResponse:
        episode = rospy.get_param(WORLD_EPISODE_PARAM, None)
        if episode is not None:
            seed = rospy.get_param(WORLD_SEED_PARAM, None)
            world.reseed(int(episode), None if seed is None else int(seed))
        return reset(request)
    return handle


def predicate_handler(world: World, predicate: str) -> Callable[[TriggerRequest], TriggerResponse]:
    """Trigger handler answering a human predicate from the current geometry."""
    def handle(_request: TriggerRequest) -> TriggerResponse:
        reading = world.query(predicate)   # SimulationError: a service error, never "false"
        return TriggerResponse(reading.value, reading.message)
    return handle


def snapshot_handler(world: World, directory: str) -> Callable[[TriggerRequest], TriggerResponse]:
    """Trigger handler writing a PNG of the scene; the message is the file's path."""
    run = time.strftime("%Y%m%d-%H%M%S") + f"-{os.getpid()}"
    numbers = itertools.count(1)

    def handle(_request: TriggerRequest) -> TriggerResponse:
        path = os.path.join(directory, snapshot_name(run, next(numbers), world.sim_time))
        try:
            return TriggerResponse(True, str(world.snapshot(path)))
        except SimulationError as error:
            return TriggerResponse(False, str(error))
    return handle


def robot_action_names(task: tasks.Task) -> Dict[str, str]:
    """What the world's robot is doing (its service's name, or ``idle``) -> the task's name
    of that robot action, as the step block and /hrc/status name it (seed: ``grasp`` ->
    ``rGrasp_obj``): the executor's mapping (``Task.robot_action_services``), read backwards."""
    names = {service: action for action, service in task.robot_action_services.items()
             if service is not None}
    names["idle"] = task.robot_idle_action
    return names


def state_message(state: dict, stamp: rospy.Time,
                  robot_actions: Optional[Dict[str, str]] = None) -> WorldState:
    """The world's :meth:`~ros_hrc.world.World.state` as a ``ros_hrc/WorldState``; the robot's
    action by its name in ``robot_actions`` (:func:`robot_action_names`; one the task has no
    name for keeps the world's)."""
    msg = WorldState()
    msg.header.stamp = stamp
    msg.header.frame_id = "world"
    msg.sim_time = state["sim_time"]
    msg.object_position = state["object"]["position"]
    msg.object_orientation = state["object"]["orientation"]
    msg.holder = state["object"]["holder"]
    msg.object_on_belt = state["object"]["on_belt"]
    msg.object_left_belt = state["object"]["left_belt"]
    msg.human_action = state["human"]["action"]
    msg.robot_action = (robot_actions or {}).get(state["robot"]["action"],
                                                 state["robot"]["action"])
    msg.belt_speed = state["belt_speed"]
    predicates = state["predicates"]
    msg.object_visible = predicates["is_ov"]
    msg.object_in_reach = predicates["is_oir"]
    msg.human_has_object = predicates["is_ho"]
    msg.human_attempting_grasp = predicates["is_a0"]
    msg.human_idle = predicates["is_a2"]
    msg.human_warning = predicates["is_h4"]
    return msg


class WorldNode:
    """The world, its services, its state publisher and (under simulated time) its clock."""

    def __init__(self, config: WorldNodeConfig) -> None:
        self.config = config
        self.world: Optional[World] = None
        self._services: list = []
        self._stop = threading.Event()
        self._threads: List[threading.Thread] = []   # the threads that read the world
        self._last_clock = 0.0
        self.window_closed = False
        self.end = WorldEnd()
        self.robot_actions = robot_action_names(tasks.get(config.task))

    def start(self) -> None:
        """Build the world, advertise everything, start stepping."""
        c = self.config
        # The task's own world facts (fabric's belt timer, tray and robot), if it has any.
        facts = getattr(tasks.get(c.task), "world_facts", {})
        self.world = World(task_world_config(facts, gui=c.gui, seed=c.seed,
                                             belt_speed=c.belt_speed,
                                             human=HumanConfig(away_time=c.away_time)),
                           c.model_dir)
        self._clock_pub = rospy.Publisher("/clock", Clock, queue_size=1) if c.use_sim_time else None
        self._state_pub = rospy.Publisher("/hrc/world_state", WorldState, queue_size=1)
        if self._clock_pub is not None:
            self.world.add_step_listener(self._publish_clock)
        # The caption of the step being played (the window's overlay, RViz's text): only for
        # someone watching. Experiments (no gui, no viz) skip it.
        board = None
        if c.gui or c.viz:
            caption_pub = rospy.Publisher("/hrc/caption", String, queue_size=10, latch=True)
            board = CaptionBoard(self.world.show_overlay if c.gui else None,
                                 lambda text: caption_pub.publish(String(data=text)))
        self.board = board
        # The loop's nodes drive the agents: their calls go first (docs/world.md, "Who is
        # served first").
        loop = frozenset(rospy.resolve_name(name) for name in c.loop_nodes)
        for action in HUMAN_ACTIONS:
            self._advertise(f"/human/{action}", action_handler(
                self.world, "human", action, c.action_timeout, board, loop))
        for predicate in PREDICATES:
            self._advertise(f"/human/{predicate}", predicate_handler(self.world, predicate))
        for action in ROBOT_ACTIONS:
            self._advertise(f"/robot/{action}", action_handler(
                self.world, "robot", action, c.action_timeout, board, loop))
        self._advertise("/hrc/world/snapshot", snapshot_handler(self.world, c.snapshot_dir))
        self._advertise("/hrc/world/reset", reseeding(self.world, action_handler(
            self.world, "world", "reset", c.action_timeout, board, loop)))
        self._services.append(rospy.Service("/hrc/world/state", GetWorldState,
                                            until_the_end(self._state_now, self.end)))
        # The physics runs in its own thread paced by the wall clock: under /use_sim_time this
        # node is the clock, so nothing here may wait on rospy time.
        if c.viz:
            self._start_frames()
        if c.gui:
            self.world.add_window_closed_listener(self._on_window_closed)
        if board is not None:
            rospy.Subscriber("/hrc/status", Status, board.step_done, queue_size=10)
        if c.camera_rate > 0:
            self._image_pub = rospy.Publisher("/hrc/camera/image", Image, queue_size=1)
            self._start_thread(self._publish_images, "world-camera")
        self.world.start(c.real_time_factor, c.pause_when_idle)
        self._start_thread(self._publish_states, "world-state")
        rospy.loginfo("hrc_world: %s; real-time factor %s%s; %d services up",
                      "; ".join(self.world.describe()), c.real_time_factor or "max",
                      ", publishing /clock" if c.use_sim_time else "", len(self._services))

    # -- RViz: descriptions, joint states, /tf ------------------------------------------------
    def _start_frames(self) -> None:
        self._joint_pubs: Dict[str, rospy.Publisher] = {
            agent: rospy.Publisher(f"/{agent}/joint_states", JointState, queue_size=1)
            for agent in ("human", "robot")}
        self._tf = tf2_ros.TransformBroadcaster()
        self._start_thread(self._publish_frames, "world-frames")

    def _transform(self, stamp: rospy.Time, child: str, pose) -> TransformStamped:
        (x, y, z), (qx, qy, qz, qw) = pose
        msg = TransformStamped()
        msg.header.stamp = stamp
        msg.header.frame_id = "world"
        msg.child_frame_id = child
        msg.transform.translation.x, msg.transform.translation.y = x, y
        msg.transform.translation.z = z
        msg.transform.rotation.x, msg.transform.rotation.y = qx, qy
        msg.transform.rotation.z, msg.transform.rotation.w = qz, qw
        return msg

    def _publish_frames(self) -> None:
        period = 1.0 / self.config.tf_rate
        while not self._stop.wait(period):
            try:
                frames = self.world.frames()
            except Exception as error:
                if not self._world_gone():
                    raise
                rospy.logdebug("hrc_world: no frames: %s", error)
                return
            stamp = self._stamp(frames)
            transforms = []
            for agent in ("human", "robot"):
                body = frames[agent]
                joints = JointState()
                joints.header.stamp = stamp
                joints.name = list(body["joints"])
                joints.position = [float(v) for v in body["joints"].values()]
                self._joint_pubs[agent].publish(joints)
                transforms.append(self._transform(stamp, f"{agent}/{body['root']}", body["base"]))
            transforms.append(self._transform(stamp, "object", frames["object"]))
            # The floor under the object, not turning with it: a label at a fixed height
            # straight over it, whoever carries it where.
            (x, y, _), _ = frames["object"]
            transforms.append(self._transform(stamp, OBJECT_FLOOR_FRAME,
                                              ((x, y, 0.0), (0.0, 0.0, 0.0, 1.0))))
            transforms.append(self._transform(stamp, "belt", frames["belt"]))
            self._tf.sendTransform(transforms)

    # -- the GUI's overlay and the camera image --------------------------------------------------
    def _on_window_closed(self) -> None:
        # Esc is how a user ends a run with a window: one line, then roslaunch stops everything
        # as Ctrl-C does. A required node that ended by itself would make roslaunch print a
        # red "REQUIRED process has died" banner, so the node asks roslaunch, its parent, to
        # stop, and lets roslaunch end it. Run by hand (rosrun), it just ends. (Called on the
        # world's thread with its lock held: quick things only.)
        self.window_closed = True
        self.end.begin(WINDOW_CLOSED)
        rospy.loginfo("hrc_world: the PyBullet window was closed: the launch stops")
        if not stop_parent_launch():
            rospy.signal_shutdown("the PyBullet window was closed")

    def _publish_images(self) -> None:
        period = 1.0 / self.config.camera_rate
        while not self._stop.wait(period):
            if self._image_pub.get_num_connections() == 0:
                continue   # rendering costs tens of ms: only for listeners
            try:
                pixels = self.world.render()
            except Exception as error:
                if not self._world_gone():
                    raise
                rospy.logdebug("hrc_world: no image: %s", error)
                return
            msg = Image()
            msg.header.stamp = rospy.Time.now()
            msg.header.frame_id = "camera"
            msg.height, msg.width = int(pixels.shape[0]), int(pixels.shape[1])
            msg.encoding, msg.is_bigendian, msg.step = "rgb8", 0, 3 * int(pixels.shape[1])
            msg.data = pixels.tobytes()
            self._image_pub.publish(msg)

    def _advertise(self, name: str, handler: Callable[[TriggerRequest], TriggerResponse]) -> None:
        self._services.append(rospy.Service(name, Trigger, until_the_end(handler, self.end)))

    def _start_thread(self, target: Callable[[], None], name: str) -> None:
        thread = threading.Thread(target=target, name=name, daemon=True)
        self._threads.append(thread)
        thread.start()

    def _world_gone(self) -> bool:
        """Whether the world ended (the node stops, or the window was closed): a failed read
        of it is then the end of the thread that read it, not a fault."""
        return bool(self.end.why) or self.world.window_closed

    def _stamp(self, state: dict) -> rospy.Time:
        return rospy.Time.from_sec(state["sim_time"]) if self.config.use_sim_time else rospy.Time.now()

    def _state_now(self, _request: GetWorldStateRequest) -> GetWorldStateResponse:
        state = self.world.state()   # a SimulationError reaches the caller as a service error
        return GetWorldStateResponse(state=state_message(state, self._stamp(state),
                                                         self.robot_actions))

    def _publish_clock(self, sim_time: float) -> None:
        now = time.monotonic()
        if now - self._last_clock >= 1.0 / _CLOCK_MAX_RATE:
            self._last_clock = now
            self._clock_pub.publish(Clock(clock=rospy.Time.from_sec(sim_time)))

    def _publish_states(self) -> None:
        period = 1.0 / self.config.publish_rate
        while not self._stop.wait(period):
            if self._state_pub.get_num_connections() == 0:
                continue   # a state costs six predicates under the world's lock: only for listeners
            try:
                state = self.world.state()
            except Exception as error:
                if not self._world_gone():
                    raise
                rospy.logdebug("hrc_world: no state: %s", error)
                return
            self._state_pub.publish(state_message(state, self._stamp(state), self.robot_actions))

    def shutdown(self) -> None:
        """End the world in an order in which nothing meets a dead physics server: the
        services answer that the world ends, the threads that read it stop (and are waited
        for), then the world closes (the calls still waiting for an action are answered
        that the world ends), and only then are the services taken down."""
        self.end.begin(NODE_STOPPING)
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=5.0)
        if self.world is not None:
            self.world.close()
        for service in self._services:
            service.shutdown()


def main() -> None:
    """Entry point of ``scripts/hrc_world``."""
    init_node("hrc_world")
    try:
        config = WorldNodeConfig.from_params()
        node = WorldNode(config)
        rospy.on_shutdown(node.shutdown)
        node.start()
    except (HrcError, ValueError) as error:
        rospy.logfatal("hrc_world cannot start: %s", error)
        raise SystemExit(1) from error
    rospy.spin()   # a closed window ends here with status 0: the user's end, not a fault
