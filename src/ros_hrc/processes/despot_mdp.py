"""despot_mdp: the simulated human's process (no ROS; it speaks only websocket).

It loads a human MDP (checked against the states and actions of the task, ``--task``:
:mod:`ros_hrc.tasks`), and is a client of the human node (``ws://127.0.0.1:9090``), where
the loop's coordinator serves one MDP at a time (a second one is refused: this process then
says so and exits with status 3). Each episode
starts with the coordinator's ``reset`` (its epoch and number). Each step it picks the
human's action, decides the next state (sampled from the model in ``auto`` mode; asked in
``manual`` mode, as the seed's MDP terminal does), sends a ``step`` message, and waits for its
answer (which carries the robot's action) before the next.

**A human who hears the robot** (a task with reaction rules: ``fabric``): the step carries the
state he acts in (for a grasp its outcome, drawn before the robot acts); the step's answer
(``ack``) carries the robot's action, and from it, and the step's end if it ended the task,
the task's rules give his next state, which he sends back (``reaction``): it completes the
step, whose report (``/hrc/status``) shows it. The terminal prints the robot's action and the rule
applied (``- Robot answered: grasp ...`` / ``- Reaction: the robot grasped:
RobotInterfered``). In manual mode the prompt comes then, after the robot acted: the typed
state is his next state (the rules are not applied); anything else lets them choose.

Manual mode asks ``Please enter the next state [integer from 0 to 7, press any non-int key
for autogen]``: an integer gives that state (with ``--manual-share`` of the belief), anything
else lets the model choose. The answer can also come as a ``next_state`` message (the
``/hrc/set_human_state`` service of the human node, or a state typed on the human node's
terminal), so no terminal of its own is needed: without one (``hrc.launch`` gives it an
xterm only when there is a display) it says so once, in one line, and each prompt says where
to answer. When its input ends (Ctrl-D at the prompt) it says so and goes on in auto mode:
the model chooses every next state from then on; restart it to type states again.

A ``reset`` message (Enter in the ROS terminal, ``/hrc/reset``, the end of an episode, a
recovery) puts the human back to its initial state, step 0, zero reward, and restarts its
random stream as the one of (``--seed``, the reset's episode, "human")
(:mod:`ros_hrc.streams`): episode e of seed s is the same human whatever ran before it,
and no two episodes share a stream.

**A sequence of tasks** (``tasks:=N``; docs/sequences.md): each task's ``reset`` names the
human model that plays it (``human_model``), and a model it drifts to with its weight
(``drift_to``, ``drift``). The process loads each model once, checked against the task, and
the agent plays the task with the two models' rows mixed
(:meth:`~ros_hrc.agents.human.HumanAgent.play`). A reset that names none keeps the model
it plays.

A ``configure`` (a warm stack's next cell: ``/hrc/configure`` of the human node) makes it read
the launch's settings again and rebuild the human model and agent as at start, with no epoch;
it then waits for the reset that starts the cell's first episode.

The human node takes only processes of its own launch: this one proves the launch's link token
in its hello (``--link-session``, given by hrc.launch; by hand ``--token-file PATH`` or
``HRC_LINK_TOKEN_FILE``; :mod:`ros_hrc.link.token`). Under hrc.launch its options are the
launch's resolved settings, which the pre-flight wrote beside the token (every path absolute);
an option on its command line wins (:func:`ros_hrc.command_line.parse_launch_options`). A
relative ``--model`` given by hand is taken from the directory it runs in.
"""
from __future__ import annotations

import argparse
import itertools
import os
import queue
import sys
import threading
import time
from typing import Dict, Optional, Sequence, TextIO, Tuple

from ros_hrc import tasks
from ros_hrc.command_line import ranged_number, reread_launch_options
from ros_hrc.errors import HrcError, LinkError
from ros_hrc.link.protocol import (ERR_INVALID, ERR_REFUSED, Ack, Configure, Error, Message,
                                   NextState, Reaction, Reset, Step, is_reply_to, reply_error)
from ros_hrc.link.transport import LinkClosed, MessageClient, link_url
from ros_hrc import settings
from ros_hrc.models import load_human_model, positional_mapping_line
from ros_hrc.pomdp.model import Model
from ros_hrc.streams import next_episode, stream_seed
from ros_hrc.agents.human import HumanAgent, HumanAgentConfig
from ros_hrc.processes.solver_process import CANNOT_START, solver_parser, start_solver

NAME = "despot_mdp"


class _ResetRequested(Exception):
    """A reset arrived while the loop was waiting for something else."""

    def __init__(self, reset: Reset) -> None:
        super().__init__(reset.reason or "reset")
        self.reset = reset


class _ConfigureRequested(Exception):
    """A configure arrived (a warm stack's next cell): the loop starts from the launch's
    settings again."""

    def __init__(self, configure: Configure) -> None:
        super().__init__(configure.reason or "configure")
        self.configure = configure


class SeatRefused(HrcError):
    """The human node serves another MDP process: this one is refused."""


class MdpProcess:
    """The human's side of the loop: choose, (ask,) step, wait for the answer, print.

    The coordinator (in the human node) owns the loop: it starts each episode with a
    ``reset`` naming the epoch and the episode, answers each step with an ``ack`` (the robot's
    action; ``episode_over``: wait for the next reset) or an ``error`` (the step was not
    carried out: wait for the reset that follows), and ends episodes. This process keeps only
    the human's own state: the MDP agent."""

    def __init__(self, agent: HumanAgent, client: MessageClient, args: argparse.Namespace,
                 out: TextIO = sys.stdout, argv: Optional[Sequence[str]] = None) -> None:
        self.agent = agent
        self.client = client
        self.args = args
        self.argv = argv     # its command line: a configure reads the launch's settings again
        self.out = out
        self.epoch: Optional[int] = None
        self.episode = 0
        self._ids = itertools.count(1)
        self._events: "queue.Queue[Tuple[str, object]]" = queue.Queue()
        self._next_states: "queue.Queue[Tuple[Optional[int], str]]" = queue.Queue()
        self._stop = threading.Event()
        self.state_var = agent.model.meta.get("state_var", "state_1")
        #: auto or manual; manual becomes auto when the terminal's input ends (Ctrl-D).
        self.mode = args.mode
        self.reads_terminal = False
        #: Why no state is taken now (the episode is over, or a refused step waits for its
        #: reset): a state given meanwhile would be dropped by the reset, so it is refused.
        self._no_states = ""
        self._states_lock = threading.Lock()   # _no_states vs. the states queued
        #: The human models a sequence's resets named, loaded once each (by name or path).
        self.models: Dict[str, Model] = {}
        self.task_index: Optional[int] = None   # the sequence's task under way (None: none)

    # -- input: the link and the terminal ------------------------------------------------------
    def start_threads(self, read_stdin: bool, stdin: Optional[TextIO] = None) -> None:
        """Read the link; in manual mode also the terminal (``read_stdin``), or else say
        once where the states come from."""
        threading.Thread(target=self._dispatch_link, name="mdp-link", daemon=True).start()
        if self.mode != "manual":
            return
        if read_stdin:
            self.reads_terminal = True
            stream = sys.stdin if stdin is None else stdin
            threading.Thread(target=self._read_terminal, args=(stream,), name="mdp-stdin",
                             daemon=True).start()
        else:
            self.print(no_terminal_line(bool(os.environ.get("DISPLAY"))))

    def _dispatch_link(self) -> None:
        while not self._stop.is_set():
            try:
                msg = self.client.receive()
            except LinkClosed:
                return
            if isinstance(msg, Reset):
                self._events.put(("reset", msg))
            elif isinstance(msg, Configure):
                self._events.put(("configure", msg))
            elif isinstance(msg, NextState):
                self._take_next_state(msg)
            elif isinstance(msg, Error) and msg.code == "seat_taken":
                self._events.put(("refused", msg))
            else:
                self._events.put(("reply", msg))

    def _take_next_state(self, msg: NextState) -> None:
        n = self.agent.model.n_states
        if msg.state is not None and not 0 <= msg.state < n:
            self._send(reply_error(msg, f"state must be an integer from 0 to {n - 1}, "
                                        f"not {msg.state}", ERR_INVALID))
            return
        if self.mode != "manual":
            why = ("its input ended (Ctrl-D), so it" if self.args.mode == "manual"
                   else "start it with mode:=manual; it")
            self._send(reply_error(msg, f"the MDP runs in auto mode ({why} chooses every next "
                                        "state itself)", ERR_INVALID))
            return
        with self._states_lock:
            refused = self._no_states
            if not refused:
                self._next_states.put((msg.state, "message"))
        if refused:
            self._send(reply_error(msg, refused, ERR_REFUSED))
            return
        self._events.put(("next_state", None))
        name = "autogen" if msg.state is None else self.agent.model.states[msg.state]
        self._send(Ack(step=self.agent.step, of=msg.type, result=f"next state: {name}",
                       reply_to=msg.id))

    def _read_terminal(self, stream: TextIO) -> None:
        for line in stream:
            with self._states_lock:
                refused = self._no_states
                if not refused:
                    self._next_states.put((self._parse_typed(line.strip()), "terminal"))
            if refused:
                self.print(f"{NAME}: {line.strip()!r} is not used: {refused}")
                continue
            self._events.put(("next_state", None))
        if self._stop.is_set():
            return
        # The input ended (Ctrl-D at the prompt, or a closed pipe): never silently. The MDP
        # goes on in auto mode; a prompt waiting now is answered by the model. The line is
        # printed before the mode changes, so the prompt's "State is generated by the model"
        # follows it (a CI run printed them the other way round).
        self.print(input_ended_line(_isatty(stream)))
        self.mode = "auto"
        self._events.put(("next_state", None))

    def _parse_typed(self, text: str) -> Optional[int]:
        try:
            return int(text)
        except ValueError:
            return None

    def print(self, text: str = "") -> None:
        print(text, file=self.out, flush=True)

    # -- waiting ----------------------------------------------------------------------------
    def _wait_event(self, wanted: str, timeout: Optional[float] = None):
        """The next event of kind ``wanted`` (None after ``timeout``); raises _ResetRequested
        on a reset and SeatRefused when the human node serves another MDP."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            try:
                kind, payload = self._events.get(timeout=left)
            except queue.Empty:
                return None
            if kind == "reset":
                raise _ResetRequested(payload)
            if kind == "configure":
                raise _ConfigureRequested(payload)
            if kind == "refused":
                raise SeatRefused(payload.message)
            if kind == wanted:
                return payload

    def _ask_next_state(self) -> Optional[int]:
        n = self.agent.model.n_states
        while True:
            self.print(f"\nPlease enter the next state [integer from 0 to {n - 1}, "
                       "press any non-int key for autogen]: ")
            if not self.reads_terminal:
                self.print("(this MDP reads no terminal: type the state in the roslaunch "
                           "terminal, or `rosservice call /hrc/set_human_state N`)")
            while True:
                try:
                    value, source = self._next_states.get_nowait()
                    break
                except queue.Empty:
                    if self.mode != "manual":   # the input ended while asking
                        value, source = None, "ended"
                        break
                    self._wait_event("next_state")
            if value is None:
                self.print("State is generated by the model")
                return None
            if 0 <= value < n:
                self.print(f"State is manually entered: {value}"
                           + (" (through hrc_human: its terminal or /hrc/set_human_state)"
                              if source == "message" else ""))
                return value
            self.print(f"{value} is not a state: enter an integer from 0 to {n - 1}")

    def _wait_reply(self, step: Step) -> Optional[Message]:
        """The answer to ``step`` (matched by its correlation id), or None after the reply
        timeout."""
        deadline = time.monotonic() + self.args.reply_timeout
        while True:
            reply = self._wait_event("reply", max(0.0, deadline - time.monotonic()))
            if reply is None or is_reply_to(reply, step):
                return reply

    # -- the loop ---------------------------------------------------------------------------
    def start_episode(self, reset: Reset) -> None:
        """A new episode, as the coordinator's reset says: its epoch and number."""
        with self._states_lock:
            if self.epoch is not None:
                # States typed for the episode that ended are not for this one (before the
                # first episode, they are).
                while not self._next_states.empty():
                    self._next_states.get_nowait()
            self._no_states = ""
        self.epoch = reset.epoch
        # The coordinator names the episode (0 is one); a reset without a number (a client
        # of the protocol's own) starts the next.
        self.episode = reset.episode if reset.episode is not None else next_episode(self.episode)
        self.task_index = reset.task_index
        played = self._play(reset) if reset.human_model is not None else ""
        self.agent.reset(seed=stream_seed(self.args.seed, self.episode, "human"))
        self.print(f"\n##### RESET ({reset.reason or 'reset'}): episode {self.episode}"
                   f"{played} #####\nInitial state:\n[{self.state_var}:{self.agent.state_name}]")

    def _model(self, name: str) -> Model:
        """The human model ``name`` (a scenario name or a file), loaded once, checked against
        the task."""
        if name not in self.models:
            self.models[name] = load_human_model(name, self.args.task)
        return self.models[name]

    def _play(self, reset: Reset) -> str:
        """Play the human the reset names (a sequence's task): what the RESET line adds."""
        try:
            model = self._model(reset.human_model)
            drift_to = self._model(reset.drift_to) if reset.drift_to else None
            self.agent.play(model, drift_to, reset.drift or 0.0)
        except (HrcError, OSError, ValueError) as exc:
            print(f"{NAME}: cannot play the human model the reset names: {exc}; the task is "
                  f"played by {self.agent.model.source or self.agent.model.name}",
                  file=sys.stderr, flush=True)
            return ""
        drift = f" drifting to {reset.drift_to} ({reset.drift or 0.0:.2f})" if drift_to else ""
        return f", task {reset.task_index}: human {reset.human_model}{drift}"

    def run(self) -> int:
        """Step until stopped; 3 when the human node refuses this MDP (another is served)."""
        self.print("##### waiting for the human node to start an episode #####")
        try:
            self._wait_for_reset()
            while not self._stop.is_set():
                try:
                    if self.one_step():
                        self._wait_for_reset()
                    elif self.mode == "auto" and self.args.step_delay > 0:
                        self._wait_event("never", self.args.step_delay)
                except _ResetRequested as reset:
                    self.start_episode(reset.reset)
                except _ConfigureRequested as configure:
                    self.configure(configure.configure)
                    self._wait_for_reset()
        except SeatRefused as exc:
            print(f"{NAME}: {exc}", file=sys.stderr, flush=True)
            return 3
        return 0

    def _wait_for_reset(self) -> None:
        while True:
            try:
                self._wait_event("never")
            except _ResetRequested as reset:
                self.start_episode(reset.reset)
                return
            except _ConfigureRequested as configure:
                self.configure(configure.configure)

    def configure(self, msg: Configure) -> None:
        """Start again from the launch's settings as they are now (a warm stack's next cell),
        as a freshly started process would: the human model, the agent and its choice, the
        seed; no epoch, no sequence's models (the next reset names them). Answered with an
        ``ack``, or an ``error`` when the settings cannot be taken (nothing changes then)."""
        try:
            args = reread_launch_options(build_parser(), self.argv, self.args)
            _task, model, agent = build_agent(args)
        except (HrcError, OSError, ValueError) as exc:
            self._send(reply_error(msg, f"{NAME} not configured: {exc}", ERR_INVALID))
            return
        with self._states_lock:
            while not self._next_states.empty():   # states given for the cell before
                self._next_states.get_nowait()
            self._no_states = ""
        self.agent, self.args, self.mode = agent, args, args.mode
        self.state_var = agent.model.meta.get("state_var", "state_1")
        self.epoch, self.episode, self.task_index = None, 0, None
        self.models.clear()
        line = human_line(model, args)
        self.print(f"\n##### CONFIGURE ({msg.reason or 'configure'}): {line} #####")
        self._send(Ack(step=0, of=msg.type, result=line, reply_to=msg.id))

    def one_step(self) -> bool:
        """One step; True when the loop now waits for a reset (the episode is over, or the
        step was not carried out)."""
        if self.agent.reacts:
            return self.one_reacting_step()
        agent = self.agent
        action = self._choose_and_say()
        manual_state = self._ask_next_state() if self.mode == "manual" else None
        result = agent.advance(action, manual_state)
        msg = Step(step=result.step, action=result.action, state=result.state,
                   reward=result.reward, state_index=result.state_index, belief=result.belief,
                   manual=result.manual, epoch=self.epoch, id=next(self._ids))
        if not self._send(msg):
            return True
        reply = self._wait_reply(msg)
        self._say_results(result)
        if self._not_carried_out(reply):
            return True
        self.print(f"- Robot answered: {reply.action or '?'} ({reply.result or ''})")
        return self._after_step(reply)

    def one_reacting_step(self) -> bool:
        """One step of a human who hears the robot (module docstring): act, send the state he
        acts in, wait for the robot's action, react to it."""
        agent = self.agent
        action = self._choose_and_say()
        before = agent.state_name
        shown = agent.act(action)
        if shown != before:
            self.print(f"- Outcome of his {agent.model.actions[action]}, drawn before the robot "
                       f"acts: [{self.state_var}:{shown}]")
        msg = Step(step=agent.step, action=agent.model.actions[action], state=shown,
                   state_index=agent.model.states.index(shown), belief=agent.belief_dict(),
                   epoch=self.epoch, id=next(self._ids))
        if not self._send(msg):
            return True
        reply = self._wait_reply(msg)
        if self._not_carried_out(reply):
            return True
        robot_action = reply.action or ""
        self.print(f"- Robot answered: {robot_action or '?'} ({reply.result or ''})")
        manual_state = None
        if self.mode == "manual" and not reply.episode_over:
            manual_state = self._ask_next_state()
        result = agent.react(robot_action, reply.end_reason or "", manual_state)
        if not self._send(Reaction(step=result.step, state=result.state,
                                   state_index=result.state_index, rule=result.rule,
                                   reward=result.reward, manual=result.manual or None,
                                   epoch=self.epoch, id=next(self._ids))):
            return True
        self._say_results(result, reaction=f"{result.reaction}" + (
            "" if result.manual else f" (rule {result.rule})"))
        return self._after_step(reply)

    # -- what both kinds of step share ----------------------------------------------------------
    def _choose_and_say(self) -> int:
        """The agent's action in its state, printed as the step's header."""
        agent = self.agent
        action = agent.choose_action()
        self.print(f"\n-----Round {self.episode} Step {agent.step}-----")
        self.print(f"Agent Took: a{action}:{agent.model.actions[action]}, in the State: "
                   f"[{self.state_var}:{agent.state_name}]")
        return action

    def _send(self, msg) -> bool:
        """Send ``msg``; False (said) when the link failed: the loop then waits for a reset."""
        try:
            self.client.send(msg)
        except LinkError as exc:
            self.print(f"(link trouble: {exc}; waiting for a reset)")
            return False
        return True

    def _say_results(self, result, reaction: Optional[str] = None) -> None:
        """The step's results block: the reaction (a reacting human's), his state, the reward,
        the sums and the agent's belief."""
        self.print("== RESULTS ==")
        if reaction is not None:
            self.print(f"- Reaction: {reaction}")
        self.print(f"- Resulting State:[{self.state_var}:{result.state}]")
        self.print(f"- Reward = {result.reward:g}")
        self.print(f"- Accumulated rewards:\n  discounted / undiscounted = "
                   f"{result.discounted:g} / {result.undiscounted:g}")
        belief = "\n".join(f"[{self.state_var}:{s}] = {p:g}" for s, p in result.belief.items())
        self.print(f"- Agent's belief:\n{belief}")

    def _not_carried_out(self, reply) -> bool:
        """True (said) when the step got no answer or was refused: the loop resets."""
        if reply is None:
            self.print(f"- World: no answer in {self.args.reply_timeout:g} s; waiting for a reset")
            return True
        if isinstance(reply, Error):
            self.print(f"- World: step refused: {reply.message}; waiting for a reset")
            self._refuse_states("the step was refused and the loop resets; give the state "
                                "when the next episode asks for it")
            return True
        return False

    def _after_step(self, reply) -> bool:
        """The episode's end, when the reply says so; True when the loop now waits for a
        reset."""
        agent = self.agent
        if reply.end_reason:
            steps = f"{agent.step} step" + ("" if agent.step == 1 else "s")
            self.print(f"\n===== Episode {self.episode} over ({reply.end_reason}) after "
                       f"{steps}: discounted / undiscounted = "
                       f"{agent.discounted:g} / {agent.undiscounted:g} =====")
        if reply.episode_over and self.task_index is not None:
            self.print("The next task of the sequence starts with the next reset, by itself.")
        elif reply.episode_over:
            self.print("The next episode starts with the next reset (with on_episode_end:=wait: "
                       "press Enter in the ROS terminal or call /hrc/reset).")
            self._refuse_states(f"episode {self.episode} is over ({reply.end_reason or 'ended'})"
                                ": no next state until the next episode; reset first (Enter "
                                "in the roslaunch terminal or `rosservice call /hrc/reset`)")
            return True
        return False

    def _refuse_states(self, why: str) -> None:
        """From now until the next reset, states given are refused with ``why``."""
        with self._states_lock:
            self._no_states = why

    def stop(self) -> None:
        self._stop.set()


def no_terminal_line(display: bool) -> str:
    """What a manual-mode MDP without a terminal to read says once at start-up."""
    why = "started without one" if display else "no display for its xterm"
    return (f"{NAME}: manual mode without a terminal of its own ({why}): type each state in "
            "the roslaunch terminal (a number, or a letter for autogen, then Enter; Enter "
            "alone resets everything) or `rosservice call /hrc/set_human_state N`; or set "
            "DISPLAY, or use start_mdp:=false and run the command the launch then prints in "
            "another terminal")


def input_ended_line(tty: bool) -> str:
    """What the MDP says when its terminal's input ends."""
    how = "Ctrl-D" if tty else "standard input closed"
    return (f"{NAME}: input ended ({how}): the MDP goes on in auto mode, the model chooses "
            "every next state from now on (to type states again, start despot_mdp anew: "
            "under roslaunch, close its window and it respawns)")


def _isatty(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError, OSError):
        return False


def build_parser() -> argparse.ArgumentParser:
    p = solver_parser(NAME, "The simulated human: an MDP agent linked to the human node by "
                      "websocket.", "human_model", "human_port")
    settings.add_argument(p, "mode")
    settings.add_argument(p, "human_choice", "--choice")
    settings.add_argument(p, "temperature")
    settings.add_argument(p, "manual_share")
    settings.add_argument(p, "step_delay")
    p.add_argument("--stdin", choices=("auto", "on", "off"), default="auto",
                   help="read typed states from the terminal (auto: when it is a terminal)")
    p.add_argument("--reply-timeout", type=ranged_number(float, 0.0, 86400.0, low_open=True),
                   default=300.0,
                   help="seconds to wait for the world and the robot to finish a step")
    return p



def build_agent(args: argparse.Namespace) -> Tuple[tasks.Task, Model, HumanAgent]:
    """The human the options ask for: the task, its model (checked against the task) and the
    MDP agent that plays it. Raises HrcError, OSError or ValueError (one line)."""
    task = tasks.get(args.task)
    model = load_human_model(args.human_model, task)
    agent = HumanAgent(model, HumanAgentConfig(choice=args.human_choice,
                                               temperature=args.temperature,
                                               manual_share=args.manual_share, seed=args.seed),
                       reaction=task.reaction)
    return task, model, agent


def human_line(model: Model, args: argparse.Namespace) -> str:
    """Who the process plays, in one line: the model, its size, the mode and the seed."""
    return (f"{model.source or args.human_model}: {model.n_states} states, "
            f"{model.n_actions} actions, {args.mode} mode, seed {args.seed}")


def main(argv: Optional[list] = None) -> int:
    started = start_solver(NAME, build_parser(), argv, build_agent)
    if started is None:
        return CANNOT_START
    args, (task, model, agent), token = started
    client = MessageClient(link_url(args.human_port, args.host), NAME, connect_timeout=3600.0,
                           send_timeout=args.reply_timeout, token=token)
    process = MdpProcess(agent, client, args, argv=argv)
    read_stdin = args.stdin == "on" or (args.stdin == "auto" and sys.stdin.isatty())
    mapping = positional_mapping_line(model)
    if mapping:
        print(f"{NAME}: {mapping}", file=sys.stderr, flush=True)
    reacts = "; he reacts to the robot" if task.reacts else ""
    print(f"{NAME}: {human_line(model, args)}, task {task.name}{reacts}; connecting to "
          f"{client.url}", flush=True)
    code = 0
    try:
        client.connect()
        process.start_threads(read_stdin)
        code = process.run()
    except KeyboardInterrupt:
        pass
    finally:
        process.stop()
        client.close()
    return code


if __name__ == "__main__":
    sys.exit(main())
