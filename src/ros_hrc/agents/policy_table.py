"""What the robot's planner does after typical observation sequences (``hrc_pomdp policy``).

A robot model's totals (success rates, rewards) do not say whether its planner behaves: the
authors' model answers a failed grasp with ``rStop_all`` and grasps on a warning, which no
total shows. This module replays named observation sequences through the planner the robot
runs online (DESPOT, :mod:`ros_hrc.pomdp.despot`) exactly as the robot process steps it
(:class:`ros_hrc.processes.despot_pomdp.RobotAgent`): reset to the initial belief, then for
each observation the belief update with (the robot's previous action, the observation),
``rIdle`` before the first, and a decision. Each row gives the actions it took after each
observation, the last one, and the belief that the human needs help (S2..S5) and that he
warned (S6) after the last observation.

The search is bounded by a number of trials, not by time (the budget is set so large that it
never binds), from a fixed seed, each sequence from a fresh planner: the table is the same on
every machine and under any load.

The sequences name observations of the robot model (``O<bits>``, :mod:`ros_hrc.tasks.seed`):
1 object visible, 2 in range, 4 grasp attempt, 8 has object, 16 warning, 32 idle. No ROS.
"""
from __future__ import annotations

import logging
import math
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence

import numpy as np

from ros_hrc import settings, tasks
from ros_hrc.tasks import seed as task
from ros_hrc.pomdp.despot import DespotConfig, DespotPlanner, DespotTables
from ros_hrc.pomdp.model import Model
from ros_hrc.agents.policy_sequences import DEFAULT_TRIALS, SEQUENCES, ObservationSequence


@dataclass
class PolicyRow:
    """What the planner did on one sequence."""

    sequence: ObservationSequence
    actions: List[str]
    needs_help: float            # belief mass on S2..S5 after the last observation
    warned: float                # belief mass on S6 after the last observation
    zero_probability: List[str] = field(default_factory=list)  # observations it called impossible
    belief: Dict[str, float] = field(default_factory=dict)  # the whole belief after the last one

    @property
    def last_action(self) -> str:
        return self.actions[-1]

    def as_dict(self) -> dict:
        return {"name": self.sequence.name, "observations": list(self.sequence.observations),
                "what": self.sequence.what, "actions": self.actions,
                "last_action": self.last_action, "needs_help": self.needs_help,
                "warned": self.warned, "zero_probability": self.zero_probability,
                "belief": self.belief}


def despot_config(trials: int = DEFAULT_TRIALS, scenarios: int = settings.default("scenarios"),
                  depth: int = settings.default("depth"),
                  pruning: float = settings.default("lambda")) -> DespotConfig:
    """The robot's online DESPOT settings, bounded by ``trials`` per decision instead of time."""
    return DespotConfig(scenarios=scenarios, depth=depth, pruning=pruning,
                        time_per_step=math.inf, max_trials=trials)   # no time budget


def _mass(model: Model, belief: np.ndarray, states) -> float:
    return float(sum(belief[model.index("state", s)] for s in states if s in model.states))


def run_sequence(model: Model, sequence: ObservationSequence, config: DespotConfig,
                 seed: int = 0, tables: Optional[DespotTables] = None) -> PolicyRow:
    """Step a fresh planner through ``sequence`` as the robot process does."""
    planner = DespotPlanner(model, config, seed=seed, tables=tables)
    planner.reset()
    # The robot process's first update: after its task's idle action (any other model: its
    # first action).
    idle = tasks.of_robot_states(model.states).robot_idle_action
    last = model.index("action", idle) if idle in model.actions else 0
    actions: List[str] = []
    impossible: List[str] = []
    for name in sequence.observations:
        planner.update(last, model.index("observation", name))
        if planner.last_update_zero_probability:
            impossible.append(name)
        last = planner.act()
        actions.append(model.actions[last])
    belief = np.clip(np.asarray(planner.belief, dtype=float), 0.0, None)
    belief = belief / belief.sum()
    return PolicyRow(sequence, actions,
                     needs_help=_mass(model, belief, sorted(task.NEEDS_HELP_STATES)),
                     warned=_mass(model, belief, ["S6"]), zero_probability=impossible,
                     belief={s: float(p) for s, p in zip(model.states, belief)})


@contextmanager
def _quiet_planner_log():
    """The planner logs each observation of probability 0; the table names them instead."""
    logger = logging.getLogger("ros_hrc.pomdp")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def check_sequences(model: Model, sequences: Sequence[ObservationSequence]) -> None:
    """ValueError naming the first observation a sequence uses that the model lacks."""
    for seq in sequences:
        for name in seq.observations:
            if name not in model.observations:
                raise ValueError(f"sequence {seq.name}: observation {name} is not one of the "
                                 f"model's ({', '.join(model.observations)})")


def policy_table(model: Model, sequences: Sequence[ObservationSequence] = SEQUENCES,
                 config: Optional[DespotConfig] = None, seed: int = 0) -> List[PolicyRow]:
    """One row per sequence, each from a fresh planner with the same seed."""
    config = config if config is not None else despot_config()
    config.validate()
    check_sequences(model, sequences)
    tables = DespotTables(model, config.upper, config.lower)
    with _quiet_planner_log():
        return [run_sequence(model, seq, config, seed, tables) for seq in sequences]


def format_belief(belief: Dict[str, float], smallest: float = 0.005) -> str:
    """The states the belief gives at least ``smallest``, as ``S2 0.15, S3 0.75``."""
    return ", ".join(f"{state} {p:.2f}" for state, p in belief.items() if p >= smallest)


def format_table(rows: Sequence[PolicyRow], with_belief: bool = False) -> str:
    """The rows as a Markdown table: sequence, observations, actions, P(needs help), P(S6),
    and with ``with_belief`` the whole belief after the last observation."""
    head = ("| sequence | observations | planner's actions (after each) | P(needs help) | "
            "P(warned) |")
    rule = "|---|---|---|---|---|"
    if with_belief:
        head += " belief after the last |"
        rule += "---|"
    lines = [head, rule]
    for row in rows:
        note = (f" (impossible: {' '.join(row.zero_probability)})" if row.zero_probability
                else "")
        line = (f"| {row.sequence.name} | {' '.join(row.sequence.observations)} | "
                f"{' '.join(row.actions)}{note} | {row.needs_help:.2f} | {row.warned:.2f} |")
        if with_belief:
            line += f" {format_belief(row.belief)} |"
        lines.append(line)
    return "\n".join(lines)
