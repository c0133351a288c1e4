#!/usr/bin/env python3
"""Write FABRIC's model files (the seed authors' successor task) from the authors' figures.

    python tools/make_fabric_models.py --out models/fabric

rewrites ``human/*.pomdpx`` (the ten human types, 12-state MDPs) and ``robot/*.pomdpx`` (the
base robot POMDP, eleven of its twelve policy variants, and the reactive robot MDP) under
``--out``. (The authors' policy2 is not in the repository index we read: models/README.md.)
The output is deterministic: a rerun writes the same bytes (a test checks the shipped files).

Where the figures come from: the GitHub repository ``cangorur/human_robot_collaboration``
(GPL-3.0; the task names its master, c0e027d), the file and commit each table file names; the
papers are Görür et al., "Social Cobots", HRI 2018, and ACM THRI 2023 (DOI 10.1145/3585276).
Only numbers are taken (probabilities, rewards, discounts: facts); the tables are our own
layout and the files are written by the package's own POMDPX writer. ``models/README.md``
("FABRIC (the successor task)") says file by file what was taken and what was changed.

The tables are TOML files in ``tools/fabric_tables/``, one per file written: ``human/<type>``,
``robot/base``, ``robot/policyN`` (the rows and rewards the policy changes in the base) and
``robot/reactive``. TOML, because a row of probabilities reads best as a one-line array under
its state's name (``TaskHuman = [0.2, 0.09, ...]``), aligned in columns like the authors'
tables, with comments that credit the source and name the columns, and a model's source,
discount, start and rewards beside its tables in one file (CSV has no comments and one
table a file, JSON no comments); ``tomllib`` (standard library) reads it and itself refuses a
repeated state or a malformed number.

A file names its source (``repository``, ``file``, ``commit``: the written file's comment),
then ``discount`` and ``start`` (but a policy's), ``rewards`` and a ``[T.<action>]`` table per
action (and ``[O]`` for the robot). A table line gives a *current* state, in the model's state
order, the probabilities of the next states in that order: 11 numbers in a human's row, every
state but ``TaskRobot`` (which the authors give 0 in every row a human leaves; 12 in
TaskRobot's own row); ``"stay"`` is 0.9 on the current state and 0.01 on each other column the
row spans (the authors' most common row); a state without a line keeps its state. Rewards are
[action, next state, value], ``*`` meaning every one, a later entry overriding an earlier one
(as in POMDPX); a reward is earned on arriving in the next state, whatever the state left (the
authors' files reward ``R(action, state_1)``).

ROS-free: only numpy, scipy and ros_hrc.pomdp (the names from ros_hrc.tasks).
"""
from __future__ import annotations

import argparse
import sys
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp

REPO = Path(__file__).resolve().parents[1]
if str(REPO / "src") not in sys.path:       # run from a checkout without an installed package
    sys.path.insert(0, str(REPO / "src"))

from ros_hrc.pomdp import pomdpx  # noqa: E402
from ros_hrc.pomdp.model import Model  # noqa: E402
from ros_hrc.pomdp.output import write_text_atomically  # noqa: E402
from ros_hrc.tasks.fabric import FABRIC  # noqa: E402
from ros_hrc.tasks.fabric_reactive import MDP_STATES  # noqa: E402

TABLES = Path(__file__).resolve().parent / "fabric_tables"
STAY = 0.9                  # a "stay" row: this on the current state ...
FLOOR = FABRIC.model_floor  # ... and this on every other column the row spans

HUMAN_STATES = list(FABRIC.human_states)
HUMAN_ACTIONS = list(FABRIC.human_actions)
#: A human row spans every state but TaskRobot, unless it is TaskRobot's own.
HUMAN_SPANS = [i for i, s in enumerate(HUMAN_STATES) if s != "TaskRobot"]
ROBOT_STATES = list(FABRIC.robot_states)
ROBOT_ACTIONS = list(FABRIC.robot_actions)
#: The authors' files number the 12 observations; the task names them after the bits they
#: stand for (docs/tasks_fabric_facts.md).
ROBOT_OBSERVATIONS = list(FABRIC.observations.names)
REACTIVE_STATES = list(MDP_STATES)
REACTIVE_ACTIONS = ["idle", "grasp", "cancel"]

Figures = Dict[str, Any]     # one table file, as tomllib reads it


@dataclass
class Notes:
    """What the builder changed in the authors' figures (printed, and checked by the tests)."""
    normalised: List[str] = field(default_factory=list)


def read_figures(relative: str) -> Figures:
    """The table file ``tools/fabric_tables/<relative>.toml``."""
    with open(TABLES / f"{relative}.toml", "rb") as stream:
        return tomllib.load(stream)


def table_rows(table: Mapping[str, Any], states: Sequence[str], width: int,
               spans: Sequence[int], label: str) -> Dict[str, np.ndarray]:
    """A table's lines as {state: row of ``width`` numbers}: each gives either ``"stay"`` or
    the numbers of the columns ``spans`` (the rest are 0), or all ``width`` numbers. Lines
    must follow the model's state order."""
    rows: Dict[str, np.ndarray] = {}
    last = -1
    for name, value in table.items():
        if name not in states:
            raise ValueError(f"{label}: unknown state {name!r}")
        if states.index(name) <= last:
            raise ValueError(f"{label}: {name} is out of order")
        last = states.index(name)
        row = np.zeros(width)
        if value == "stay":
            row[list(spans)] = FLOOR
            row[last] = STAY
        elif isinstance(value, list) and len(value) in (len(spans), width):
            row[list(spans) if len(value) == len(spans) else slice(None)] = value
        else:
            raise ValueError(f"{label}: {name} is {value!r}, not \"stay\" or a list of "
                             f"{len(spans)} or {width} numbers")
        rows[name] = row
    return rows


def action_rows(tables: Mapping[str, Any], states: Sequence[str], actions: Sequence[str],
                spans: Sequence[int], label: str) -> Dict[str, Dict[str, np.ndarray]]:
    """Every ``[T.<action>]`` table's rows, {action: {state: row}}."""
    unknown = sorted(set(tables) - set(actions))
    if unknown:
        raise ValueError(f"{label}: unknown actions {unknown}")
    return {a: table_rows(t, states, len(states), spans, f"{label} T {a}")
            for a, t in tables.items()}


def transition_tables(states: Sequence[str], actions: Sequence[str],
                      rows: Mapping[str, Mapping[str, np.ndarray]], notes: Notes,
                      label: str) -> List[sp.csr_matrix]:
    """T[a] from the given rows; a state without a row keeps its state. A row that does not
    sum to one (beyond float rounding) is normalised and noted."""
    out = []
    for action in actions:
        T = np.eye(len(states))
        for name, row in rows.get(action, {}).items():
            T[states.index(name)] = _normalised(row, f"{label} T {action} {name}", notes)
        out.append(sp.csr_matrix(T))
    return out


def _normalised(row: np.ndarray, label: str, notes: Notes) -> np.ndarray:
    total = float(row.sum())
    if abs(total - 1.0) <= 1e-9:
        return row
    notes.normalised.append(f"{label}: sums to {total:g}, divided by it")
    return row / total


def reward_tables(states: Sequence[str], actions: Sequence[str],
                  entries: Sequence[Sequence[Any]]) -> List[sp.csr_matrix]:
    """R[a][s, s'] from [action, next state, value] entries, ``*`` for every one, later entries
    overriding earlier ones; the value is the same whatever the state left."""
    R = np.zeros((len(actions), len(states), len(states)))
    for action, state, value in entries:
        a_sel = slice(None) if action == "*" else actions.index(action)
        s_sel = slice(None) if state == "*" else states.index(state)
        R[a_sel, :, s_sel] = value
    return [sp.csr_matrix(R[a]) for a in range(len(actions))]


def mdp_model(figures: Figures, states: Sequence[str], actions: Sequence[str],
              spans: Sequence[int], name: str, notes: Notes) -> Model:
    """A fully observable model (a human type, the reactive robot) from its table file."""
    rows = action_rows(figures["T"], states, actions, spans, name)
    model = Model(states=list(states), actions=list(actions), observations=list(states),
                  discount=figures["discount"],
                  initial_belief=np.eye(len(states))[states.index(figures["start"])],
                  T=transition_tables(states, actions, rows, notes, name),
                  O=[sp.identity(len(states), format="csr") for _ in actions],
                  R=reward_tables(states, actions, figures["rewards"]),
                  fully_observable=True, name=f"fabric_{name}")
    model.validate()
    return model


def robot_model(base: Figures, policy: Optional[Figures], name: str, notes: Notes) -> Model:
    """The base robot POMDP (``policy`` None) or the base as a policy file changes it."""
    spans = range(len(ROBOT_STATES))
    rows = action_rows(base["T"], ROBOT_STATES, ROBOT_ACTIONS, spans, "base")
    rewards = list(base["rewards"])
    if policy is not None:
        for action, changed in action_rows(policy["T"], ROBOT_STATES, ROBOT_ACTIONS, spans,
                                           name).items():
            rows[action].update(changed)
        rewards += policy["rewards"]
    o_rows = table_rows(base["O"], ROBOT_STATES, len(ROBOT_OBSERVATIONS),
                        range(len(ROBOT_OBSERVATIONS)), "O")
    O = np.vstack([_normalised(o_rows[s], f"{name} O {s}", notes) for s in ROBOT_STATES])
    model = Model(states=list(ROBOT_STATES), actions=list(ROBOT_ACTIONS),
                  observations=list(ROBOT_OBSERVATIONS), discount=base["discount"],
                  initial_belief=np.eye(len(ROBOT_STATES))[ROBOT_STATES.index(base["start"])],
                  T=transition_tables(ROBOT_STATES, ROBOT_ACTIONS, rows, notes, name),
                  O=[sp.csr_matrix(O) for _ in ROBOT_ACTIONS],
                  R=reward_tables(ROBOT_STATES, ROBOT_ACTIONS, rewards),
                  name=f"fabric_robot_{name}")
    model.validate()
    return model


def _header(figures: Figures) -> str:
    return (f"<!-- FABRIC, the seed authors' successor task. Figures of {figures['repository']} "
            f"{figures['file']} (commit {figures['commit'][:7]}; GPL-3.0); file written by "
            f"tools/make_fabric_models.py, see models/README.md. -->")


def human_types() -> List[str]:
    """The human types, one table file each."""
    return sorted(path.stem for path in (TABLES / "human").glob("*.toml"))


def robot_policies() -> List[str]:
    """The base robot's policy variants, one table file each."""
    return sorted(path.stem for path in (TABLES / "robot").glob("policy*.toml"))


def model_texts() -> Tuple[Dict[str, str], Notes]:
    """Every file's relative path and text, and the notes on what was changed."""
    notes = Notes()
    texts: Dict[str, str] = {}

    def add(path: str, model: Model, figures: Figures) -> None:
        head, rest = pomdpx.dump(model).split("\n", 1)
        texts[path] = f"{head}\n{_header(figures)}\n{rest}"

    for name in human_types():
        figures = read_figures(f"human/{name}")
        add(f"human/{name}.pomdpx", mdp_model(figures, HUMAN_STATES, HUMAN_ACTIONS,
                                              HUMAN_SPANS, f"human_{name}", notes), figures)
    base = read_figures("robot/base")
    add("robot/base.pomdpx", robot_model(base, None, "base", notes), base)
    for name in robot_policies():
        policy = read_figures(f"robot/{name}")
        add(f"robot/{name}.pomdpx", robot_model(base, policy, name, notes), policy)
    reactive = read_figures("robot/reactive")
    add("robot/reactive.pomdpx", mdp_model(reactive, REACTIVE_STATES, REACTIVE_ACTIONS,
                                           range(len(REACTIVE_STATES)), "robot_reactive",
                                           notes), reactive)
    return texts, notes


def write_models(out: Path) -> Notes:
    """Write every file under ``out`` (human/ and robot/); each file whole or not at all."""
    texts, notes = model_texts()
    for relative, text in texts.items():
        path = out / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomically(path, text)
    return notes


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(REPO / "models" / "fabric"),
                        help="the folder to write human/ and robot/ into (default: %(default)s)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    try:
        notes = write_models(out)
    except OSError as exc:
        print(f"make_fabric_models: cannot write under {out}: {exc.strerror or exc}",
              file=sys.stderr)
        return 1
    for line in notes.normalised:
        print(f"normalised: {line}")
    print(f"wrote {len(human_types())} human and {len(robot_policies()) + 2} robot models "
          f"under {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
