"""despot_pomdp: the robot's decision process (no ROS; it speaks only websocket).

It loads the robot POMDP (checked against the states, actions and observations of the task,
``--task``: :mod:`ros_hrc.tasks`) and keeps the robot's belief. It is a websocket **server**
on port 7070 for the coordinator (``hrc_human``). For each ``observation``: update the
belief with the robot's previous action and the observation (the task's idle action before
the first step, ``rIdle`` for the seed: the robot starts idle), plan (DESPOT by default, a
saved offline policy, or a baseline robot of ``ros_hrc.agents.robots``: the reactive robot
or no robot, which keep the belief but decide without it), and answer with a ``decision``.
The coordinator has the robot carry it out (the world's /robot/* services), not this
process.
A ``reset`` puts the belief back to the model's initial belief (and the reactive robot's step
count, or fabric's reactive robot's MDP state, back to the start), in the epoch the reset names, and restarts the planner's random stream as
the one of (``--seed``, the reset's episode, "planner") (:mod:`ros_hrc.streams`): episode
e of seed s gets the same decisions whatever ran before it. Observations of any other epoch
are refused.

``--time-per-step 0`` takes the time budget away: DESPOT is bounded by ``--max-trials`` alone,
so its decisions depend on nothing but the seed (no clock is read in a decision); experiments
run it so (``ros_hrc.experiment.stack``), live launches keep the 0.1 s budget.

An observation of zero probability under the belief cannot be explained by the model: the
belief keeps the prediction through T without it, the step goes on, and the terminal says so.

It serves only processes of its own launch: a client must prove the launch's link token in its
hello (``--link-session``, given by hrc.launch; by hand ``--token-file PATH`` or
``HRC_LINK_TOKEN_FILE``; :mod:`ros_hrc.link.token`). Under hrc.launch its options are the
launch's resolved settings, which the pre-flight wrote beside the token (every path absolute);
an option on its command line wins (:func:`ros_hrc.command_line.parse_launch_options`). A
relative ``--model`` or ``--policy`` given by hand is taken from the directory it runs in.
"""
from __future__ import annotations

import argparse
import math
import sys
import threading
import time
from typing import Optional

import numpy as np

from ros_hrc import tasks
from ros_hrc.command_line import parse_launch_options, print_whole_lines
from ros_hrc.errors import HrcError, LinkError
from ros_hrc.link.protocol import (ERR_INVALID, ERR_STALE, Ack, Decision, DispatchTable,
                                   Message, Observation, Reset, reply_error)
from ros_hrc.link.token import add_token_arguments, launch_token, stop_launch
from ros_hrc.link.transport import MessageServer, Peer
from ros_hrc import settings
from ros_hrc.models import load_robot_model, positional_mapping_line
from ros_hrc.streams import stream_seed
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner
from ros_hrc.pomdp.planner import Planner, PolicyPlanner
from ros_hrc.pomdp.policy import load as load_policy
from ros_hrc.agents.robots import ExplorePlanner, NoRobotConfig, NoRobotPlanner, reactive_planner

NAME = "despot_pomdp"


class RobotAgent:
    """The robot's belief and planner, stepped by observation names. ``seed``: the run's seed,
    from which each episode's planner stream is derived."""

    def __init__(self, model: Model, planner: Planner, first_action: str = "rIdle",
                 seed: int = 0) -> None:
        self.model = model
        self.planner = planner
        self.seed = seed
        self.episode: Optional[int] = None
        self.first_action = model.index("action", first_action) if first_action in model.actions else 0
        self.reset()

    def reset(self, episode: Optional[int] = None) -> None:
        """Back to the initial belief; for ``episode`` (when given), the planner draws from
        that episode's stream, from its start."""
        if episode is not None:
            reseed = getattr(self.planner, "reseed", None)
            if reseed is not None:
                reseed(stream_seed(self.seed, episode, "planner"))
            self.episode = episode
        self.planner.reset()
        self.last_action = self.first_action
        self.surprises = 0

    def step(self, observation: str, elapsed: Optional[float] = None):
        """Belief update with (previous action, observation), then plan: (action, ms, note).
        ``elapsed``: the simulated seconds since the episode's reset (None: unknown), for a
        planner that counts time (``observe_time``: the fabric reactive robot)."""
        o = self.model.index("observation", observation)
        note = ""
        observe_time = getattr(self.planner, "observe_time", None)
        if observe_time is not None:
            observe_time(elapsed)
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
    """The 7070 server's handlers: an observation in, a decision out; a reset into an epoch.

    The belief belongs to the epoch it was last reset into. An observation of another epoch
    is refused, never applied: after a restart this process has no epoch at all, so the
    coordinator learns that the belief it relied on is gone and resets the loop."""

    def __init__(self, agent: RobotAgent) -> None:
        self.agent = agent
        self.epoch: Optional[int] = None
        self.dispatch = DispatchTable(NAME)
        self.dispatch.on(Observation, self.on_observation)
        self.dispatch.on(Reset, self.on_reset)
        self._said_no_time = False

    def on_reset(self, msg: Reset, peer: Peer) -> Message:
        # The coordinator names the episode (0 is one); a reset without a number (a client of
        # the protocol's own) starts the next.
        episode = msg.episode if msg.episode is not None else (
            0 if self.agent.episode is None else self.agent.episode + 1)
        self.agent.reset(episode)
        self.epoch = msg.epoch
        print(f"\n##### RESET: belief back to the initial belief (episode {msg.episode}, "
              f"epoch {msg.epoch}) #####\n{self._belief_text()}", flush=True)
        return Ack(step=0, of=msg.type, result="robot belief reset", epoch=msg.epoch,
                   reply_to=msg.id)

    def on_observation(self, msg: Observation, peer: Peer) -> Message:
        model = self.agent.model
        if self.epoch is None or msg.epoch != self.epoch:
            return reply_error(msg, f"{NAME} was not reset into epoch {msg.epoch} (its belief "
                                    f"is of epoch {self.epoch}): reset it first", ERR_STALE)
        if msg.observation not in model.observations:
            return reply_error(msg, f"unknown observation {msg.observation!r}; the model's are "
                                    f"{', '.join(model.observations)}", ERR_INVALID)
        action, decision_ms, note = self.agent.step(msg.observation, msg.elapsed)
        belief = self.agent.belief
        at = f" at {msg.elapsed:.1f} s" if msg.elapsed is not None else ""
        print(f"\n-----Step {msg.step}-----\n- Observation = {msg.observation} "
              f"(bits {msg.bits}){at}; true state (not seen) = {msg.state}", flush=True)
        if msg.elapsed is None and hasattr(self.agent.planner, "observe_time") \
                and not self._said_no_time:
            self._said_no_time = True
            print(f"{NAME}: observations carry no time (elapsed): the reactive robot's wait "
                  "(rule waited) cannot apply", file=sys.stderr, flush=True)
        if note:
            print(f"- NOTE: {note}", flush=True)
        # The reactive robot says which of its rules chose the action (and the MDP state).
        rule = getattr(self.agent.planner, "last_rule", None)
        mdp_state = getattr(self.agent.planner, "mdp_state", None)
        why = (f"rule {rule}, " if rule else "") + (f"MDP state {mdp_state}, " if mdp_state else "")
        print(f"- Belief:\n{self._belief_text()}\n- Action = {model.actions[action]} "
              f"({why}{decision_ms:.1f} ms)", flush=True)
        # Why it chose: the value of each action the planner compared (none from a baseline).
        values = sorted(self.agent.planner.last_stats.action_values.items())
        return Decision(step=msg.step, action=model.actions[action], belief=belief.tolist(),
                        belief_states=list(model.states), decision_ms=decision_ms,
                        surprise=bool(note), rule=rule or None,
                        action_names=[model.actions[a] for a, _ in values] or None,
                        action_values=[v for _, v in values] or None, epoch=msg.epoch,
                        reply_to=msg.id)

    def _belief_text(self) -> str:
        b = self.agent.belief
        return "\n".join(f"  {s} = {p:.4f}" for s, p in zip(self.agent.model.states, b) if p > 0)


def build_planner(model: Model, args: argparse.Namespace) -> Planner:
    """The planner the command line asks for: DESPOT, a saved offline policy, the reactive
    robot, no robot or the exploring robot."""
    if args.planner == "despot":
        if args.time_per_step == 0 and not args.max_trials:
            raise ValueError("--time-per-step 0 (no time budget) needs --max-trials > 0")
        # 0: no time budget, the trials alone bound the search (no clock read in a decision).
        config = DespotConfig(scenarios=args.scenarios, depth=args.depth, pruning=args.lambda_,
                              time_per_step=args.time_per_step or math.inf,
                              max_trials=args.max_trials or None)
        return DespotPlanner(model, config, seed=args.seed)
    if args.planner == "policy":
        if not args.policy_file:
            raise ValueError("--planner policy needs --policy FILE (hrc_pomdp solve -o FILE)")
        return PolicyPlanner(model, load_policy(args.policy_file, model), seed=args.seed,
                             lookahead=True)
    if args.planner == "reactive":
        return reactive_planner(tasks.get(args.task), model, budget=args.reactive_budget,
                                wait=args.reactive_wait, seed=args.seed)
    if args.planner == "none":
        idle = tasks.get(args.task).robot_idle_action
        return NoRobotPlanner(model, NoRobotConfig(idle_action=idle), seed=args.seed)
    if args.planner == "explore":
        return ExplorePlanner(model, seed=args.seed)
    raise ValueError(f"unknown planner {args.planner!r}: "
                     f"{', '.join(settings.SETTINGS['planner'].choices)}")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=NAME, description="The robot's POMDP planner: a websocket "
                                "server answering each observation with a decision.")
    settings.add_argument(p, "task")
    settings.add_argument(p, "robot_model", "--model")
    settings.add_argument(p, "host")
    settings.add_argument(p, "pomdp_port", "--port")
    settings.add_argument(p, "link_read_timeout")
    settings.add_argument(p, "planner")
    settings.add_argument(p, "policy_file", "--policy")
    settings.add_argument(p, "reactive_budget")
    settings.add_argument(p, "reactive_wait")
    settings.add_argument(p, "time_per_step")
    settings.add_argument(p, "scenarios")
    settings.add_argument(p, "depth")
    settings.add_argument(p, "lambda", "--lambda", dest="lambda_")
    settings.add_argument(p, "max_trials")
    settings.add_argument(p, "seed")
    add_token_arguments(p)
    return p


def main(argv: Optional[list] = None) -> int:
    print_whole_lines()
    args = parse_launch_options(build_parser(), argv)
    try:
        task = tasks.get(args.task)
        model = load_robot_model(args.robot_model, task)
        planner = build_planner(model, args)
        token = launch_token(args)
    except (HrcError, OSError, ValueError) as exc:
        print(f"{NAME}: {exc}", file=sys.stderr, flush=True)
        if args.link_session and stop_launch(args.link_session):
            # Respawned, it would fail the same way about once a second: stop the launch.
            print(f"{NAME}: cannot start on this launch's settings: stopping the launch",
                  file=sys.stderr, flush=True)
        return 2
    process = PomdpProcess(RobotAgent(model, planner, first_action=task.robot_idle_action,
                                      seed=args.seed))
    server = MessageServer(args.pomdp_port, process.dispatch, host=args.host, name=NAME,
                           read_timeout=args.link_read_timeout, token=token)
    try:
        server.start()
    except LinkError as exc:
        print(f"{NAME}: {exc}", file=sys.stderr)
        return 2
    mapping = positional_mapping_line(model)
    if mapping:
        print(f"{NAME}: {mapping}", file=sys.stderr, flush=True)
    print(f"{NAME}: {model.source or args.robot_model}: {model.n_states} states, {model.n_actions} "
          f"actions, {model.n_observations} observations; planner {args.planner}; "
          f"observations on {server.url}", flush=True)
    policy_text = getattr(planner, "policy_text", None)
    if policy_text is not None:
        print(f"{NAME}: the reactive MDP's policy (value iteration): {policy_text()}", flush=True)
    try:
        threading.Event().wait()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
