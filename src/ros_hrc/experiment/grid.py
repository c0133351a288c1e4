"""An experiment grid planned: its cells (human model x robot policy x seed), each with the
episodes still to record, from the parsed arguments of hrc_experiment (and hrc_fit's task
helpers). No ROS here.

The grid is planned lazily: each cell's episodes to run are ranges
(:class:`ros_hrc.experiment.stack.EpisodeRanges`), never a list of every episode. Every file
argument is made absolute here, once (:func:`resolve_files`): the cells' processes run
elsewhere. A fitted robot model is not evaluated on the streams it was fitted on unless asked
(:func:`check_held_out`). What cannot be planned is a :class:`GridError`, one line naming the
argument or the file.
"""
from __future__ import annotations

import argparse
from collections import defaultdict
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Protocol, Set, Tuple

from ros_hrc import tasks
from ros_hrc.errors import HrcError
from ros_hrc.experiment.arguments import names_argument
from ros_hrc.experiment.episode import DEFAULT_POLICIES as POLICIES_BY_DEFAULT
from ros_hrc.experiment.episode import ALONE_POLICY, reactive_policy_name, robot_policy
from ros_hrc.experiment.provenance import file_sha256, ranges_text, read_fitted_on
from ros_hrc.experiment.stack import CellSpec, EpisodeRanges
from ros_hrc.experiment.zoo import zoo_argument
from ros_hrc.models import ModelNotFound, model_path, shown_path
from ros_hrc.pomdp.planner import planner_class
from ros_hrc.model_files import user_path

#: The study evaluates on the zoo's held-out humans (the robot model is fitted on the others).
DEFAULT_HUMANS = zoo_argument("held_out")
#: Where the human-alone episodes go when ``no_robot`` is not one of the grid's policies.
ALONE_DIRECTORY = "alone"


class GridError(HrcError):
    """The grid cannot run: one line naming the argument or the file."""


def task_of(args: argparse.Namespace) -> tasks.Task:
    """The task of the grid (``--task``; the default task for a namespace without one)."""
    return tasks.get(getattr(args, "task", None) or tasks.DEFAULT_TASK)


def task_humans(task: tasks.Task) -> List[str]:
    """The human models of a task's study when ``--human-models`` is not given: the seed's
    zoo's held-out humans; another task's every shipped type (fabric's ten)."""
    if task.name == tasks.DEFAULT_TASK:
        return names_argument(DEFAULT_HUMANS)
    return sorted({p.stem for p in Path(task.model_dirs["human"]).glob("*.pomdp*")})


def training_humans(task: tasks.Task) -> List[str]:
    """The human models a task's robot is fitted or its selector trained on when
    ``--human-models`` is not given: the seed's zoo's fit set (never the held-out humans the
    study evaluates on); another task's every shipped type (its study's types)."""
    if task.name == tasks.DEFAULT_TASK:
        return names_argument(zoo_argument("fit"))
    return task_humans(task)


def task_launch_args(args: argparse.Namespace) -> List[str]:
    """The cells' hrc.launch argument for a task other than the default (none for it)."""
    task = task_of(args)
    return [] if task.name == tasks.DEFAULT_TASK else [f"task:={task.name}"]


def apply_task_defaults(args: argparse.Namespace) -> None:
    """``--robot-model``, ``--human-models``, ``--policies`` and ``--step-limit`` not given:
    the task's (``--task``; its study's, :class:`ros_hrc.tasks.definition.Task`)."""
    task = task_of(args)
    if getattr(args, "robot_model", "") is None:
        args.robot_model = task.default_robot_model
    if getattr(args, "human_models", ()) is None:
        args.human_models = task_humans(task)
    if getattr(args, "policies", ()) is None:
        args.policies = list(task.study_policies or POLICIES_BY_DEFAULT)
    if getattr(args, "step_limit", 0) is None:
        args.step_limit = task.study_step_limit


def expand_policies(args: argparse.Namespace) -> None:
    """Add ``reactive@N`` for every ``--reactive-budgets`` N to ``args.policies`` (once)."""
    if getattr(args, "policies_expanded", False):
        return
    extra = [reactive_policy_name(b) for b in getattr(args, "reactive_budgets", [])]
    args.policies = list(dict.fromkeys(list(args.policies) + extra))
    args.policies_expanded = True


def resolve_files(args: argparse.Namespace) -> None:
    """Make every file argument absolute, against the directory the command runs in, once
    (:func:`ros_hrc.model_files.user_path`): the cells' processes run elsewhere. Sets
    ``args.robot_model``, ``args.out`` and ``args.human_files`` (grid name -> absolute
    file); a model that is not there is a GridError naming the argument, before any cell."""
    if getattr(args, "human_files", None) is not None:
        return
    args.out = str(user_path(args.out))
    task = task_of(args)
    try:
        args.robot_model = str(model_path(args.robot_model, "robot", task))
    except ModelNotFound as exc:
        raise GridError(f"--robot-model: {exc}") from None
    files = {}
    for human in args.human_models:
        try:
            files[human] = str(model_path(human, "human", task))
        except ModelNotFound as exc:
            raise GridError(f"--human-models: {exc}") from None
    args.human_files = files


def robot_model_of(policy: str, grid_model: str, task: Optional[tasks.Task] = None) -> str:
    """The robot model a policy runs with, as an absolute file: its own (pomdp_fitted:
    robot_fitted, in ``task``'s folder) or the grid's."""
    own = robot_policy(policy).robot_model
    if own is None:
        return grid_model
    try:
        return str(model_path(own, "robot", task))
    except ModelNotFound:
        return own      # validate_grid refuses it, naming the policy


def plans_on_model(policy: str) -> bool:
    """Whether the policy's planner decides on its robot model, so the held-out rule applies
    to it (its class says: :attr:`ros_hrc.pomdp.planner.Planner.plans_on_model`)."""
    return planner_class(robot_policy(policy).planner).plans_on_model


def in_sample_streams(args: argparse.Namespace) -> Dict[Tuple[str, str, int], Set[int]]:
    """(policy, human model, seed) -> the grid's episodes on which that policy's robot model
    was fitted (:mod:`ros_hrc.experiment.provenance`); only pairs that overlap appear."""
    resolve_files(args)
    found: Dict[Tuple[str, str, int], Set[int]] = {}
    digests = {human: file_sha256(path) for human, path in args.human_files.items()}
    for policy in dict.fromkeys(args.policies):
        if not plans_on_model(policy):
            continue
        model_file = robot_model_of(policy, args.robot_model, task_of(args))
        try:
            fitted = read_fitted_on(model_file)
        except OSError:
            continue       # validate_grid has refused a model that cannot be read
        except ValueError as exc:
            raise GridError(f"--policies {policy}: {exc}") from None
        for streams in fitted:
            for human, digest in digests.items():
                for seed in args.seeds:
                    start, stop = streams.episodes
                    overlap = range(max(start, 0), min(stop, args.episodes))
                    if len(overlap) and (digest, seed) == (streams.sha256, streams.seed):
                        found.setdefault((policy, human, seed), set()).update(overlap)
    return found


def check_held_out(args: argparse.Namespace) -> None:
    """Refuse (GridError, one line) to evaluate a fitted robot model on the streams it was
    fitted on, unless ``--allow-in-sample``; sets ``args.in_sample`` for marking rows."""
    args.in_sample = in_sample_streams(args)
    if args.in_sample and not getattr(args, "allow_in_sample", False):
        (policy, human, seed), episodes = next(iter(args.in_sample.items()))
        model = shown_path(robot_model_of(policy, args.robot_model, task_of(args)))
        raise GridError(f"--policies {policy}: its robot model {model} was fitted on human "
                        f"model {human}, seed {seed}, episodes {ranges_text(episodes)}, which "
                        "this grid would evaluate it on; choose other --seeds (or human "
                        "models), or give --allow-in-sample to run them marked in_sample")


def plan_cells(args: argparse.Namespace, done: set) -> List[CellSpec]:
    """The cells with episodes still to record, in grid order (``no_robot``, the human
    alone, first: the robots' episodes are set against it). Each cell's episodes are ranges
    (:class:`EpisodeRanges`): memory in proportion to what is recorded, not to
    ``--episodes``."""
    resolve_files(args)
    expand_policies(args)
    recorded: Dict[Tuple[str, str, int], Set[int]] = defaultdict(set)
    for human, policy, seed, episode in done:
        recorded[(human, policy, seed)].add(episode)
    cells = []
    log_dir = str(Path(args.out) / "logs")
    for human in args.human_models:
        for policy in args.policies:
            for seed in args.seeds:
                missing = EpisodeRanges.missing(args.episodes,
                                                recorded.get((human, policy, seed), ()))
                if missing:
                    cells.append(_cell(args, human, policy, seed, missing, log_dir))
    return sorted(cells, key=lambda cell: cell.robot_policy != ALONE_POLICY)


class RecordedAlone(Protocol):
    """What the grid needs of the alone episodes recorded so far (the recorder's
    :class:`ros_hrc.experiment.recording.AloneEpisodes`, a floor above)."""

    def episodes_of(self, human: str, seed: int) -> Iterable[int]: ...


def plan_alone_cells(args: argparse.Namespace, alone: RecordedAlone) -> List[CellSpec]:
    """The ``no_robot`` cells the grid needs for its counterfactual and does not have yet
    (none when ``no_robot`` is one of the grid's policies: its own cells are the alone
    episodes). One cell per (human model, seed), whatever the number of robot policies."""
    resolve_files(args)
    expand_policies(args)
    if ALONE_POLICY in args.policies:
        return []
    cells = []
    log_dir = str(Path(args.out) / ALONE_DIRECTORY / "logs")
    for human in args.human_models:
        for seed in args.seeds:
            have = alone.episodes_of(human, seed)
            missing = EpisodeRanges.missing(args.episodes, have)
            if missing:
                cells.append(_cell(args, human, ALONE_POLICY, seed, missing, log_dir))
    return cells


def _cell(args: argparse.Namespace, human: str, policy: str, seed: int,
          episodes: EpisodeRanges, log_dir: str) -> CellSpec:
    budget = robot_policy(policy).reactive_budget
    extra = task_launch_args(args)
    swept = task_of(args).reactive_parameter
    if budget is not None and swept != "reactive_budget":
        # This task's reactive robot is tuned by its own argument (fabric: its wait).
        extra = extra + [f"{swept}:={budget}"]
        budget = None
    return CellSpec(
        human_model=human, robot_policy=policy, seed=seed, episodes=episodes,
        step_limit=args.step_limit, log_dir=log_dir,
        human_model_file=args.human_files[human],
        robot_model=robot_model_of(policy, args.robot_model, task_of(args)),
        human_choice=args.human_choice,
        max_trials=args.max_trials,
        reactive_budget=args.reactive_budget if budget is None else budget,
        scenarios=args.scenarios, depth=args.depth, lambda_=args.lambda_, record_bag=args.bag,
        extra_args=extra)
