"""despot_pomdp: the robot's decision process (no ROS; it speaks only websocket).

It loads the robot POMDP (checked against the states, actions and observations of the task,
``--task``: :mod:`ros_hrc.tasks`) and keeps the robot's belief. It is a websocket **server**
on port 7070 for the coordinator (``hrc_human``). For each ``observation``: update the
belief with the robot's previous action and the observation (the task's idle action before
the first step, ``rIdle`` for the seed: the robot starts idle), plan (DESPOT by default, a
saved offline policy, a baseline robot of ``ros_hrc.agents.robots``: the reactive robot
or no robot, which keep the belief but decide without it, or a planner of the user's own
package: ``planner:=`` is any name of :mod:`ros_hrc.registry`, docs/extending.md), and answer
with a ``decision``.
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

**A robot model of human types** (:mod:`ros_hrc.pomdp.typed`: states ``<state>__<type>``) is
planned on like any model. Its decisions still carry the belief over the task's states (the
types summed out), so every reader of a decision's belief works unchanged, and with it the
belief over the types (``type_names``, ``type_belief``); the terminal prints both each step.

**A sequence of tasks** (``tasks:=N``; docs/sequences.md): each task starts with a reset that
names it (``task_index``). With ``selector:=fixed`` (the default) the one planner runs every
task, as above. With any other selector the process loads the policy library at start
(:mod:`ros_hrc.processes.selection`; one line per policy), builds one planner per policy, and
at each reset that starts a new task asks its selector for the policy and switches to that
policy's planner (a task cut short and played again keeps its policy). During a task it keeps
each observation's signature code (:func:`ros_hrc.agents.selectors.signature_code`) and the
policy's own discounted reward over the true states the coordinator reports; the task's
``task_end`` is answered with a ``task_report`` (the selector, the policy, its belief over
the human types after learning from the task, the signature; a selector without a type
belief, e.g. ``fixed``, reports the belief of a robot model of types instead). A robot model
of types carries its type belief from task to task: a new task (``task_index`` above 1)
starts from the model's initial belief with the type prior
``mix_with_uniform(type belief at the last task's end, bpr_forgetting)``; task 1 (a new
sequence) and a reset outside a sequence start from the model's own prior, and a task cut
short and played again from the prior it started with.

A ``configure`` (a warm stack's next cell: ``/hrc/configure`` of the human node) makes it read
the launch's settings again and rebuild what it built at start, the robot model, planner,
selector and library, with no epoch; a setting it cannot take in place (its port, its task)
is refused and nothing changes.

It serves only processes of its own launch: a client must prove the launch's link token in its
hello (``--link-session``, given by hrc.launch; by hand ``--token-file PATH`` or
``HRC_LINK_TOKEN_FILE``; :mod:`ros_hrc.link.token`). Under hrc.launch its options are the
launch's resolved settings, which the pre-flight wrote beside the token (every path absolute);
an option on its command line wins (:func:`ros_hrc.command_line.parse_launch_options`). A
relative ``--model`` or ``--policy`` given by hand is taken from the directory it runs in.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from ros_hrc import tasks
from ros_hrc.command_line import reread_launch_options
from ros_hrc.errors import HrcError, LinkError
from ros_hrc.registry import RegistryError
from ros_hrc.link.protocol import (ERR_INVALID, ERR_STALE, Ack, Configure, Decision,
                                   DispatchTable, Message, Observation, Reset, TaskEnd,
                                   TaskReport, reply_error)
from ros_hrc.link.transport import MessageServer, Peer
from ros_hrc import settings
from ros_hrc.models import load_robot_model, positional_mapping_line
from ros_hrc.models import shown_path as shown_model
from ros_hrc.streams import next_episode, stream_seed
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.planner import Planner, planner_class
from ros_hrc.pomdp.type_names import ranked_types
from ros_hrc.pomdp.typed import TypeLayout
from ros_hrc.agents.learning import LearntFigure, LearntHuman, planning_of, selector_of
from ros_hrc.pomdp.bayes_adaptive import LookBonus
from ros_hrc.agents.selectors import Selector, TaskResult, mix_with_uniform, signature_code
from ros_hrc.processes.solver_process import CANNOT_START, solver_parser, start_solver
from ros_hrc.processes.selection import Selection, load_selection, new_selector, uses_library
from ros_hrc.tasks.definition import Task
from ros_hrc.tasks.schedule import nearest_type

NAME = "despot_pomdp"


class RobotAgent:
    """The robot's belief and planner, stepped by observation names. ``seed``: the run's seed,
    from which each episode's planner stream is derived. A model of human types
    (:mod:`ros_hrc.pomdp.typed`) has a ``layout``: its belief is then over (type, state), and
    the agent tells the task-state part (:meth:`task_belief`) from the type part
    (:attr:`type_belief`)."""

    def __init__(self, model: Model, planner: Planner, first_action: str = "rIdle",
                 seed: int = 0, reports_types: bool = True,
                 bonus: Optional[LookBonus] = None) -> None:
        self.model = model
        self.planner = planner
        #: The learning robot's exploration bonus for this task (its states the task's: with
        #: types, every type's block takes the same), or None.
        self.bonus = bonus
        self.seed = seed
        self.layout = TypeLayout.of(model)
        #: Whether its hidden types are human types worth reporting (a learning robot's
        #: root-sampled model has draws there, which mean nothing beyond the task).
        self.reports_types = reports_types and self.layout is not None
        #: The (action, observation) indices of the belief updates since the last reset.
        self.history: List[Tuple[int, int]] = []
        self.episode: Optional[int] = None
        self.first_action = model.index("action", first_action) if first_action in model.actions else 0
        self.reset()

    def reset(self, episode: Optional[int] = None, belief: Optional[np.ndarray] = None) -> None:
        """Back to ``belief`` (the model's initial belief when not given); for ``episode``
        (when given), the planner draws from that episode's stream, from its start."""
        if episode is not None:
            self.planner.reseed(stream_seed(self.seed, episode, "planner"))
            self.episode = episode
        self.planner.reset(belief)
        self.last_action = self.first_action
        self.surprises = 0
        self.history = []

    def step(self, observation: str, elapsed: Optional[float] = None):
        """Belief update with (previous action, observation), then plan: (action, ms, note).
        ``elapsed``: the simulated seconds since the episode's reset (None: unknown), for a
        planner that counts time (``reads_time``: the fabric reactive robot)."""
        o = self.model.index("observation", observation)
        note = ""
        self.planner.observe_time(elapsed)
        started = time.perf_counter()
        self.history.append((self.last_action, o))
        self.planner.update(self.last_action, o)
        if self.planner.last_update_zero_probability:
            self.surprises += 1
            note = (f"observation {observation} has probability 0 after "
                    f"{self.model.actions[self.last_action]}: the belief keeps the "
                    "prediction without it")
        if self.bonus is not None:
            per_state = self.bonus.per_state()
            if self.layout is not None:
                per_state = np.tile(per_state, len(self.layout.types))
            self.planner.root_bonus = (self.bonus.action, per_state)
        action = self.planner.act()
        if self.bonus is not None and action == self.bonus.action:
            self.bonus.looked(self.task_belief()[1])
        decision_ms = (time.perf_counter() - started) * 1000.0
        self.last_action = action
        return action, decision_ms, note

    @property
    def belief(self) -> np.ndarray:
        """The planner's belief over the model's states (with types: over (type, state))."""
        b = np.clip(np.asarray(self.planner.belief, dtype=float), 0.0, None)
        return b / b.sum()

    def task_belief(self) -> Tuple[List[str], np.ndarray]:
        """(state names, probabilities) over the task's states: the belief itself, or with
        types the types summed out (what every reader of a decision's belief expects)."""
        if self.layout is None:
            return list(self.model.states), self.belief
        return list(self.layout.states), self.layout.state_marginal(self.belief)

    @property
    def type_belief(self) -> Optional[np.ndarray]:
        """P(type) in the order of ``layout.types`` (None: a model of no types, or of types
        not worth reporting)."""
        return self.layout.type_marginal(self.belief) if self.reports_types else None

    def expected_reward(self, state: str, action: int) -> Optional[float]:
        """R(state, action) of a true state named as the task names it (None: a state the
        model lacks). With types, the reward expected under the current type belief:
        Σ_t P(t) R(state@t, action)."""
        if state in self.model.states:
            return float(self.model.R_sa[action, self.model.states.index(state)])
        if self.layout is None or state not in self.layout.states:
            return None
        at = self.layout.states.index(state)
        per_type = self.layout.blocks(self.model.R_sa[action])[:, at]
        return float(self.layout.type_marginal(self.belief) @ per_type)


@dataclass
class TaskRecord:
    """The task under way of a sequence: its number, the policy running it, the belief it
    started from (None: the model's initial belief; a task played again starts from it
    again), each step's signature code and the policy's own discounted reward so far;
    ``ended`` once its end was reported (a reset into the same number then starts a new
    sequence's task, not the same task again)."""
    index: int
    policy: str
    start_belief: Optional[np.ndarray] = None
    signature: List[int] = field(default_factory=list)
    reward: float = 0.0
    ended: bool = False


class SequenceRobot:
    """The robot across the tasks of a sequence: one agent per policy (``agents``, by name:
    the library's, or the launch's one robot under ``selector:=fixed``), the selection a
    selector is made from (None: ``fixed``, the one agent every task), and what the task under
    way recorded. ``robot_models``: each policy's robot model file ("" for none).

    An agent whose model has human types carries its type belief from task to task: the
    belief at the end of its last task, mixed with uniform by ``forgetting`` (the BPR
    selectors' floor, so a switched human is found again), is the type prior of its next
    task in the sequence; the first task of a sequence starts from the model's own prior."""

    def __init__(self, task: Task, agents: Mapping[str, RobotAgent],
                 robot_models: Mapping[str, str], selection: Optional[Selection] = None,
                 seed: int = 0, forgetting: float = 0.0,
                 learner: Optional[LearntHuman] = None,
                 new_planner=None) -> None:
        self.task = task
        #: The learning robot's model of its human (None: a robot that does not learn), and
        #: how a planner is made for the model it plans each task on.
        self.learner = learner
        self.new_planner = new_planner
        self.learn_ms = 0.0
        #: What the learnt model says now (None: no learner, or a task without the figure).
        self.figure: Optional[LearntFigure] = learner.figure() if learner is not None else None
        self.agents = dict(agents)
        self.robot_models = dict(robot_models)
        self.selection = selection
        self.seed = seed
        self.forgetting = forgetting
        self.selector: Optional[Selector] = None
        self.record: Optional[TaskRecord] = None
        self.tasks_ended = 0
        #: Policy name -> its agent's type belief at the end of its last task of this sequence.
        self.type_belief_at_end: Dict[str, np.ndarray] = {}

    @property
    def name(self) -> str:
        """The selector's name (``fixed`` for the launch's one robot)."""
        if self.selector is not None:
            return self.selector.name
        if self.selection is not None:
            return self.selection.spec
        return selector_of(self.learner.planning) if self.learner is not None else "fixed"

    @property
    def task_policy(self) -> Optional[str]:
        """The policy that decides the task under way (None: no task has started)."""
        return self.record.policy if self.record is not None else None

    def start_task(self, index: int, episode: int, true_type: str) -> str:
        """A reset starts task ``index`` (of episode ``episode``; its human ``true_type``):
        the policy that runs it (chosen now for a new task; kept for a task played again),
        and in ``record.start_belief`` the belief its agent starts from."""
        again = self.record is not None and self.record.index == index and \
            not self.record.ended
        if again:
            self.record = TaskRecord(index, self.record.policy, self.record.start_belief)
            return self.record.policy
        if index == 1:
            self.type_belief_at_end.clear()    # a new sequence: nothing carried over
        if self.selection is None:
            policy = next(iter(self.agents))
            if self.learner is not None:
                self._plan_on_posterior(policy, index, episode)
        else:
            if self.selector is None or index == 1:
                # A new sequence (its first task): a fresh selector on its own stream.
                self.selector = new_selector(self.selection, self.seed, episode,
                                             self.forgetting)
                self.tasks_ended = 0
            if true_type:
                self.selector.tell_true_type(nearest_type(true_type))
            policy = self.selector.choose()
        self.record = TaskRecord(index, policy, self._start_belief(policy))
        return policy

    def _plan_on_posterior(self, policy: str, index: int, episode: int) -> None:
        """The learning robot's new task: back to its prior for a new sequence (the draws'
        stream of (seed, the sequence's first episode, "learning")), then an agent on the
        model the posterior gives for this task."""
        learner = self.learner
        if index == 1:
            learner.restart(stream_seed(self.seed, episode, "learning"))
            # Back to the prior: its figure. Between tasks the posterior is the one the last
            # task's end learnt, whose figure end_task took (a figure costs ~7 ms).
            self.figure = learner.figure()
        model = learner.model_for_task()
        self.agents[policy] = RobotAgent(model, self.new_planner(model), seed=self.seed,
                                         first_action=self.task.robot_idle_action,
                                         reports_types=False, bonus=learner.look_bonus())

    def _start_belief(self, policy: str) -> Optional[np.ndarray]:
        """The belief ``policy``'s agent starts a new task from: the type belief it ended its
        last task with, mixed with uniform, as the prior; None (the model's initial belief)
        for a model of no types or an agent that ended no task of this sequence yet."""
        agent = self.agents[policy]
        at_end = self.type_belief_at_end.get(policy)
        if agent.layout is None or at_end is None:
            return None
        return agent.layout.with_type_prior(agent.model.initial_belief,
                                            mix_with_uniform(at_end, self.forgetting))

    def note_step(self, bits: int, state: str, action: int) -> None:
        """One step of the task under way: the robot saw ``bits`` while the true state was
        ``state`` and chose ``action``."""
        record = self.record
        if record is None:
            return
        record.signature.append(signature_code(bits, self.task))
        agent = self.agents[record.policy]
        reward = agent.expected_reward(state, action)
        if reward is not None:
            step = len(record.signature) - 1
            record.reward += agent.model.discount ** step * reward

    def end_task(self, msg: TaskEnd) -> TaskReport:
        """The task ``msg`` names ended: the selector learns from it; the report."""
        record = self.record
        if record is None or record.index != msg.task_index:
            raise ValueError(f"task {msg.task_index} is not the task under way "
                             f"({record.index if record else 'none'})")
        names: tuple = ()
        belief: tuple = ()
        if self.selector is not None:
            self.selector.observe(TaskResult(record.policy, tuple(record.signature),
                                             msg.utility))
            names = tuple(self.selector.type_names)
            belief = tuple(float(p) for p in self.selector.belief())
        agent = self.agents[record.policy]
        if self.learner is not None:
            started = time.perf_counter()
            self.learner.learn(agent.history, agent.last_action,
                               succeeded=msg.outcome == "success")
            self.learn_ms = (time.perf_counter() - started) * 1000.0
            self.figure = self.learner.figure()
        if agent.reports_types:
            self.type_belief_at_end[record.policy] = agent.type_belief
            if not names:    # the selector's own type belief, when it has one, is the report's
                names = agent.layout.types
                belief = tuple(float(p) for p in agent.type_belief)
        self.tasks_ended += 1
        record.ended = True
        return TaskReport(selector=self.name, policy=record.policy,
                          robot_model=self.robot_models.get(record.policy) or None,
                          type_names=list(names) or None, type_belief=list(belief) or None,
                          signature=list(record.signature),
                          total_disc_reward=record.reward,
                          **figure_fields(self.figure))


class PomdpProcess:
    """The 7070 server's handlers: an observation in, a decision out; a reset into an epoch.

    The belief belongs to the epoch it was last reset into. An observation of another epoch
    is refused, never applied: after a restart this process has no epoch at all, so the
    coordinator learns that the belief it relied on is gone and resets the loop."""

    def __init__(self, agent: RobotAgent, sequence: Optional[SequenceRobot] = None,
                 args: Optional[argparse.Namespace] = None,
                 argv: Optional[Sequence[str]] = None) -> None:
        self.agent = agent
        #: The robot across a sequence's tasks (None: this process plays no sequence).
        self.sequence = sequence
        #: The options it was built from, and its command line (a ``configure`` reads the
        #: launch's settings again with it).
        self.args = args
        self.argv = argv
        self.epoch: Optional[int] = None
        self.dispatch = DispatchTable(NAME)
        self.dispatch.on(Observation, self.on_observation)
        self.dispatch.on(Reset, self.on_reset)
        self.dispatch.on(TaskEnd, self.on_task_end)
        self.dispatch.on(Configure, self.on_configure)
        self._said_no_time = False

    def on_configure(self, msg: Configure, peer: Peer) -> Message:
        """Start again from the launch's settings as they are now (a warm stack's next cell),
        as a freshly started process would: the robot model, the planner, the selector and
        its library, the seed; no epoch (the next reset names one). A refusal changes
        nothing."""
        if self.args is None:
            return reply_error(msg, f"{NAME} was not started from a launch's settings: "
                                    "nothing to read again", ERR_INVALID)
        try:
            args = reread_launch_options(build_parser(), self.argv, self.args)
            model, planner, sequence = build_robot(args)
        except (HrcError, OSError, ValueError) as exc:
            return reply_error(msg, f"{NAME} not configured: {exc}", ERR_INVALID)
        self.args, self.sequence = args, sequence
        self.agent = next(iter(sequence.agents.values()))
        self.epoch = None
        self._said_no_time = False
        line = robot_line(model, planner, args)
        print(f"\n##### CONFIGURE ({msg.reason or 'configure'}): {line} #####", flush=True)
        return Ack(step=0, of=msg.type, result=line, reply_to=msg.id)

    def on_reset(self, msg: Reset, peer: Peer) -> Message:
        # The coordinator names the episode (0 is one); a reset without a number (a client of
        # the protocol's own) starts the next.
        episode = msg.episode if msg.episode is not None else next_episode(self.agent.episode)
        start: Optional[np.ndarray] = None
        if msg.task_index is not None and self.sequence is not None:
            policy = self.sequence.start_task(msg.task_index, episode, msg.true_type or "")
            self.agent = self.sequence.agents[policy]
            start = self.sequence.record.start_belief
            note = self.sequence.selector.note if self.sequence.selector is not None else ""
            print(f"\n##### TASK {msg.task_index}: selector {self.sequence.name} chose policy "
                  f"{policy}{'; ' + note if note else ''} #####", flush=True)
        self.agent.reset(episode, start)
        self.epoch = msg.epoch
        which = "the initial belief" if start is None else "the type prior carried over"
        print(f"\n##### RESET: belief back to {which} (episode {msg.episode}, "
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
        if self.sequence is not None:
            self.sequence.note_step(msg.bits, msg.state, action)
        states, belief = self.agent.task_belief()
        type_belief = self.agent.type_belief
        at = f" at {msg.elapsed:.1f} s" if msg.elapsed is not None else ""
        print(f"\n-----Step {msg.step}-----\n- Observation = {msg.observation} "
              f"(bits {msg.bits}){at}; true state (not seen) = {msg.state}", flush=True)
        if msg.elapsed is None and self.agent.planner.reads_time and not self._said_no_time:
            self._said_no_time = True
            print(f"{NAME}: observations carry no time (elapsed): the reactive robot's wait "
                  "(rule waited) cannot apply", file=sys.stderr, flush=True)
        if note:
            print(f"- NOTE: {note}", flush=True)
        # The reactive robot says which of its rules chose the action (and the MDP state).
        rule = self.agent.planner.last_rule
        mdp_state = self.agent.planner.mdp_state
        why = (f"rule {rule}, " if rule else "") + (f"MDP state {mdp_state}, " if mdp_state else "")
        # How far a search went (trials, deepest node), for a planner that searches.
        stats = self.agent.planner.last_stats
        searched = (f", {stats.trials} trials, depth {stats.depth}"
                    if stats.trials else "")
        print(f"- Belief:\n{self._belief_text()}\n- Action = {model.actions[action]} "
              f"({why}{decision_ms:.1f} ms{searched})", flush=True)
        # Why it chose: the value of each action the planner compared (none from a baseline).
        values = sorted(stats.action_values.items())
        layout = self.agent.layout
        return Decision(step=msg.step, action=model.actions[action], belief=belief.tolist(),
                        belief_states=states, decision_ms=decision_ms,
                        surprise=bool(note), rule=rule or None,
                        action_names=[model.actions[a] for a, _ in values] or None,
                        action_values=[v for _, v in values] or None,
                        type_names=list(layout.types) if type_belief is not None else None,
                        type_belief=type_belief.tolist() if type_belief is not None else None,
                        **figure_fields(self.sequence.figure if self.sequence else None),
                        policy=self.sequence.task_policy if self.sequence else None,
                        epoch=msg.epoch, reply_to=msg.id)

    def on_task_end(self, msg: TaskEnd, peer: Peer) -> Message:
        """A task of the sequence ended: the selector learns from it; the task's report."""
        if self.sequence is None:
            return reply_error(msg, f"{NAME} plays no sequence", ERR_INVALID)
        try:
            report = self.sequence.end_task(msg)
        except ValueError as exc:
            return reply_error(msg, str(exc), ERR_INVALID)
        belief = ranked_types(report.type_names or (), report.type_belief or (), limit=3)
        print(f"\n##### TASK {msg.task_index} over: {msg.outcome}, utility {msg.utility:.2f}; "
              f"policy {report.policy}{'; belief ' + belief if belief else ''} #####",
              flush=True)
        if self.sequence.figure is not None:
            print(f"- Learnt: {figure_text(self.sequence.figure)} (learnt from the task in "
                  f"{self.sequence.learn_ms:.1f} ms)", flush=True)
        return dataclasses.replace(report, epoch=msg.epoch, reply_to=msg.id)

    def _belief_text(self) -> str:
        """The belief over the task's states, one line each, and a model of types' belief
        over the types."""
        states, b = self.agent.task_belief()
        lines = [f"  {s} = {p:.4f}" for s, p in zip(states, b) if p > 0]
        type_belief = self.agent.type_belief
        if type_belief is not None:
            lines.append(f"- Type belief: {ranked_types(self.agent.layout.types, type_belief)}")
        figure = self.sequence.figure if self.sequence is not None else None
        if figure is not None:
            lines.append(f"- Learnt: {figure_text(figure)}")
        return "\n".join(lines)


def figure_fields(figure: Optional[LearntFigure]) -> Dict[str, object]:
    """A decision's or a task report's fields of the learnt model's figure (none without)."""
    if figure is None:
        return {}
    return {"learnt_name": figure.name, "learnt_value": figure.value,
            "learnt_spread": figure.spread}


def figure_text(figure: LearntFigure) -> str:
    """The figure in one line: ``P(...) = 0.42 +- 0.08``."""
    return f"{figure.name} = {figure.value:.2f} \u00b1 {figure.spread:.2f}"


def build_planner(model: Model, args: argparse.Namespace) -> Planner:
    """The planner the command line asks for (``--planner``: a registered name or
    ``module:Class``, :func:`ros_hrc.pomdp.planner.planner_class`), made from the options
    (:meth:`ros_hrc.pomdp.planner.Planner.from_settings`). Raises ValueError (one line)."""
    try:
        kind = planner_class(args.planner)
        own = kind.checked_options(settings.planner_option_values(args.planner_options))
    except RegistryError as exc:
        raise ValueError(f"--planner {args.planner}: {exc.reason}") from None
    except ValueError as exc:
        raise ValueError(f"--planner-options {args.planner_options}: {exc}") from None
    return kind.from_settings(model, tasks.get(args.task), {**planner_settings(args), **own})


def planner_settings(args: argparse.Namespace) -> Dict[str, object]:
    """The options as a planner reads them: setting name -> value (``lambda`` for argparse's
    ``lambda_``), with a library policy's own options among them."""
    values = dict(vars(args))
    values["lambda"] = values.pop("lambda_", settings.default("lambda"))
    return values


def build_parser() -> argparse.ArgumentParser:
    p = solver_parser(NAME, "The robot's POMDP planner: a websocket server answering each "
                      "observation with a decision.", "robot_model", "pomdp_port")
    settings.add_argument(p, "link_read_timeout")
    settings.add_argument(p, "planner")
    settings.add_argument(p, "planner_options")
    settings.add_argument(p, "policy_file", "--policy")
    settings.add_argument(p, "reactive_budget")
    settings.add_argument(p, "reactive_wait")
    settings.add_argument(p, "time_per_step")
    settings.add_argument(p, "scenarios")
    settings.add_argument(p, "depth")
    settings.add_argument(p, "lambda", "--lambda", dest="lambda_")
    settings.add_argument(p, "max_trials")
    settings.add_argument(p, "selector")
    settings.add_argument(p, "library")
    settings.add_argument(p, "selector_model")
    settings.add_argument(p, "bpr_forgetting")
    for name in settings.LEARNING_SETTINGS:
        settings.add_argument(p, name)
    return p


def fixed_policy_name(args: argparse.Namespace) -> str:
    """What the reports call the launch's one robot (``selector:=fixed``): its model's name
    for a planner that plans on it, else the planner's name (reactive, none, explore)."""
    if planner_class(args.planner).plans_on_model:
        return Path(str(args.robot_model)).stem
    return args.planner


def policy_arguments(args: argparse.Namespace, settings_of_policy: Mapping[str, object]
                     ) -> argparse.Namespace:
    """The command line's options with a library policy's settings (its planner, robot model
    and options) in their place."""
    values = dict(vars(args))
    values["planner_options"] = ""     # the launch's are its planner's; the policy's its own
    for name, value in settings_of_policy.items():
        values["lambda_" if name == "lambda" else name] = value
    return argparse.Namespace(**values)


def build_sequence_robot(task: Task, model: Model, planner: Planner, args: argparse.Namespace
                         ) -> SequenceRobot:
    """The robot of a sequence: under ``selector:=fixed`` the launch's one agent; otherwise
    the library's policies, one agent (and planner) each, built now. Raises HrcError or
    ValueError (one line)."""
    first = task.robot_idle_action
    planning = planning_of(args.selector)
    if planning is not None:
        # The learning robot: the launch's robot model is its prior; the planner is made
        # again for each task's model (build_planner with the launch's options).
        problem = settings.learning_planner_problem(args.selector, args.planner)
        if problem:
            raise ValueError(f"selector:={args.selector} {problem}")
        learner = LearntHuman(model, task, args.learning_strength, args.learning_forgetting,
                              planning, args.learning_draws,
                              seed=stream_seed(args.seed, 0, "learning"),
                              bonus=task.learning_bonus if args.learning_bonus is None
                              else args.learning_bonus)
        name = fixed_policy_name(args)
        # Until the first task's reset, the agent is the prior's: each task then gets an
        # agent on the model the posterior gives for it (_plan_on_posterior).
        agent = RobotAgent(model, planner, first_action=first, seed=args.seed)
        robot = SequenceRobot(task, {name: agent}, {name: model.source or ""}, seed=args.seed,
                              learner=learner,
                              new_planner=lambda m: build_planner(m, args))
        print(f"{NAME}: selector {args.selector}: learns its human from the prior "
              f"{shown_model(model.source or args.robot_model)}, strength "
              f"{learner.strength:g}, forgetting {learner.forgetting:g}"
              + (f", exploration bonus {learner.bonus:g}" if learner.bonus else "")
              + (f", {learner.draws} posterior draws a task" if planning == "sampled" else
                 ", the posterior mean"), flush=True)
        return robot
    if not uses_library(args.selector):
        name = fixed_policy_name(args)
        agent = RobotAgent(model, planner, first_action=first, seed=args.seed)
        acts_by = planner.acts_by(task) or model.source
        # The forgetting a model of human types carries its type belief across tasks with.
        return SequenceRobot(task, {name: agent}, {name: acts_by or ""}, seed=args.seed,
                             forgetting=args.bpr_forgetting)
    selection = load_selection(args.selector, args.library, args.selector_model, task)
    agents: Dict[str, RobotAgent] = {}
    files: Dict[str, str] = {}
    for policy in selection.library.policies:
        pargs = policy_arguments(args, policy.settings())
        # A planner without a model of its own (the reactive robot) keeps the launch's
        # model for its belief, as planner:=reactive does.
        pmodel = model if policy.robot_model is None else load_robot_model(
            str(policy.robot_model), task)
        agents[policy.name] = RobotAgent(pmodel, build_planner(pmodel, pargs),
                                         first_action=first, seed=args.seed)
        # What the reports name as its model: its file; the reactive robot's own (its MDP's
        # file, or its name), not the belief model it keeps.
        files[policy.name] = str(policy.robot_model) if policy.robot_model is not None else (
            agents[policy.name].planner.acts_by(task) or "")
        options = ", ".join(f"{k} {v}" for k, v in policy.options.items())
        print(f"{NAME}: policy {policy.name}: planner {policy.planner}"
              f"{', ' + shown_model(policy.robot_model) if policy.robot_model else ''}"
              f"{', ' + options if options else ''}", flush=True)
    model_line = (f"selector model {shown_model(selection.model.path)}" if selection.model
                  is not None and selection.model.path else "no selector model")
    print(f"{NAME}: selector {args.selector} over {len(agents)} policies of "
          f"{shown_model(selection.library.manifest)}; {model_line}", flush=True)
    return SequenceRobot(task, agents, files, selection, seed=args.seed,
                         forgetting=args.bpr_forgetting)


def build_robot(args: argparse.Namespace) -> Tuple[Model, Planner, SequenceRobot]:
    """The robot the options ask for: its model (checked against the task), its planner
    and the robot across a sequence's tasks (the library's agents under a selector). Raises
    HrcError, OSError or ValueError (one line)."""
    task = tasks.get(args.task)
    model = load_robot_model(args.robot_model, task)
    planner = build_planner(model, args)
    return model, planner, build_sequence_robot(task, model, planner, args)


def robot_line(model: Model, planner: Planner, args: argparse.Namespace) -> str:
    """What the process plays, in one line: the model, its size and the planner."""
    return (f"{model.source or args.robot_model}: {model.n_states} states, {model.n_actions} "
            f"actions, {model.n_observations} observations; planner {args.planner}, seed "
            f"{args.seed}")


def main(argv: Optional[list] = None) -> int:
    started = start_solver(NAME, build_parser(), argv, build_robot)
    if started is None:
        return CANNOT_START
    args, (model, planner, sequence), token = started
    process = PomdpProcess(next(iter(sequence.agents.values())), sequence, args, argv)
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
    print(f"{NAME}: {robot_line(model, planner, args)}; observations on {server.url}",
          flush=True)
    policy_text = planner.policy_text()
    if policy_text is not None:
        print(f"{NAME}: {policy_text}", flush=True)
    try:
        threading.Event().wait()
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
