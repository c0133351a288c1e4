"""hrc_human: hosts the loop's episode coordinator and adapts it to ROS and the links.

The coordinator (:mod:`ros_hrc.loop.coordinator`) owns the step; this node only carries out
what it asks, through four adapters (:mod:`ros_hrc.nodes.loop_ports`):

* the **human MDP**: a websocket server (``~human_port``, 9090 by default, bound to
  ``~host``). The first client is the served MDP; a second one is refused with one line and
  disconnected.
  ``step`` messages go to the coordinator; its answers go back as ``ack`` / ``error``, and a
  ``reset`` (with the new epoch) starts each episode. A human who hears the robot (a task
  with reaction rules) answers each ``ack`` with a ``reaction`` (his state after the robot
  acted), which completes the step.
* the **world**: ``/human/<action>`` (the seed's Table 3.2), ``/hrc/world/state`` (one
  atomic snapshot: the six predicates and where the object is) and ``/hrc/world/reset``,
  after setting ``/hrc/world/episode`` to the episode that starts (the world reseeds its
  random stream from it).
* the **robot planner**: this node is the websocket client of the POMDP process
  (``~pomdp_port``, 7070 by default): the robot's ``observation`` out, the ``decision`` that
  answers it in, a ``reset`` into each new epoch. No process in between.
* the **robot executor**: the world's ``/robot/<action>`` service of the robot's action (the
  seed's Table 3.2: ``rPoint_obj`` /robot/point_to_obj, ``rGrasp_obj`` /robot/grasp,
  ``rStop_all`` /robot/cancel_action; ``rIdle`` moves nothing). No process in between: this
  node drives both agents of the world.

Each step prints one block in the terminal and is published on ``/hrc/status`` (also a step
that failed: its ``fault`` says what failed, and the loop starts again from a reset).

**Start-up.** The world (a GUI world under load can take a minute) and the POMDP process may
come up after this node. No call goes to them before every service the loop uses is
registered and the POMDP process is connected: the node waits for them with no timeout,
naming those still awaited every ``~wait_report_every`` seconds (``waiting for the world
(hrc_world): /hrc/world/reset, ... (30 s; ...)``). Until then the first reset waits, so the
MDP gets no ``reset`` and takes no step: step 0 is taken once, when the world and the
planner can carry it out. Later, while the POMDP process is not connected (it died, or is
restarting), a decision or a reset of the planner is answered at once that it is not: the
step fails, and the reset says what it could not reset and is retried.

**This terminal.** Enter resets everything. In manual mode a line typed here that is not
empty is the human's next state for the MDP (a number; anything else lets the model choose),
sent as ``/hrc/set_human_state`` sends it: without a display the MDP has no terminal of its
own and its prompt shows here, so what is typed at it must not be taken for Enter. When the
input ends (Ctrl-D) the node says so: Enter no longer resets, ``/hrc/reset`` still does.

**A sequence of tasks** (``tasks:=N``; docs/sequences.md): the coordinator plays N tasks, each
by the human the schedule names (``schedule``), and resets into the next by itself. When a
task ends this node publishes it on ``/hrc/task_status`` (ros_hrc/TaskStatus: how it ended,
and the robot's selector, policy and type belief from the POMDP process's report) and prints
one line (``task 3/5 (...): success (robot) in 12 steps, 21.4 s, utility 0.77; policy
policy3; belief: ...``).

Topics: /hrc/status (ros_hrc/Status), one message per step; /hrc/task_status
(ros_hrc/TaskStatus), one message per task of a sequence.
Services offered: /hrc/reset (std_srvs/Trigger: reset everything and wait until it is done),
/hrc/set_human_state (ros_hrc/SetHumanState: the human's next state, for manual mode without
a terminal), /hrc/configure (std_srvs/Trigger: start again from the launch's resolved
settings as they are now, which an experiment worker rewrote for its next cell: both solver
processes rebuild from them (``configure``) and a fresh coordinator starts with a reset, as a
new launch would; :meth:`HumanNode.configure`, docs/experiments.md, "Warm stacks").
Parameters: ~task (the collaboration task, ros_hrc.tasks: seed or fabric), ~seed (the run's
seed: the task's observation noise draws from its (seed, episode) streams), ~host,
~human_port (this node's server, for the MDP), ~pomdp_port (the POMDP process's server),
~mode, ~max_steps, ~on_episode_end,
~end_on_goal, ~episodes (the episode numbers to play, e.g. ``0-99`` or ``2,5-7``; ``live``: 1,
2, 3 ...: see :mod:`ros_hrc.streams`), ~wait_for_listener (no step before someone
subscribes to /hrc/status), ~read_stdin (Enter on this node's terminal resets everything), ~print_steps,
~service_timeout (s to wait for a service that went away during the run; at start-up the
node waits however long it takes), ~wait_report_every (s between the lines saying what the
start-up still waits for), ~decide_timeout (s to wait for the POMDP process's decision), ~planner_reset_timeout (s to wait for its answer to a
reset, which takes no planning), ~reset_timeout (s /hrc/reset waits for the reset),
~reply_timeout (s to wait for the MDP's answer to a next state),
~reset_join_window, ~wait_note_every, ~world_call_timeout (see CoordinatorConfig; the values
of all of them are in docs/loop.md, "Timeouts"), ~tasks (a sequence's length; empty: none),
and from the launch's resolved configuration /hrc/config: schedule, task_timeout and
human_model (who plays a sequence's tasks without a schedule),
~link_session (hrc.launch's session: the link token's file) or ~token_file (by hand).
"""
from __future__ import annotations

import itertools
import os
import sys
import threading
from dataclasses import dataclass, fields, replace
from typing import Dict, Mapping, Optional, TextIO, Tuple

import rospy
from std_srvs.srv import Trigger, TriggerResponse

from ros_hrc.command_line import print_whole_lines
from ros_hrc.errors import HrcError, LinkError
from ros_hrc.link.protocol import (ERR_SEAT_TAKEN, MAX_STATE_INDEX, Ack, Configure,
                                   DispatchTable, Error, Message, MessageError, NextState,
                                   Reaction, Reset, Step, reply_error)
from ros_hrc.link.token import launch_token, read_session_settings
from ros_hrc.link.transport import MessageClient, MessageServer, Peer, link_url
from ros_hrc import settings, tasks
from ros_hrc.loop.coordinator import (EPISODE_OVER, RESET_JOIN_WINDOW, WAIT_NOTE_EVERY,
                                      WORLD_CALL_TIMEOUT, Coordinator, CoordinatorConfig)
from ros_hrc.loop.display import (STEP_BLOCK_TYPES, action_values_text, belief_text,
                                  learnt_text, task_line)
from ros_hrc.pomdp.type_names import ranked_types
from ros_hrc.loop.effects import (DECISION_IN_REPORT, ReactionRequest, STEP_TIMINGS, StepReport,
                                  StepRequest, TaskStatusReport)
from ros_hrc.loop.runner import LoopRunner, ReportPort
from ros_hrc.streams import EpisodeSchedule
from ros_hrc.model_files import model_names
from ros_hrc.msg import Status, TaskStatus
from ros_hrc.nodes.common import (ServiceWait, TriggerCaller, init_node, parameter, read_config,
                                  registered_services, route_python_logging)
from ros_hrc.tasks.schedule import parse_schedule
from ros_hrc.tasks.utility import sim_span
from ros_hrc.nodes.loop_ports import LinkMdp, LinkPlanner, RosExecutor, RosWorld
from ros_hrc.srv import SetHumanState, SetHumanStateResponse


@dataclass
class HumanNodeConfig:
    """The node's parameters (read_config); a launch setting's default is the table's."""
    task: str = settings.default("task")
    seed: int = settings.default("seed")
    host: str = settings.default("host")
    human_port: int = settings.default("human_port")
    pomdp_port: int = settings.default("pomdp_port")
    link_read_timeout: float = settings.default("link_read_timeout")
    mode: str = settings.default("mode")
    max_steps: int = settings.default("max_steps")
    on_episode_end: str = settings.default("on_episode_end")
    # the episode numbers to play (EpisodeSchedule text; live: 1, 2, ...)
    episodes: str = settings.default("episodes")
    # no step before someone subscribes to /hrc/status
    wait_for_listener: bool = settings.default("wait_for_listener")
    end_on_goal: bool = settings.default("end_on_goal")
    read_stdin: bool = True
    print_steps: bool = True
    service_timeout: float = 30.0
    wait_report_every: float = 10.0
    decide_timeout: float = 120.0
    planner_reset_timeout: float = 10.0
    reset_timeout: float = 120.0
    reply_timeout: float = 10.0
    reset_join_window: float = RESET_JOIN_WINDOW
    wait_note_every: float = WAIT_NOTE_EVERY
    world_call_timeout: float = WORLD_CALL_TIMEOUT
    link_session: str = ""      # hrc.launch's session: where the link token is
    token_file: str = ""        # or the token's file, for a node started by hand
    # a sequence of tasks (empty: none); its schedule, timeout and default human are the
    # launch's resolved settings (a schedule file's path made absolute where it was typed)
    tasks: Optional[int] = settings.default("tasks")
    schedule: str = parameter(settings.default("schedule"), "/hrc/config/schedule")
    task_timeout: Optional[float] = parameter(settings.default("task_timeout"),
                                              "/hrc/config/task_timeout")
    sequence_human: str = parameter("", "/hrc/config/human_model")


def configured(config: HumanNodeConfig, launch: Mapping[str, object]) -> HumanNodeConfig:
    """``config`` with the launch's resolved settings ``launch`` in place of those a running
    loop takes in place (:data:`ros_hrc.settings.IN_PLACE`: the seed, the episodes, a
    sequence's length and schedule...); the human who plays a sequence is the launch's
    ``human_model``, as /hrc/config gives it at start."""
    changes = {f.name: launch[f.name] for f in fields(config)
               if f.name in settings.IN_PLACE and f.name in launch}
    if "human_model" in launch:
        changes["sequence_human"] = launch["human_model"]
    return replace(config, **changes)


def world_services(task: tasks.Task) -> Tuple[str, ...]:
    """The world's services the loop calls for ``task``: its reset, its snapshot, every
    /human/* service of the task's human actions and every /robot/* service of its robot's."""
    return ("/hrc/world/reset", "/hrc/world/state") + tuple(
        f"/human/{service}" for service in task.human_world_services()) + tuple(
        f"/robot/{service}" for service in task.robot_world_services())


def startup_services(task: tasks.Task, planner_url: str
                     ) -> Tuple[Tuple[str, Tuple[str, ...]], ...]:
    """What the loop calls, by who offers it: the node waits for all of them before the
    first reset (the POMDP process is named by the URL of its link, ``planner_url``, which
    counts as up once this node is connected to it)."""
    return (("the world (hrc_world)", world_services(task)),
            ("the robot planner (despot_pomdp)", (planner_url,)))


#: The seed task's (the default's) on the default ports: what the node waits for before the
#: first reset.
WORLD_SERVICES = world_services(tasks.get(tasks.DEFAULT_TASK))
PLANNER_LINK = link_url(settings.default("pomdp_port"))
STARTUP_SERVICES = startup_services(tasks.get(tasks.DEFAULT_TASK), PLANNER_LINK)
#: Stands in the start-up wait for "someone subscribes to /hrc/status" (~wait_for_listener).
STATUS_LISTENER = "/hrc/status (subscribed)"


# -- what the terminal shows ----------------------------------------------------------------------

def format_step(status: Status, task: Optional[tasks.Task] = None) -> str:
    """The block the ROS terminal prints for one step (``task``: whose bits the robot's
    observation shows; the default task's when not given)."""
    task = task or tasks.get(tasks.DEFAULT_TASK)
    lines = [f"------------------------------ step {status.step} ------------------------------",
             f"human action      : {status.human_action}"]
    if status.fault and not status.robot_observation:
        lines += [f"human state       : {status.human_state} ({status.human_state_index})",
                  f"STEP FAILED       : {status.fault}"]
        return "\n".join(lines)
    bits = status.observation_bits
    belief = belief_text(status.belief_states, status.belief)
    lines += [
        f"human observation : {status.human_observation}",
        f"robot observation : {status.robot_observation} ({task.describe_bits(bits)})",
        f"human state       : {status.human_state} ({status.human_state_index})",
        f"robot state       : {status.robot_state}",
        # A sequence's task starts: the policy its selector chose, shown once, at step 0.
        *([f"robot policy      : {status.policy} (decides this task)"]
          if status.policy and status.step == 0 else []),
        f"robot action      : {status.robot_action or '-'}",
        f"robot belief      : {belief or '-'}",
    ]
    if status.robot_failed and status.robot_result:   # why (a grasp out of reach: how far)
        lines.insert(-1, f"robot failed      : {status.robot_result}")
    values = action_values_text(status)
    if values:   # why the robot chose its action (a baseline robot sends no values)
        lines.insert(-1, f"robot values      : {values}")
    if status.type_names:   # a robot model of human types: whom it believes it works with
        lines.append(f"robot types       : "
                     f"{ranked_types(status.type_names, status.type_belief, STEP_BLOCK_TYPES)}")
    if status.learnt_name:   # a learning robot: what it has learnt of this human so far
        lines.append(f"robot learnt      : {status.learnt_name} = {learnt_text(status)}")
    if status.fault:
        lines.append(f"STEP FAILED       : {status.fault}")
    else:
        lines.append(f"object            : {object_text(status)} (t = "
                     f"{episode_time(status):.2f} s simulated since the episode's start)")
    if status.episode_over:
        lines.append(f"episode           : {status.episode} over ({status.end_reason})")
    return "\n".join(lines)


def episode_time(status: Status) -> float:
    """The step's simulated time counted from its episode's start (the message keeps the
    world's raw ``sim_time``, which counts from the launch)."""
    return sim_span(status.episode_start_time, status.sim_time)


def object_text(status: Status) -> str:
    if status.object_holder in ("human", "robot"):
        return f"held by the {status.object_holder}"
    return "missed: it left the belt" if status.object_left_belt else "on the belt"


def task_status_message(report: TaskStatusReport) -> TaskStatus:
    """The coordinator's report of a finished task as ``ros_hrc/TaskStatus``."""
    status = TaskStatus()
    status.header.stamp = rospy.Time.now()
    for name in TaskStatus.__slots__[1:]:
        value = getattr(report, name)
        setattr(status, name, list(value) if isinstance(value, tuple) else value)
    return status


def status_message(report: StepReport, mode: str) -> Status:
    """The coordinator's step report as ``ros_hrc/Status``."""
    status = Status()
    status.header.stamp = rospy.Time.now()
    status.mode = mode
    for name in ("epoch", "episode", "step", "human_action", "human_state", "human_state_index",
                 "human_reward", "human_observation", "observation_bits", "robot_observation",
                 "robot_state", "sim_time", "object_holder", "object_left_belt",
                 "episode_start_time", "human_result", "robot_result", "episode_over",
                 "end_reason", "fault"):
        setattr(status, name, getattr(report, name))
    status.robot_failed = not report.robot_acted
    for name in DECISION_IN_REPORT.values():   # the planner's decision, as declared
        value = getattr(report, name)
        setattr(status, name, list(value) if isinstance(value, tuple) else value)
    for part in STEP_TIMINGS:
        setattr(status, f"{part}_ms", report.timings_ms.get(part, 0.0))
    return status


# -- the four adapters ------------------------------------------------------------------------

class Terminal(ReportPort):
    """Steps to the terminal and /hrc/status; the coordinator's lines to rosout."""

    def __init__(self, publisher: rospy.Publisher, mode: str, print_steps: bool,
                 task: Optional[tasks.Task] = None,
                 task_publisher: Optional[rospy.Publisher] = None) -> None:
        self.publisher = publisher
        self.mode = mode
        self.print_steps = print_steps
        self.task = task
        self.task_publisher = task_publisher

    def task_ended(self, report: TaskStatusReport) -> None:
        """A task of the sequence ended: /hrc/task_status and one line."""
        status = task_status_message(report)
        if self.task_publisher is not None:
            self.task_publisher.publish(status)
        rospy.loginfo("hrc_human: %s", task_line(status))

    def step(self, report: StepReport) -> None:
        status = status_message(report, self.mode)
        self.publisher.publish(status)
        if self.print_steps:
            text = format_step(status, self.task)
            if report.reaction:
                text += f"\nhuman reaction    : {report.reaction} (to the robot's action)"
            if report.observation_noise:
                text += f"\nobservation noise : {report.observation_noise}"
            print(text, flush=True)

    def note(self, level: str, text: str) -> None:
        if text.startswith("RESET"):
            print(f"=============== {text} ===============", flush=True)
            return
        {"error": rospy.logerr, "warn": rospy.logwarn, "debug": rospy.logdebug}.get(
            level, rospy.loginfo)("hrc_human: %s", text)


# -- this node's terminal ---------------------------------------------------------------------

RESET = "reset"


def typed_line(line: str, mode: str) -> Tuple[str, Optional[int]]:
    """What a line typed on this node's terminal asks for: ``("reset", None)``, or in manual
    mode ``("state", n)`` for a line that is not empty: the human's next state (``None``: the
    model chooses, for a negative number or anything that is not a number, as the MDP's
    prompt reads it). In auto mode every line is Enter."""
    text = line.strip()
    if mode != "manual" or not text:
        return RESET, None
    try:
        value = int(text)
    except ValueError:
        return "state", None
    return "state", (value if value >= 0 else None)


def input_ended_line(mode: str, tty: bool) -> str:
    """What this node says when its standard input ends."""
    how = "Ctrl-D" if tty else "standard input closed"
    line = (f"hrc_human: input ended ({how}): Enter here no longer resets; "
            "`rosservice call /hrc/reset` still does")
    if mode == "manual":
        line += (", and `rosservice call /hrc/set_human_state N` gives the human's next state "
                 "(typed states here no longer reach the MDP)")
    return line


# -- the node ---------------------------------------------------------------------------------

class HumanNode:
    """The coordinator, its runner and the adapters."""

    def __init__(self, config: HumanNodeConfig) -> None:
        self.config = config
        self.task = tasks.get(config.task)
        self.call = TriggerCaller(config.service_timeout)
        # No call reaches the world or the planner before their services are up: the first
        # reset (and so the MDP's step 0) waits, however long the world takes to start.
        self.status_pub = rospy.Publisher("/hrc/status", Status, queue_size=100)
        # latched: the last task's status is there for whoever subscribes after it ended
        self.task_pub = rospy.Publisher("/hrc/task_status", TaskStatus, queue_size=100,
                                        latch=True)
        token = launch_token(config)
        self.pomdp = MessageClient(link_url(config.pomdp_port, config.host), "hrc_human",
                                   send_timeout=config.decide_timeout, token=token)
        awaited = startup_services(self.task, self.pomdp.url)
        if config.wait_for_listener:
            # An experiment cell records every step: none is taken before it listens.
            awaited += (("a listener (wait_for_listener)", (STATUS_LISTENER,)),)
        self.startup = ServiceWait(awaited, say=lambda text: rospy.loginfo(
            "hrc_human: %s", text), every=config.wait_report_every, registered=self._up)
        self.runner = self._new_runner(config)
        self._configuring = threading.Lock()    # one /hrc/configure at a time
        table = DispatchTable("hrc_human")
        table.on(Step, self._on_step)
        table.on(Reaction, self._on_reaction)
        table.on(Reset, self._on_reset)
        table.on(Ack, self._on_answer)
        table.on(Error, self._on_answer)
        self.server = MessageServer(config.human_port, table, host=config.host,
                                    name="hrc_human", on_connect=self._mdp_came,
                                    on_disconnect=self._mdp_left,
                                    read_timeout=config.link_read_timeout, token=token)
        self._next_state_ids = itertools.count(1)   # correlation ids of next_state requests
        self._answers: Dict[int, Message] = {}
        self._answered = threading.Condition()

    def _new_runner(self, config: HumanNodeConfig) -> LoopRunner:
        """A fresh coordinator for ``config`` and the runner that carries out what it asks,
        as at this node's start. Raises HrcError or ValueError (a bad schedule)."""
        human = config.sequence_human or self.task.default_model("human")
        schedule = parse_schedule(config.schedule, model_names(self.task.model_dirs["human"]),
                                  human, self.task.name) if config.tasks else None
        # A random first epoch: a respawned (or reconfigured) loop never mints an epoch its
        # predecessor used.
        first_epoch = int.from_bytes(os.urandom(3), "big") << 4
        coordinator = Coordinator(CoordinatorConfig(
            max_steps=config.max_steps, end_on_goal=config.end_on_goal,
            on_episode_end=config.on_episode_end, first_epoch=first_epoch,
            reset_join_window=config.reset_join_window,
            wait_note_every=config.wait_note_every,
            world_call_timeout=config.world_call_timeout,
            episodes=EpisodeSchedule.parse(config.episodes), task=self.task,
            seed=config.seed, human_model=human if config.tasks else "",
            tasks=config.tasks or 0, schedule=schedule,
            task_timeout=config.task_timeout))
        planner = LinkPlanner(self.pomdp, config.decide_timeout, config.planner_reset_timeout,
                              self.startup.wait)
        executor = RosExecutor(self.call, self.task.robot_action_services, self.startup.wait)
        world = RosWorld(self.call, self.startup.wait, seed=config.seed)
        return LoopRunner(coordinator, world, planner, executor, LinkMdp(),
                          Terminal(self.status_pub, config.mode, config.print_steps, self.task,
                                   self.task_pub))

    def configure(self) -> Tuple[bool, str]:
        """Start again from the launch's settings as they are now (``/hrc/configure``: a warm
        stack's next cell; the experiment worker rewrote them): the loop stops, both solver
        processes read them again and start afresh (``configure``), and a fresh coordinator
        on the new settings starts with a reset, its world reseeded on the new seed, as a
        newly started stack would. (success, what was done or why not). A settings change
        that needs a new launch (:data:`ros_hrc.settings.IN_PLACE`) is refused before
        anything stops; a solver that refuses leaves the loop stopped (the stack is then
        replaced)."""
        with self._configuring:
            if not self.config.link_session:
                return False, "this node was not started by a launch: no settings to read"
            try:
                launch = read_session_settings(self.config.link_session)
                config = configured(self.config, launch)
                moved = [name for name in ("task", "host", "human_port", "pomdp_port", "mode")
                         if getattr(config, name) != getattr(self.config, name)]
                if moved:
                    return False, (f"{', '.join(moved)} changed: only a new launch takes "
                                   f"{'it' if len(moved) == 1 else 'them'}")
                runner = self._new_runner(config)
            except (HrcError, ValueError) as exc:
                return False, f"not configured: {exc}"
            self.runner.stop()
            said = []
            for who, ask in (("despot_pomdp", self._configure_pomdp),
                             ("despot_mdp", self._configure_mdp)):
                ok, text = ask()
                if not ok:
                    return False, f"{who} did not take the settings: {text}"
                said.append(text)
            seat = self.server_seat()
            self.config, self.runner = config, runner
            runner.start()
            if seat is not None:
                runner.mdp_connected(seat)
            return True, "configured: " + "; ".join(said)

    def server_seat(self) -> Optional[Peer]:
        """The MDP process the stopped loop served (the new loop serves it again)."""
        return self.runner.coordinator.seat

    def _configure_pomdp(self) -> Tuple[bool, str]:
        try:
            reply = self.pomdp.request(Configure(reason="/hrc/configure called"),
                                       self.config.reset_timeout)
        except LinkError as exc:
            return False, str(exc)
        if isinstance(reply, Ack):
            return True, reply.result or "configured"
        return False, getattr(reply, "message", f"answered a {reply.type}")

    def _configure_mdp(self) -> Tuple[bool, str]:
        seat = self.server_seat()
        if seat is None:
            return False, "no MDP process is connected"
        request_id = next(self._next_state_ids)
        return self._ask_mdp(seat, Configure(reason="/hrc/configure called", id=request_id),
                             self.config.reset_timeout, "configured")

    def _ask_mdp(self, seat: Peer, message: Message, timeout: float, done: str
                 ) -> Tuple[bool, str]:
        """Send the served MDP ``message`` (a request: it has an id) and wait up to
        ``timeout`` s for its answer: (success, what it answered, or ``done``)."""
        if not seat.send(message):
            return False, "the MDP process is gone"
        with self._answered:
            self._answered.wait_for(lambda: message.id in self._answers, timeout)
            answer = self._answers.pop(message.id, None)
        if answer is None:
            return False, "the MDP process did not answer"
        if isinstance(answer, Error):
            return False, answer.message
        return True, answer.result or done

    def configure_service(self, _req) -> TriggerResponse:
        ok, text = self.configure()
        return TriggerResponse(success=ok, message=text)

    def _up(self) -> set:
        """What the start-up wait finds up now: the services registered, the POMDP process's
        link once connected, and (~wait_for_listener) a listener of /hrc/status."""
        up = registered_services()
        if self.pomdp.connected:
            up.add(self.pomdp.url)
        if self.config.wait_for_listener and self.status_pub.get_num_connections():
            up.add(STATUS_LISTENER)
        return up

    def start(self) -> None:
        threading.Thread(target=self.startup.run, name="startup-wait", daemon=True).start()
        self.runner.start()
        self.pomdp.start()
        self.server.start()

    def stop(self) -> None:
        """The node ends (rospy's shutdown: Ctrl-C, the launch stopping): the loop first,
        so that what the other processes do as they end with it (the MDP leaving, the
        planner going away, the world shutting down) is no news: no line, no step, no
        reset."""
        self.runner.stop()
        self.startup.stop()
        self.server.stop()
        self.pomdp.close()
        self.call.close()

    def _mdp_came(self, peer: Peer) -> None:
        self.runner.mdp_connected(peer)     # the runner of now (a configure replaces it)

    def _mdp_left(self, peer: Peer) -> None:
        self.runner.mdp_disconnected(peer, stopped=peer.stopped)

    # -- the MDP's messages -------------------------------------------------------------------
    def _on_step(self, msg: Step, peer: Peer) -> None:
        self.runner.step_requested(peer, StepRequest(
            epoch=msg.epoch, step=msg.step, action=msg.action, state=msg.state,
            reward=msg.reward or 0.0, reply=msg.id))

    def _on_reaction(self, msg: Reaction, peer: Peer) -> None:
        self.runner.reaction_received(peer, ReactionRequest(
            epoch=msg.epoch, step=msg.step, state=msg.state, rule=msg.rule or "",
            reward=msg.reward or 0.0, manual=bool(msg.manual), reply=msg.id))

    def _on_reset(self, msg: Reset, peer: Peer) -> Message:
        if peer is not self.runner.coordinator.seat:
            return reply_error(msg, "only the served MDP process may reset the loop on this "
                                    "port (anyone may call /hrc/reset)", ERR_SEAT_TAKEN)
        self.runner.request_reset(f"asked by {peer.who}: {msg.reason or 'reset'}")
        return Ack(step=0, of=Reset.TYPE, result="reset requested", reply_to=msg.id)

    def _on_answer(self, msg: Message, peer: Peer) -> None:
        # The MDP's answers to next_state requests, matched by correlation id.
        if msg.reply_to is None:
            return None
        with self._answered:
            self._answers[msg.reply_to] = msg
            self._answered.notify_all()
        return None

    # -- services -------------------------------------------------------------------------------
    def reset_service(self, _req) -> TriggerResponse:
        ok, text = self.runner.reset("/hrc/reset called", self.config.reset_timeout)
        if not ok and not self.startup.ready:
            text += f" ({self.startup.describe()}; the reset is done once they are up)"
        return TriggerResponse(success=ok, message=text)

    def set_human_state(self, req) -> SetHumanStateResponse:
        ok, text = self.send_next_state(None if req.state < 0 else int(req.state))
        return SetHumanStateResponse(success=ok, message=text)

    def send_next_state(self, state: Optional[int]) -> Tuple[bool, str]:
        """Give the served MDP its next state (None: the model chooses): (success, what the
        MDP answered)."""
        coordinator = self.runner.coordinator
        seat = coordinator.seat
        if seat is None:
            return False, "no MDP process is connected"
        if coordinator.phase == EPISODE_OVER:
            # The MDP takes no step before the next reset, and a reset starts its episode
            # afresh: a state given now would be acknowledged and then dropped.
            return False, (f"episode {coordinator.episode} is over: no next state until the "
                           "next episode; reset first (Enter in the roslaunch terminal or "
                           "`rosservice call /hrc/reset`), then give the state")
        request_id = next(self._next_state_ids)
        try:
            message = NextState(state=state, id=request_id)
        except MessageError:   # a number no model has (the field is at most MAX_STATE_INDEX)
            return False, (f"no human state {state}: states are numbered from 0 to at most "
                           f"{MAX_STATE_INDEX}; a negative number lets the model choose")
        return self._ask_mdp(seat, message, self.config.reply_timeout, "next state queued")

    def read_enter(self, stream: Optional[TextIO] = None) -> None:
        """Enter on this node's terminal resets everything; in manual mode a typed state goes
        to the MDP (:func:`typed_line`). Says so when the input ends."""
        stream = sys.stdin if stream is None else stream
        for line in stream:
            if rospy.is_shutdown():
                return
            what, state = typed_line(line, self.config.mode)
            if what == RESET:
                self.runner.request_reset("Enter pressed")
                continue
            ok, text = self.send_next_state(state)
            typed = line.strip()
            if ok:
                print(f"hrc_human: typed {typed!r}: {text}", flush=True)
            else:
                print(f"hrc_human: typed {typed!r} did not reach the MDP: {text} (Enter alone "
                      "resets everything)", flush=True)
        if not rospy.is_shutdown():
            print(input_ended_line(self.config.mode, _isatty(stream)), flush=True)


def _isatty(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError, OSError):
        return False


def main() -> None:
    print_whole_lines()    # its step block, whole, in the terminal it shares
    init_node("hrc_human")
    route_python_logging()
    try:
        node = HumanNode(read_config(HumanNodeConfig))
        node.start()
    except (HrcError, ValueError) as exc:   # (a ScheduleError is a ValueError)
        rospy.logfatal("hrc_human cannot start: %s", exc)
        raise SystemExit(2) from None
    rospy.on_shutdown(node.stop)
    rospy.Service("/hrc/reset", Trigger, node.reset_service)
    rospy.Service("/hrc/configure", Trigger, node.configure_service)
    rospy.Service("/hrc/set_human_state", SetHumanState, node.set_human_state)
    if node.config.read_stdin and sys.stdin is not None and not sys.stdin.closed:
        threading.Thread(target=node.read_enter, name="enter-resets", daemon=True).start()
        if node.config.mode == "manual":
            print("hrc_human: press Enter in this terminal to reset the whole scenario; a state "
                  "typed here (a number, then Enter) is the human's next state, as "
                  "/hrc/set_human_state gives it", flush=True)
        else:
            print("hrc_human: press Enter in this terminal to reset the whole scenario",
                  flush=True)
    rospy.loginfo("hrc_human: waiting for the MDP process on %s", node.server.url)
    rospy.spin()
