"""A sequence study planned: ``hrc_experiment --sequence L`` (docs/experiments.md,
"Sequences"). No ROS here.

A cell is (schedule, selector, seed); its unit is a sequence of ``L`` tasks on one stack
(``tasks:=L``), the robot's selector choosing a policy of the task's library before each task
and learning from each (docs/sequences.md). ``--episodes N`` is N independent sequences per
cell, numbered from 0; task ``t`` of sequence ``s`` plays the loop's episode
:func:`~ros_hrc.experiment.sequence_rows.task_episode` ``(s, t, L) = s*L + t - 1``, so every
task has streams of its own and the same (seed, sequence, task) is the same human under every
selector: the pairs of the paired tests.

The schedules (``--schedule``, comma-separated, each a cell per selector and seed):
- ``per-type``: one cell per ``--human-models`` type, the same human for all ``L`` tasks;
- ``fabric``: FABRIC's schedule (``schedule:=fabric``: 10 types x 30 tasks; a sequence of
  ``L`` tasks plays its first ``L``, so ``--sequence 300`` plays it whole);
- a schedule file (``schedule:=FILE``, docs/sequences.md's format), labelled by its stem.

Selectors (``--selectors``): ``fixed`` stands for every policy of the library as
``fixed:<policy>``; ``pomdp_types`` is the robot that infers its human's type (the study's
policy of that name: one model of human types plays every task, its type belief carried
from task to task); the others are the robot process's (``ros_hrc.agents.selectors``). A
selector that uses a trained model (the BPRs, the oracle) is not evaluated on the seeds its
model was trained on (:func:`check_trained_elsewhere`).
"""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Set, Tuple

from ros_hrc import registry
from ros_hrc.agents.selectors import selector_class
from ros_hrc.experiment.episode import TYPES_POLICY
from ros_hrc.experiment.grid import (GridError, resolve_files, robot_model_of, task_launch_args,
                                     task_of)
from ros_hrc.experiment.provenance import file_sha256, read_fitted_on
from ros_hrc.experiment.sequence_rows import CEILING, POOLED, launched_selector
from ros_hrc.settings import LEARNING_SELECTORS, LEARNING_SETTINGS
from ros_hrc.experiment.stack import CellSpec, EpisodeRanges
from ros_hrc.model_files import user_path
from ros_hrc.models import model_path
from ros_hrc.tasks.schedule import type_name

#: ``--schedule`` words that are no file.
PER_TYPE = "per-type"
FABRIC = "fabric"
SCHEDULE_WORDS = (PER_TYPE, FABRIC)
#: The selector that stands for every library policy (``fixed:<policy>`` each).
FIXED = "fixed"
#: The study's own robots that ``--selectors`` takes beside the registry's selectors
#: (``ros_hrc.selectors``) and ``fixed``: the robot of human types, the ceiling, the pooled
#: prior and the learning robots.
STUDY_ROBOTS: Tuple[str, ...] = (TYPES_POLICY, CEILING, POOLED) + LEARNING_SELECTORS
#: The selector model's file name, beside the library's manifest (``models/fabric/`` and
#: ``models/robot/``), where ``selector_model:=auto`` finds it.
SELECTOR_MODEL_FILE = "selector_model.json"
#: Tasks per sequence: a task is a uint32 where it travels, and so is its episode number.
MAX_SEQUENCE = 100000


def expand_selectors(names: Sequence[str], policies: Sequence[str]) -> List[str]:
    """``--selectors`` as the cells run them: ``fixed`` becomes ``fixed:<policy>`` for every
    library policy (in the library's order), ``fixed:<policy>`` is checked against the
    library, the study's own words (the robot of types, the learning robot, pooled, ceiling)
    kept, the others looked up as selectors of the registry (ours, an installed package's,
    module:Class; :func:`ros_hrc.agents.selectors.selector_class`, which imports it). GridError
    (one line naming the known ones and the nearest) for an unknown name."""
    out: List[str] = []
    for name in names:
        if name == FIXED:
            out.extend(f"{FIXED}:{policy}" for policy in policies)
        elif name.startswith(f"{FIXED}:"):
            policy = name[len(FIXED) + 1:]
            if policy not in policies:
                raise GridError(f"--selectors: {name}: no policy {policy!r} in the library "
                                f"(its policies: {', '.join(policies)})")
            out.append(name)
        elif name in STUDY_ROBOTS:
            out.append(name)
        else:
            try:
                selector_class(name)
            except registry.RegistryError as exc:
                raise GridError(f"--selectors: {exc}; also fixed, fixed:<policy>, "
                                f"{', '.join(STUDY_ROBOTS)}") from None
            out.append(name)
    return list(dict.fromkeys(out))


def model_selectors(names: Sequence[str]) -> List[str]:
    """The selectors of ``names`` whose choices rest on the trained selector model (the
    held-out rule applies to them): those whose class ``needs_model``."""
    return [name for name in names
            if name.partition(":")[0] != FIXED and name not in STUDY_ROBOTS
            and selector_class(name).needs_model]


def load_study_library(args: argparse.Namespace):
    """The library of the study (``--library``; ``auto``: the task's manifest), loaded and
    checked against the task (``ros_hrc.agents.library.load_library``); GridError naming
    ``--library`` otherwise."""
    from ros_hrc.agents.library import load_library
    from ros_hrc.errors import HrcError
    given = args.library
    where = given if given == "auto" else str(user_path(given))
    try:
        return load_library(where, task_of(args))
    except HrcError as exc:
        raise GridError(f"--library: {exc}") from None


def selector_model_file(args: argparse.Namespace, library) -> Optional[Path]:
    """The selector model a study's stacks use: ``--selector-model`` (absolute), or for
    ``auto`` the one beside the library's manifest if it exists; None without one."""
    if args.selector_model != "auto":
        return user_path(args.selector_model)
    beside = Path(library.manifest).parent / SELECTOR_MODEL_FILE
    return beside if beside.exists() else None


def schedule_label(schedule: str) -> str:
    """The name a schedule's cells are known by (the results' ``schedule`` column): the word,
    or a file's stem."""
    return schedule if schedule in SCHEDULE_WORDS else Path(schedule).stem


def resolve_schedules(args: argparse.Namespace) -> None:
    """Make ``--schedule``'s files absolute and check they are there (GridError naming the
    argument otherwise); their contents are the stack's pre-flight's to check."""
    resolved = []
    for schedule in args.schedule:
        if schedule in SCHEDULE_WORDS:
            resolved.append(schedule)
            continue
        path = user_path(schedule)
        if not path.is_file():
            raise GridError(f"--schedule: {schedule}: no schedule file (looked for {path}); "
                            f"give {PER_TYPE}, {FABRIC} or a schedule file")
        resolved.append(str(path))
    labels = [schedule_label(s) for s in resolved]
    twice = sorted({label for label in labels if labels.count(label) > 1})
    if twice:
        raise GridError(f"--schedule: two schedules are called {twice[0]!r}")
    args.schedule = resolved


def check_trained_elsewhere(args: argparse.Namespace, model_seeds: Sequence[int]) -> List[str]:
    """The held-out rule of a selector model: one trained on seeds S is not evaluated on S.
    GridError (one line) when a selector that uses it (:func:`model_selectors`) would run on
    one of its seeds, unless ``--allow-in-sample``; then the warning line, returned."""
    users = model_selectors(args.selectors)
    shared = sorted(set(model_seeds) & set(args.seeds))
    if not users or not shared:
        return []
    line = (f"--selectors {','.join(users)}: their selector model {args.selector_model_file} "
            f"was trained on seeds {','.join(map(str, shared))}, which this study would "
            f"evaluate them on")
    if not getattr(args, "allow_in_sample", False):
        raise GridError(f"{line}; choose other --seeds, or give --allow-in-sample to run "
                        "them anyway")
    return [f"warning: {line} (--allow-in-sample)"]


def sequence_launch_args(args: argparse.Namespace, selector: str, schedule: str) -> List[str]:
    """The hrc.launch arguments that make a cell's stack play sequences: ``tasks:=L``, the
    selector, the library and the selector model (each ``auto`` unless given: the stack
    finds the task's own), and the schedule (none for ``per-type``: the launch's
    ``human_model`` plays every task)."""
    # auto stays auto: each stack finds its task's own (on a cluster's node, its install's).
    library = "auto" if args.library == "auto" else args.library_manifest
    words = task_launch_args(args) + [f"tasks:={args.sequence}",
                                      f"selector:={launched_selector(selector)}",
                                      f"library:={library}"]
    if args.selector_model != "auto":
        words.append(f"selector_model:={args.selector_model_file}")
    if schedule != PER_TYPE:
        words.append(f"schedule:={schedule}")
    if selector in LEARNING_SELECTORS:
        for name in LEARNING_SETTINGS:
            value = getattr(args, name, None)
            if value is not None:
                words.append(f"{name}:={value}")
    return words


def cell_humans(args: argparse.Namespace, schedule: str) -> List[Tuple[str, str]]:
    """(label, human model file) of a schedule's cells: per type, one per ``--human-models``;
    otherwise one, its human the task's default (the schedule names who plays each task)."""
    if schedule == PER_TYPE:
        return [(human, args.human_files[human]) for human in args.human_models]
    task = task_of(args)
    return [(schedule_label(schedule), str(model_path(task.default_human_model, "human", task)))]


def ceiling_model(args: argparse.Namespace, human: str) -> str:
    """The ceiling's robot model for ``human`` (``--ceiling-models DIR``: ``DIR/<label>.pomdp``,
    the label the human's rows carry, the file's stem for a human given as a file;
    ``hrc_fit --human-models <human>`` on another seed), checked: it exists and was fitted on
    that human on none of the study's seeds. GridError (one line) otherwise."""
    folder = getattr(args, "ceiling_models", None)
    if not folder:
        raise GridError(f"--selectors {CEILING}: give --ceiling-models DIR, a folder of robot "
                        f"models each fitted on one human (docs/learning.md)")
    path = Path(folder) / f"{type_name(human)}.pomdp"
    if not path.is_file():
        raise GridError(f"--selectors {CEILING}: no model fitted on human {human} ({path}); "
                        f"fit one on other seeds of that human: hrc_fit --human-models {human} "
                        f"--seed S --prior robot_considerate --rewards utility --out {path}")
    try:
        fitted = read_fitted_on(path)
    except (OSError, ValueError) as exc:
        raise GridError(f"--ceiling-models: {exc}") from None
    digest = file_sha256(args.human_files[human])
    mine = [f for f in fitted if f.sha256 == digest]
    if not mine:
        raise GridError(f"--selectors {CEILING}: {path} was not fitted on human {human} (its "
                        f"fitted-on lines name no other seeds of it)")
    shared = sorted({f.seed for f in mine} & set(args.seeds))
    if shared:
        raise GridError(f"--selectors {CEILING}: {path} was fitted on seed {shared[0]} of "
                        f"human {human}, which this study evaluates: it needs other seeds")
    return str(path)


def cell_robot_model(args: argparse.Namespace, selector: str, human: str) -> str:
    """The robot model a cell's stack runs: the model of human types for ``pomdp_types``,
    the task's learning prior for the learning robots and for ``pomdp_pooled`` (that prior,
    never learnt), the ceiling's model of this human for ``pomdp_ceiling``, else the study's
    ``--robot-model``."""
    task = task_of(args)
    if selector == TYPES_POLICY:
        return robot_model_of(TYPES_POLICY, args.robot_model, task)
    if selector in LEARNING_SELECTORS + (POOLED,):
        if not task.learning_prior:
            raise GridError(f"--selectors {selector}: task {task.name} has no learning prior "
                            f"yet (a pooled fit priced by its utility: hrc_fit --rewards "
                            f"utility)")
        return str(model_path(task.learning_prior, "robot", task))
    if selector == CEILING:
        return ceiling_model(args, human)
    return args.robot_model


def plan_sequence_cells(args: argparse.Namespace, done: Set[tuple]) -> List[CellSpec]:
    """The cells with sequences still to record: schedules x selectors x seeds (per type, x
    ``--human-models``), each with its missing sequence numbers as ranges (a sequence is
    recorded whole or runs again)."""
    resolve_files(args)
    recorded: Dict[tuple, Set[int]] = {}
    for schedule, selector, seed, sequence in done:
        recorded.setdefault((schedule, selector, seed), set()).add(sequence)
    cells = []
    for schedule in args.schedule:
        for label, human_file in cell_humans(args, schedule):
            for selector in args.selectors:
                for seed in args.seeds:
                    missing = EpisodeRanges.missing(args.episodes,
                                                    recorded.get((label, selector, seed), ()))
                    if missing:
                        cells.append(CellSpec(
                            human_model=label, robot_policy=selector, seed=seed,
                            episodes=missing, step_limit=args.step_limit,
                            log_dir=str(Path(args.out) / "logs"),
                            human_model_file=human_file,
                            robot_model=cell_robot_model(args, selector, label),
                            human_choice=args.human_choice,
                            max_trials=args.max_trials, reactive_budget=args.reactive_budget,
                            scenarios=args.scenarios, depth=args.depth, lambda_=args.lambda_,
                            record_bag=args.bag, sequence=args.sequence,
                            extra_args=sequence_launch_args(args, selector, schedule)))
    return cells


def tasks_of(cells: Sequence[CellSpec]) -> int:
    """Tasks the cells will play."""
    return sum(len(c.episodes) * c.sequence for c in cells)
