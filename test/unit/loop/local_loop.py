"""The whole loop in one thread, without ROS or sockets (test_fabric_loop.py).

The episode coordinator (Sans-I/O) is carried out against the real parts: the PyBullet world
(``ros_hrc.world.World``, stepped on this thread; the human's and the robot's actions called
as hrc_human calls /human/* and /robot/*), the MDP process's own step logic
(``MdpProcess.one_step``: this object stands in for its link and answers each step at once)
and the POMDP process's handlers (``PomdpProcess``, its ``RobotAgent`` with DESPOT bounded by
trials), asked as hrc_human's planner adapter asks them: an ``observation`` message in, the
``decision`` message out, taken by ``Decision.of``. What the sockets and ROS services carry
in between is not here; what the loop decides is: a run depends on the seed alone."""
from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any, List, Optional

from ros_hrc import tasks
from ros_hrc.link.protocol import Ack, Error, Observation, Reaction, Reset, Step
from ros_hrc.link.protocol import Decision as DecisionMessage
from ros_hrc.loop.coordinator import Coordinator, CoordinatorConfig
from ros_hrc.loop.effects import (ActHuman, ActRobot, Decide, Decision, Fault, MdpRefused,
                                  MdpReset, MdpStepDone, ObserveWorld, Outcome, PublishStep,
                                  ReactionRequest, ResetPlanner, ResetWorld, Snapshot, StepReport,
                                  StepRequest)
from ros_hrc.models import load_human_model, load_robot_model
from ros_hrc.streams import EpisodeSchedule
from ros_hrc.processes.despot_mdp import MdpProcess, _ResetRequested
from ros_hrc.processes.despot_pomdp import PomdpProcess, RobotAgent, build_planner
from ros_hrc.agents.human import HumanAgent, HumanAgentConfig
from ros_hrc.world import World
from ros_hrc.world.config import task_world_config
from ros_hrc.world.human import HumanConfig

PEER = "mdp"


class _Terminal:
    """The MDP process's terminal: its lines, kept."""

    def __init__(self) -> None:
        self.lines: List[str] = []

    def write(self, text: str) -> int:
        self.lines.extend(text.splitlines())
        return len(text)

    def flush(self) -> None:
        pass


class LocalLoop:
    """One stack: ``run(steps)`` plays that many MDP steps through episode resets."""

    def __init__(self, task: str, human_model: str, robot_model: str, seed: int = 0,
                 episodes: str = "1-1000", max_steps: int = 12, planner: str = "despot",
                 max_trials: int = 60, reactive_wait: float = 15.0,
                 away_time: float = 0.0) -> None:
        self.task = tasks.get(task)
        self.world = World(task_world_config(getattr(self.task, "world_facts", {}), seed=seed,
                                             human=HumanConfig(away_time=away_time)))
        human = load_human_model(human_model, self.task)
        robot = load_robot_model(robot_model, self.task)
        self.coordinator = Coordinator(CoordinatorConfig(
            task=self.task, seed=seed, human_model=human_model, max_steps=max_steps,
            on_episode_end="reset", episodes=EpisodeSchedule.parse(episodes), first_epoch=1))
        self.terminal = _Terminal()
        agent = HumanAgent(human, HumanAgentConfig(seed=seed), reaction=self.task.reaction)
        self.mdp = MdpProcess(agent, client=self, out=self.terminal, args=SimpleNamespace(
            mode="auto", seed=seed, step_delay=0.0, reply_timeout=5.0))
        args = SimpleNamespace(planner=planner, planner_options="", time_per_step=0.0, max_trials=max_trials,
                               scenarios=100, depth=30, lambda_=0.1, seed=seed,
                               reactive_budget=8, reactive_wait=reactive_wait, policy_file="",
                               task=self.task.name)
        self.robot = RobotAgent(robot, build_planner(robot, args),
                                first_action=self.task.robot_idle_action, seed=seed)
        self.pomdp = PomdpProcess(self.robot)
        self.reports: List[StepReport] = []

    def close(self) -> None:
        self.world.close()

    # -- the MDP's link ---------------------------------------------------------------------
    def send(self, msg: Any) -> None:
        """The MDP process sends a step (the coordinator plays it at once) or a reaction."""
        if isinstance(msg, Reaction):
            self.coordinator.reaction_received(PEER, ReactionRequest(
                epoch=msg.epoch, step=msg.step, state=msg.state, rule=msg.rule or "",
                reward=msg.reward or 0.0, manual=bool(msg.manual), reply=msg.id))
        else:
            assert isinstance(msg, Step), msg
            self.coordinator.step_requested(PEER, StepRequest(
                epoch=msg.epoch, step=msg.step, action=msg.action, state=msg.state,
                reward=msg.reward or 0.0, reply=msg.id))
        self._pump()

    # -- the loop ---------------------------------------------------------------------------
    def run(self, steps: int) -> List[StepReport]:
        """Play ``steps`` steps of the MDP (the coordinator resets between episodes)."""
        if self.coordinator.seat is None:
            self.coordinator.mdp_connected(PEER)
            self._pump()
            self.mdp._wait_for_reset()
        for _ in range(steps):
            # As MdpProcess.run: a step that ends the episode waits for the reset.
            try:
                if self.mdp.one_step():
                    self.mdp._wait_for_reset()
            except _ResetRequested as reset:
                self.mdp.start_episode(reset.reset)
        return self.reports

    def _pump(self) -> None:
        while True:
            effects = self.coordinator.effects()
            if not effects:
                return
            for effect in effects:
                self._carry_out(effect)

    def _carry_out(self, effect: Any) -> None:
        c = self.coordinator
        if isinstance(effect, ActHuman):
            done = self.world.run("human", effect.service, driver=True)
            c.call_done(effect.id, Outcome(done.success, done.message))
        elif isinstance(effect, ObserveWorld):
            c.call_done(effect.id, self._snapshot())
        elif isinstance(effect, Decide):
            reply = self.pomdp.on_observation(Observation(
                step=effect.step, observation=effect.observation, bits=effect.bits,
                state=effect.state, elapsed=effect.elapsed, epoch=effect.epoch), PEER)
            c.call_done(effect.id, Decision.of(reply) if isinstance(reply, DecisionMessage)
                        else Fault(f"the POMDP process refused: {reply.message}"))
        elif isinstance(effect, ActRobot):
            service = self.task.robot_action_services[effect.action]
            done = self.world.run("robot", service, driver=True)
            c.call_done(effect.id, Outcome(done.success, done.message))
        elif isinstance(effect, ResetWorld):
            if not effect.interrupt:
                self.world.reseed(effect.episode)
            # As hrc_human's reset through /hrc/world/reset: the loop's node drives the world,
            # so its reset interrupts an action under way (fabric's grasp, answered as it
            # started, may still run) instead of being refused as a bystander's call.
            done = self.world.run("world", "reset", driver=True)
            c.call_done(effect.id, Outcome(done.success, done.message))
        elif isinstance(effect, ResetPlanner):
            reply = self.pomdp.on_reset(Reset(reason="reset", episode=effect.episode,
                                              epoch=effect.epoch), PEER)
            c.call_done(effect.id, Outcome(True, reply.result))
        elif isinstance(effect, MdpReset):
            # As the link delivers it: after the answer to the step that ended the episode.
            self.mdp._events.put(("reset", Reset(reason=effect.reason, episode=effect.episode,
                                                 epoch=effect.epoch)))
        elif isinstance(effect, MdpStepDone):
            self.mdp._events.put(("reply", Ack(
                step=effect.step, of=Step.TYPE, action=effect.robot_action,
                success=effect.success, result=effect.result, episode=effect.episode,
                episode_over=effect.episode_over, end_reason=effect.end_reason or None,
                epoch=effect.epoch, reply_to=effect.reply)))
        elif isinstance(effect, MdpRefused):
            self.mdp._events.put(("reply", Error(
                message=effect.message, code=effect.code, in_reply_to=Step.TYPE,
                step=effect.step, epoch=effect.epoch, reply_to=effect.reply)))
        elif isinstance(effect, PublishStep):
            self.reports.append(effect.report)

    def _snapshot(self) -> Snapshot:
        state = self.world.state()
        return Snapshot(predicates=dict(state["predicates"]), sim_time=state["sim_time"],
                        holder=state["object"]["holder"],
                        left_belt=bool(state["object"]["left_belt"]))


def record(report: StepReport) -> list:
    """What a pinned run compares of a step: who did what, what was seen, the labels."""
    return [report.episode, report.step, report.human_action, report.human_state,
            report.reaction, report.observation_bits, report.robot_observation,
            report.observation_noise,
            report.robot_state, report.robot_action, report.robot_acted, report.object_holder,
            report.end_reason, report.fault]
