"""despot_pomdp: the robot's decision process (no ROS; it speaks only websocket).

It loads the robot POMDP and keeps the robot's belief. It is a websocket **server** on port
7070 for the observer (``hrc_obs``) and a **client** of the robot node on 8080. For each
``observation``: update the belief with the robot's previous action and the observation
(``rIdle`` before the first step: the robot starts idle), plan (DESPOT by default, a saved
offline policy, or a baseline robot of ``ros_hrc.robot_policies``: the reactive robot or no
robot, which keep the belief but decide without it), send the ``action`` to the robot node,
wait until the robot has carried it out, and answer the observer with the same ``action``
message plus the robot's result.
A ``reset`` puts the belief back to the model's initial belief (and the reactive robot's step
count back to 0).

An observation of zero probability under the belief cannot be explained by the model: the
belief keeps the prediction through T without it, the step goes on, and the terminal says so.
"""
from __future__ import annotations

import argparse
import sys
import threading
import time
from typing import Optional

import numpy as np

from ros_hrc.command_line import own_arguments
from ros_hrc.errors import HrcError, LinkError
from ros_hrc.link.protocol import Ack, Action, Error, Message, Observation, Reset
from ros_hrc.link.transport import MessageClient, MessageServer, Peer, link_url
from ros_hrc.model_files import resolve_model
from ros_hrc.pomdp.io import load_model
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner
from ros_hrc.pomdp.planner import Planner, PolicyPlanner
from ros_hrc.pomdp.policy import load as load_policy
from ros_hrc.robot_policies import NoRobotConfig, NoRobotPlanner, ReactiveConfig, ReactivePlanner

NAME = "despot_pomdp"
#: --planner's choices; build_planner is the one place that turns them into planners.
PLANNERS = ("despot", "policy", "reactive", "none")


class RobotAgent:
    """The robot's belief and planner, stepped by observation names."""

    def __init__(self, model: Model, planner: Planner, first_action: str = "rIdle") -> None:
        self.model = model
        self.planner = planner
        self.first_action = model.index("action", first_action) if first_action in model.actions else 0
        self.reset()

    def reset(self) -> None:
        self.planner.reset()
        self.last_action = self.first_action
        self.surprises = 0

    def step(self, observation: str):
        """Belief update with (previous action, observation), then plan: (action, ms, note)."""
        o = self.model.index("observation", observation)
        note = ""
        started = time.perf_counter()
        self.planner.update(self.last_action, o)
        if self.planner.last_update_zero_probability:
            self.surprises += 1
            note = (f"observation {observation} has probability 0 after "
                    f"{self.model.actions[self.last_action]}: the belief keeps the "
                    "prediction without it")
        action = self.planner.act()
        decision_ms = (time.perf_counter() - started) * 1000.0
        self.last_action = action
        return action, decision_ms, note

    @property
    def belief(self) -> np.ndarray:
        b = np.clip(np.asarray(self.planner.belief, dtype=float), 0.0, None)
        return b / b.sum()


class PomdpProcess:
    """The 7070 server's handler: observation in, robot action carried out, action back."""

    def __init__(self, agent: RobotAgent, robot: MessageClient, reply_timeout: float) -> None:
        self.agent = agent
        self.robot = robot
        self.reply_timeout = reply_timeout
        self._lock = threading.Lock()

    def handle(self, msg: Message, peer: Peer) -> Optional[Message]:
        with self._lock:
            if isinstance(msg, Observation):
                return self.on_observation(msg)
            if isinstance(msg, Reset):
                self.agent.reset()
                try:
                    self.robot.request(Reset(reason=msg.reason or "reset"), self.reply_timeout)
                except LinkError:
                    pass  # the robot node resets with the world anyway
                print(f"\n##### RESET: belief back to the initial belief #####\n"
                      f"{self._belief_text()}", flush=True)
                return Ack(step=0, of=msg.type, result="robot belief reset")
        return Error(message=f"{NAME} does not take {msg.type} messages",
                     in_reply_to=msg.type, step=getattr(msg, "step", None))

    def on_observation(self, msg: Observation) -> Message:
        model = self.agent.model
        if msg.observation not in model.observations:
            return Error(message=f"unknown observation {msg.observation!r}; the model's are "
                                 f"{', '.join(model.observations)}", in_reply_to=msg.type,
                         step=msg.step)
        action, decision_ms, note = self.agent.step(msg.observation)
        belief = self.agent.belief
        decision = Action(step=msg.step, action=model.actions[action], belief=belief.tolist(),
                          belief_states=list(model.states), decision_ms=decision_ms)
        try:
            reply = self.robot.request(decision, self.reply_timeout)
            success = isinstance(reply, Ack) and reply.success is not False
            result = reply.result if isinstance(reply, Ack) else reply.message
        except LinkError as exc:
            success, result = False, f"robot node unreachable: {exc}"
        print(f"\n-----Step {msg.step}-----\n- Observation = {msg.observation} "
              f"(bits {msg.bits}); true state (not seen) = {msg.state}", flush=True)
        if note:
            print(f"- NOTE: {note}", flush=True)
        # The reactive robot says which of its rules chose the action.
        rule = getattr(self.agent.planner, "last_rule", None)
        why = f"rule {rule}, " if rule else ""
        print(f"- Belief:\n{self._belief_text()}\n- Action = {model.actions[action]} "
              f"({why}{decision_ms:.1f} ms)\n- Robot: {result}", flush=True)
        return Action(step=msg.step, action=decision.action, belief=decision.belief,
                      belief_states=decision.belief_states, decision_ms=decision_ms,
                      extra={"success": bool(success), "result": result or "",
                             "surprise": bool(note)})

    def _belief_text(self) -> str:
        b = self.agent.belief
        return "\n".join(f"  {s} = {p:.4f}" for s, p in zip(self.agent.model.states, b) if p > 0)


def build_planner(model: Model, args: argparse.Namespace) -> Planner:
    """The planner the command line asks for: DESPOT, a saved offline policy, the reactive
    robot or no robot."""
    if args.planner == "despot":
        config = DespotConfig(scenarios=args.scenarios, depth=args.depth, pruning=args.lambda_,
                              time_per_step=args.time_per_step,
                              max_trials=args.max_trials or None)
        return DespotPlanner(model, config, seed=args.seed)
    if args.planner == "policy":
        if not args.policy:
            raise ValueError("--planner policy needs --policy FILE (hrc_pomdp solve -o FILE)")
        return PolicyPlanner(model, load_policy(args.policy, model), seed=args.seed,
                             lookahead=True)
    if args.planner == "reactive":
        return ReactivePlanner(model, ReactiveConfig(budget=args.reactive_budget), seed=args.seed)
    if args.planner == "none":
        return NoRobotPlanner(model, NoRobotConfig(), seed=args.seed)
    raise ValueError(f"unknown planner {args.planner!r}: {', '.join(PLANNERS)}")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=NAME, description="The robot's POMDP planner, linked by "
                                "websocket to the observer (server) and the robot node (client).")
    p.add_argument("--model", default="robot", help="robot model name (models/robot/) or file")
    p.add_argument("--host", default="127.0.0.1", help="address to serve observations on")
    p.add_argument("--port", type=int, default=7070, help="port to serve observations on")
    p.add_argument("--robot-host", default="127.0.0.1", help="robot node's host")
    p.add_argument("--robot-port", type=int, default=8080, help="robot node's websocket port")
    p.add_argument("--planner", choices=PLANNERS, default="despot",
                   help="online DESPOT, a saved offline policy (needs --policy), the reactive "
                        "robot (rules on the current observation) or none (the robot never acts)")
    p.add_argument("--policy", help="offline policy file (hrc_pomdp solve -o FILE)")
    p.add_argument("--reactive-budget", type=int, default=ReactiveConfig.budget,
                   help="reactive robot: help after this many steps since the reset without "
                        "the human getting the object (0: never for that reason)")
    p.add_argument("--time-per-step", type=float, default=0.1, help="DESPOT's budget per decision, s")
    p.add_argument("--scenarios", type=int, default=500, help="DESPOT's K sampled scenarios")
    p.add_argument("--depth", type=int, default=90, help="DESPOT's maximum depth")
    p.add_argument("--lambda", dest="lambda_", type=float, default=0.1,
                   help="DESPOT's regularisation (pruning constant)")
    p.add_argument("--max-trials", type=int, default=0,
                   help="cap on DESPOT trials per decision (0: time only); makes runs reproducible")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.add_argument("--reply-timeout", type=float, default=120.0,
                   help="seconds to wait for the robot node to carry out an action")
    return p


def main(argv: Optional[list] = None) -> int:
    args = build_parser().parse_args(own_arguments(argv))
    try:
        model = load_model(str(resolve_model(args.model, "robot")))
        planner = build_planner(model, args)
    except (HrcError, OSError, ValueError) as exc:
        print(f"{NAME}: {exc}", file=sys.stderr)
        return 2
    agent = RobotAgent(model, planner)
    robot = MessageClient(link_url(args.robot_port, args.robot_host), NAME,
                          connect_timeout=3600.0, send_timeout=args.reply_timeout)
    process = PomdpProcess(agent, robot, args.reply_timeout)
    server = MessageServer(args.port, process.handle, host=args.host, name=NAME)
    try:
        server.start()
    except LinkError as exc:
        print(f"{NAME}: {exc}", file=sys.stderr)
        return 2
    robot.start()
    print(f"{NAME}: {model.source or args.model}: {model.n_states} states, {model.n_actions} "
          f"actions, {model.n_observations} observations; planner {args.planner}; "
          f"observations on {server.url}, robot node at {robot.url}", flush=True)
    try:
        threading.Event().wait()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
        robot.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
