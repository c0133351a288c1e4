"""despot_mdp: the simulated human's process (no ROS; it speaks only websocket).

It loads a human MDP, and is a client of the human node (``ws://127.0.0.1:9090``). Each step
it picks the human's action, decides the next state (sampled from the model in ``auto``
mode; asked in ``manual`` mode, as the seed's MDP terminal does), sends a ``step`` message,
and waits for the human node's ``ack`` (which carries the robot's answer) before the next.

Manual mode asks ``Please enter the next state [integer from 0 to 7, press any non-int key
for autogen]``: an integer gives that state (with ``--manual-share`` of the belief), anything
else lets the model choose. The answer can also come as a ``next_state`` message (the
``/hrc/set_human_state`` service of the human node), so no terminal is needed.

A ``reset`` message (Enter in the ROS terminal, ``/hrc/reset``) puts the human back to its
initial state, step 0, zero reward.
"""
from __future__ import annotations

import argparse
import queue
import sys
import threading
import time
from typing import Optional, TextIO, Tuple

from ros_hrc.command_line import own_arguments
from ros_hrc.errors import HrcError, LinkError
from ros_hrc.link.protocol import Ack, Error, Message, NextState, Reset, Step
from ros_hrc.link.transport import LinkClosed, MessageClient, link_url
from ros_hrc.model_files import resolve_model
from ros_hrc.pomdp.io import load_model
from ros_hrc.processes.human_agent import ACTION_CHOICES, HumanAgent, HumanAgentConfig

NAME = "despot_mdp"
EPISODE_END_CHOICES = ("wait", "reset", "continue")


class _ResetRequested(Exception):
    """A reset arrived while the loop was waiting for something else."""


class MdpProcess:
    """The human's loop: choose, (ask,) step, wait for the world and the robot, print."""

    def __init__(self, agent: HumanAgent, client: MessageClient, args: argparse.Namespace,
                 out: TextIO = sys.stdout) -> None:
        self.agent = agent
        self.client = client
        self.args = args
        self.out = out
        self.episode = 0
        self._events: "queue.Queue[Tuple[str, object]]" = queue.Queue()
        self._next_states: "queue.Queue[Tuple[Optional[int], str]]" = queue.Queue()
        self._stop = threading.Event()
        self.state_var = agent.model.meta.get("state_var", "state_1")

    # -- input: the link and the terminal ------------------------------------------------------
    def start_threads(self, read_stdin: bool) -> None:
        threading.Thread(target=self._dispatch_link, name="mdp-link", daemon=True).start()
        if read_stdin:
            threading.Thread(target=self._read_terminal, name="mdp-stdin", daemon=True).start()

    def _dispatch_link(self) -> None:
        while not self._stop.is_set():
            try:
                msg = self.client.receive()
            except LinkClosed:
                return
            if isinstance(msg, Reset):
                self._events.put(("reset", msg))
            elif isinstance(msg, NextState):
                self._take_next_state(msg)
            else:
                self._events.put(("reply", msg))

    def _take_next_state(self, msg: NextState) -> None:
        n = self.agent.model.n_states
        if msg.state is not None and not 0 <= msg.state < n:
            self._send(Error(message=f"state must be an integer from 0 to {n - 1}, "
                                     f"not {msg.state}", in_reply_to=msg.type))
            return
        if self.args.mode != "manual":
            self._send(Error(message="the MDP runs in auto mode: it chooses the next state "
                                     "itself (start it with mode:=manual)", in_reply_to=msg.type))
            return
        self._next_states.put((msg.state, "message"))
        self._events.put(("next_state", None))
        name = "autogen" if msg.state is None else self.agent.model.states[msg.state]
        self._send(Ack(step=self.agent.step, of=msg.type, result=f"next state: {name}"))

    def _read_terminal(self) -> None:
        for line in sys.stdin:
            self._next_states.put((self._parse_typed(line.strip()), "terminal"))
            self._events.put(("next_state", None))

    def _parse_typed(self, text: str) -> Optional[int]:
        try:
            value = int(text)
        except ValueError:
            return None
        return value

    def _send(self, msg: Message) -> None:
        try:
            self.client.send(msg)
        except LinkError as exc:
            self.print(f"(could not send {msg.type}: {exc})")

    def print(self, text: str = "") -> None:
        print(text, file=self.out, flush=True)

    # -- waiting ----------------------------------------------------------------------------
    def _wait_event(self, wanted: str, timeout: Optional[float] = None):
        """The next event of kind ``wanted``; raises _ResetRequested on a reset."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            try:
                kind, payload = self._events.get(timeout=left)
            except queue.Empty:
                return None
            if kind == "reset":
                raise _ResetRequested()
            if kind == wanted:
                return payload

    def _ask_next_state(self) -> Optional[int]:
        n = self.agent.model.n_states
        while True:
            self.print(f"\nPlease enter the next state [integer from 0 to {n - 1}, "
                       "press any non-int key for autogen]: ")
            while True:
                try:
                    value, source = self._next_states.get_nowait()
                    break
                except queue.Empty:
                    self._wait_event("next_state")
            if value is None:
                self.print("State is generated by the model")
                return None
            if 0 <= value < n:
                self.print(f"State is manually entered: {value}"
                           + (" (from /hrc/set_human_state)" if source == "message" else ""))
                return value
            self.print(f"{value} is not a state: enter an integer from 0 to {n - 1}")

    def _wait_reply(self, step: Step) -> Message:
        while True:
            reply = self._wait_event("reply", self.args.reply_timeout)
            if reply is None:
                raise LinkError(f"no answer to step {step.step} in {self.args.reply_timeout} s")
            same_episode = reply.extra.get("episode", self.episode) == self.episode
            if isinstance(reply, (Ack, Error)) and getattr(reply, "step", None) == step.step \
                    and same_episode:
                return reply

    # -- the loop ---------------------------------------------------------------------------
    def reset(self, reason: str) -> None:
        self.episode += 1
        self.agent.reset(seed=self.args.seed + self.episode)
        while not self._next_states.empty():
            self._next_states.get_nowait()
        self.print(f"\n##### RESET ({reason}) #####\nInitial state:\n"
                   f"[{self.state_var}:{self.agent.state_name}]")

    def episode_over(self) -> bool:
        steps = self.args.max_steps
        return self.agent.state_name == self.args.goal_state or bool(steps and self.agent.step >= steps)

    def run(self) -> None:
        self.print(f"#####\nInitial state:\n[{self.state_var}:{self.agent.state_name}]")
        while not self._stop.is_set():
            try:
                if self.agent.step > 0 and self.episode_over():
                    self._end_episode()
                    continue
                self.one_step()
                if self.args.mode == "auto" and self.args.step_delay > 0:
                    if self._wait_event("never", self.args.step_delay) is None:
                        pass
            except _ResetRequested:
                self.reset("asked by the ROS side")
            except LinkError as exc:
                self.print(f"(link trouble: {exc}; waiting for a reset)")
                self._wait_for_reset()

    def _wait_for_reset(self) -> None:
        try:
            while True:
                self._wait_event("never")
        except _ResetRequested:
            self.reset("asked by the ROS side")

    def _end_episode(self) -> None:
        why = "success" if self.agent.state_name == self.args.goal_state else \
            f"{self.args.max_steps} steps"
        self.print(f"\n===== Episode {self.episode} over ({why}) after {self.agent.step} steps: "
                   f"discounted / undiscounted = {self.agent.discounted:g} / "
                   f"{self.agent.undiscounted:g} =====")
        if self.args.on_episode_end == "continue":
            self.args.goal_state, self.args.max_steps = None, 0  # keep stepping
            return
        if self.args.on_episode_end == "reset":
            # The link's replies arrive through the dispatcher thread, as events.
            self._send(Reset(reason=f"episode over ({why})"))
            while True:
                reply = self._wait_event("reply", self.args.reply_timeout)
                if reply is None or (isinstance(reply, Ack) and reply.of == "reset") or \
                        (isinstance(reply, Error) and reply.in_reply_to == "reset"):
                    break
            if reply is None:
                self.print("(the human node did not acknowledge the reset)")
            self.reset(f"episode over ({why})")
            return
        self.print("Press Enter in the ROS terminal (or call /hrc/reset) for a new episode.")
        self._wait_for_reset()

    def one_step(self) -> None:
        agent = self.agent
        action = agent.choose_action()
        self.print(f"\n-----Round {self.episode} Step {agent.step}-----")
        self.print(f"Agent Took: a{action}:{agent.model.actions[action]}, in the State: "
                   f"[{self.state_var}:{agent.state_name}]")
        manual_state = self._ask_next_state() if self.args.mode == "manual" else None
        result = agent.advance(action, manual_state)
        msg = Step(step=result.step, action=result.action, state=result.state,
                   reward=result.reward, state_index=result.state_index, belief=result.belief,
                   manual=result.manual, extra={"episode": self.episode})
        self.client.send(msg)
        reply = self._wait_reply(msg)
        self.print("== RESULTS ==")
        self.print(f"- Resulting State:[{self.state_var}:{result.state}]")
        self.print(f"- Reward = {result.reward:g}")
        self.print(f"- Accumulated rewards:\n  discounted / undiscounted = "
                   f"{result.discounted:g} / {result.undiscounted:g}")
        belief = "\n".join(f"[{self.state_var}:{s}] = {p:g}" for s, p in result.belief.items())
        self.print(f"- Agent's belief:\n{belief}")
        if isinstance(reply, Error):
            self.print(f"- World: step refused: {reply.message}")
        else:
            self.print(f"- Robot answered: {reply.action or '?'} ({reply.result or ''})")

    def stop(self) -> None:
        self._stop.set()


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=NAME, description="The simulated human: an MDP agent "
                                "linked to the human node by websocket.")
    p.add_argument("--model", default="humanModel",
                   help="human scenario name (models/human/<name>.pomdpx) or a model file")
    p.add_argument("--host", default="127.0.0.1", help="human node's host")
    p.add_argument("--port", type=int, default=9090, help="human node's websocket port")
    p.add_argument("--mode", choices=("auto", "manual"), default="auto",
                   help="auto: the model picks the next state; manual: ask for it")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same run)")
    p.add_argument("--choice", choices=ACTION_CHOICES, default="optimal",
                   help="how the human picks actions from the MDP values")
    p.add_argument("--temperature", type=float, default=1.0, help="softmax temperature")
    p.add_argument("--manual-share", type=float, default=0.8,
                   help="belief given to a manually entered state (the seed's 80 %%)")
    p.add_argument("--step-delay", type=float, default=1.0,
                   help="pause between steps in auto mode, seconds")
    p.add_argument("--max-steps", type=int, default=0, help="end an episode after N steps (0: never)")
    p.add_argument("--goal-state", default="success", help="state that ends an episode")
    p.add_argument("--on-episode-end", choices=EPISODE_END_CHOICES, default="wait",
                   help="wait for a reset, reset at once, or continue stepping")
    p.add_argument("--stdin", choices=("auto", "on", "off"), default="auto",
                   help="read typed states from the terminal (auto: when it is a terminal)")
    p.add_argument("--reply-timeout", type=float, default=300.0,
                   help="seconds to wait for the world and the robot to finish a step")
    return p


def main(argv: Optional[list] = None) -> int:
    args = build_parser().parse_args(own_arguments(argv))
    try:
        model = load_model(str(resolve_model(args.model, "human")))
        agent = HumanAgent(model, HumanAgentConfig(choice=args.choice, temperature=args.temperature,
                                                   manual_share=args.manual_share, seed=args.seed))
    except (HrcError, OSError, ValueError) as exc:
        print(f"{NAME}: {exc}", file=sys.stderr)
        return 2
    client = MessageClient(link_url(args.port, args.host), NAME, connect_timeout=3600.0,
                           send_timeout=args.reply_timeout)
    process = MdpProcess(agent, client, args)
    read_stdin = args.stdin == "on" or (args.stdin == "auto" and sys.stdin.isatty())
    print(f"{NAME}: {model.source or args.model}: {model.n_states} states, "
          f"{model.n_actions} actions, {args.mode} mode; connecting to {client.url}", flush=True)
    try:
        client.connect()
        process.start_threads(read_stdin)
        process.run()
    except KeyboardInterrupt:
        pass
    finally:
        process.stop()
        client.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
