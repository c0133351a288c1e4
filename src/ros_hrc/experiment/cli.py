"""hrc_experiment: the anticipatory robot against baselines, across kinds of human, in one command.

Runs a grid of human models x robot policies x seeds x episodes through the real stack (one
``hrc.launch`` per cell, headless, its world as fast as the machine goes; cells run in
parallel, one per core by default), writes one CSV row per episode and per step as each
episode ends, and at the end a summary with 95 % confidence intervals and PNG plots.
Running the same command again resumes: recorded episodes are kept and skipped.

    hrc_experiment --human-models beginner,tired --policies pomdp,no_robot \\
                   --reactive-budgets 1..10 --seeds 1 --episodes 92 --out results/experiment

Every robot episode is set against the human alone on the same (human model, seed, episode)
stream: the ``no_robot`` episode, which hrc_experiment runs itself, once per human stream (the
grid's own ``no_robot`` episodes when it has that policy; otherwise into ``<out>/alone/``),
before the robot policies' episodes of that stream, and reuses across policies and resumed
runs. ``--reactive-budgets`` sweeps the reactive robot's budget (policies ``reactive@N``);
the summary names the best budget and compares every robot with it and with the human alone
(paired tests, ``ros_hrc.experiment.statistics``). A robot model fitted by hrc_fit says
which streams it was fitted on; evaluating it on them is refused unless
``--allow-in-sample`` (the rows are then marked ``in_sample``).

Every file argument (``--robot-model``, a ``--human-models`` file, ``--out``) is taken
against the directory the command runs in, once, here: the cells get absolute paths only.
The whole grid is checked before any stack starts (every model against the task's tables,
every setting as hrc.launch checks it, every number against what its consumer takes); a bad
one is one line naming the argument or the file, exit status 2. The grid is planned lazily
(each cell's episodes to run are ranges, never a list of every episode). A file that cannot
be written (a full disk) is one line naming it, exit status 1. ``--out`` is locked for the whole run: a second run on the same directory is
refused. SIGINT or SIGTERM stops every cell's stack, keeps what was recorded and exits 130 or
143; the same command then resumes.
"""
from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import os
import shlex
import signal
import subprocess
import sys
import threading
import time
from collections import defaultdict
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Set, Tuple

from ros_hrc.command_line import own_arguments
from ros_hrc.errors import HrcError
from ros_hrc.experiment.episode import DEFAULT_POLICIES as POLICIES_BY_DEFAULT
from ros_hrc.experiment.episode import (ALONE_POLICY, ROBOT_POLICIES, pair, pair_alone,
                                        reactive_policy_name, robot_policy, stream_of)
from ros_hrc.experiment.plots import plot_belief, plot_outcomes, plot_success, plot_time_gain
from ros_hrc.experiment.provenance import file_sha256, ranges_text, read_fitted_on
from ros_hrc.experiment.stack import (MAX_ATTEMPTS, MAX_EPISODES, CellSpec, EpisodeRanges,
                                      cell_name, check_launch_settings, decode_episode, say,
                                      worker_command, write_spec)
from ros_hrc.experiment.statistics import summarize, write_summary
from ros_hrc.experiment.zoo import zoo_argument
from ros_hrc.experiment.cluster import add_argument as add_cluster_argument
from ros_hrc.experiment.cluster import check_reachable as check_cluster
from ros_hrc.experiment.cluster import without
from ros_hrc.experiment.lock import DirectoryLocked, lock_directory
from ros_hrc.experiment.rows import EpisodeRow, StepRow
from ros_hrc.experiment.store import ResultsStore
from ros_hrc import tasks
from ros_hrc.loop import settings
from ros_hrc.loop.models import (ModelNotFound, load_human_model, load_robot_model, model_path,
                                 positional_mapping_line, shown_path)
from ros_hrc.loop.settings import SettingError
from ros_hrc.model_files import user_path
from ros_hrc.pomdp.output import write_text_atomically

NAME = "hrc_experiment"
#: The study evaluates on the zoo's held-out humans (the robot model is fitted on the others).
DEFAULT_HUMANS = zoo_argument("held_out")
DEFAULT_POLICIES = ",".join(POLICIES_BY_DEFAULT)
#: Episodes per cell by default: the fewest paired episodes at which McNemar's exact test
#: detects a 15-point difference in success with 80 % power at alpha 0.05 when the weaker
#: policy still wins 5 % of the pairs (``paired.episodes_to_detect(0.15, 0.05)``; a unit test
#: keeps the two equal; docs/experiments.md says how).
DEFAULT_EPISODES = 92
#: The default seed of the grid: not hrc_fit's (0), so a fitted model is evaluated on other
#: streams than it was fitted on; not 1, on which the first considerate model was evaluated
#: before its robot-success value was tuned (on the fit set, seed 3; docs/robot_model.md), so
#: the README's study runs on streams nothing was chosen by.
DEFAULT_SEEDS = "2"
#: Where the human-alone episodes go when ``no_robot`` is not one of the grid's policies.
ALONE_DIRECTORY = "alone"


class GridError(HrcError):
    """The grid cannot run: one line naming the argument or the file."""


class OneLineParser(argparse.ArgumentParser):
    """argparse whose errors are one line, ``hrc_experiment: argument --x: ...``, exit 2."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, f"{self.prog}: {' '.join(message.split())}\n")


class GridParser(OneLineParser):
    """The grid's parser: what ``--task`` changes (its humans, its policies) is filled in once
    the task is known (:func:`apply_task_defaults`)."""

    def parse_known_args(self, args=None, namespace=None):  # type: ignore[override]
        parsed, rest = super().parse_known_args(args, namespace)
        apply_task_defaults(parsed)
        return parsed, rest


def task_humans(task: tasks.Task) -> List[str]:
    """The human models of a task's study when ``--human-models`` is not given: the seed's
    zoo's held-out humans; another task's every shipped type (fabric's ten)."""
    if task.name == tasks.DEFAULT_TASK:
        return names_argument(DEFAULT_HUMANS)
    return sorted({p.stem for p in Path(task.model_dirs["human"]).glob("*.pomdp*")})


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


def names_argument(text: str) -> List[str]:
    """Comma-separated names: at least one, none empty (``a,,b`` is a typo, not two names),
    none twice."""
    names = [part.strip() for part in text.split(",")]
    if not any(names):
        raise argparse.ArgumentTypeError("give at least one name (comma-separated)")
    if not all(names):
        raise argparse.ArgumentTypeError(f"an empty item between commas in {text!r}")
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise argparse.ArgumentTypeError(f"{repeated[0]!r} is given twice in {text!r}")
    return names


def _seeds(text: str) -> List[int]:
    seeds = []
    for part in names_argument(text):
        try:
            seeds.append(settings.parse("seed", part))
        except SettingError as exc:     # the range is hrc.launch's (an int32 parameter)
            requirement = getattr(exc, "requirement", "must be an integer >= 0")
            shown = part if len(part) <= 60 else f"{part[:40]}... ({len(part)} characters)"
            raise argparse.ArgumentTypeError(f"seeds are comma-separated; each "
                                             f"{requirement}, got {shown!r}") from None
    return seeds


#: A step limit travels as the ``max_steps`` ROS parameter: an XML-RPC int (int32).
MAX_STEP_LIMIT = 2**31 - 1
#: Stacks side by side: each is a roscore and six processes.
MAX_JOBS = 1000
#: Digits an integer option may have before it is not read at all (Python refuses to convert
#: more than 4300; none of these numbers needs 20).
_MAX_DIGITS = 40


def at_least(minimum: int, maximum: Optional[int] = None) -> Callable[[str], int]:
    """An argparse type: an integer >= ``minimum`` (and <= ``maximum``)."""
    def parse(text: str) -> int:
        shown = text if len(text) <= 60 else f"{text[:40]}... ({len(text)} characters)"
        try:
            if len(text.strip()) > _MAX_DIGITS:
                raise ValueError
            value = int(text.strip())
        except ValueError:
            if text.strip().isdigit() and maximum is not None:
                raise argparse.ArgumentTypeError(f"must be an integer from {minimum} to "
                                                 f"{maximum}, got {shown!r}") from None
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, "
                                             f"got {shown!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {shown!r}")
        if maximum is not None and value > maximum:
            raise argparse.ArgumentTypeError(f"must be an integer from {minimum} to {maximum}, "
                                             f"got {shown!r}")
        return value

    parse.__name__ = "int"
    return parse


#: Budgets a sweep may list: each one is a cell per human model and seed.
MAX_BUDGETS = 100


def budgets_argument(text: str) -> List[int]:
    """Reactive budgets: ``A..B`` (inclusive) or a comma-separated list, each >= 1; ``none``:
    no sweep (the default)."""
    words = text.strip()
    if words == "none":
        return []
    try:
        if ".." in words:
            low, _, high = words.partition("..")
            budgets = list(range(int(low), int(high) + 1))
        else:
            budgets = [int(part) for part in names_argument(words)]
    except (ValueError, argparse.ArgumentTypeError):
        raise argparse.ArgumentTypeError(f"expected A..B or a comma-separated list of "
                                         f"integers >= 1, got {text[:60]!r}") from None
    if not budgets or min(budgets) < 1 or max(budgets) > settings.INT32_MAX:
        raise argparse.ArgumentTypeError(f"budgets must be integers from 1 to "
                                         f"{settings.INT32_MAX}, got {text[:60]!r}")
    if len(budgets) > MAX_BUDGETS:
        raise argparse.ArgumentTypeError(f"at most {MAX_BUDGETS} budgets, got {len(budgets)}")
    return list(dict.fromkeys(budgets))


def build_parser() -> argparse.ArgumentParser:
    p = GridParser(prog=NAME, description=__doc__.split("\n\n")[0],
                   formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--human-models", type=names_argument, default=None,
                   help=f"human scenarios or .pomdpx files, comma-separated (the task's: "
                        f"{DEFAULT_HUMANS} for the seed, every shipped type for fabric)")
    p.add_argument("--policies", type=names_argument, default=None,
                   help=f"robot policies, comma-separated, of {', '.join(ROBOT_POLICIES)} (the "
                        f"task's: {DEFAULT_POLICIES} for the seed, "
                        f"{','.join(tasks.get('fabric').study_policies)} for fabric)")
    p.add_argument("--reactive-budgets", type=budgets_argument, default=[],
                   help="also run the reactive robot with each of these budgets (policies "
                        "reactive@N), e.g. 1..10 or 2,4,8 (none: no sweep, the default); the "
                        "summary names the best. The seed's budget is observations before it "
                        "helps; fabric's is simulated seconds without success (its "
                        "reactive_wait, the authors' 15)")
    p.add_argument("--seeds", type=_seeds, default=_seeds(DEFAULT_SEEDS),
                   help=f"seeds, comma-separated ({DEFAULT_SEEDS})")
    p.add_argument("--episodes", type=at_least(1, MAX_EPISODES), default=DEFAULT_EPISODES,
                   help=f"episodes per cell, 1 to {MAX_EPISODES} ({DEFAULT_EPISODES}: a "
                        "15-point difference in success detectable, see docs/experiments.md)")
    p.add_argument("--allow-in-sample", action="store_true",
                   help="evaluate a fitted robot model on streams it was fitted on too "
                        "(marked in_sample); refused otherwise")
    p.add_argument("--step-limit", type=at_least(1, MAX_STEP_LIMIT), default=None,
                   help="steps before an episode ends (the task's: 15 for the seed; 300 for "
                        "fabric, a safety net: its episodes end in the world, the object taken "
                        "or at the belt's end)")
    p.add_argument("--jobs", type=at_least(0, MAX_JOBS), default=0,
                   help="stacks run side by side (0: one per core; with --cluster, one per "
                        "ros_hrc slot of the cluster)")
    p.add_argument("--out", default="results/experiment",
                   help="results directory (relative to the current directory)")
    settings.add_argument(p, "robot_model", default=None)   # the task's (apply_task_defaults)
    settings.add_argument(p, "task")     # (#22) every cell runs task:=, models checked against it
    settings.add_argument(p, "human_choice")
    settings.add_argument(p, "max_trials")
    settings.add_argument(p, "reactive_budget")
    settings.add_argument(p, "scenarios")
    settings.add_argument(p, "depth")
    settings.add_argument(p, "lambda", dest="lambda_")
    add_cluster_argument(p)
    p.add_argument("--bag", action=argparse.BooleanOptionalAction, default=False,
                   help="also record /hrc/status as a rosbag (default: no)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    return p


def validate_grid(args: argparse.Namespace) -> None:
    """Check the whole grid before any stack starts: the policies, every human model and the
    robot model against the task's tables, every cell's launch settings. Raises HrcError with
    one line naming the argument or the file and the offending names. Once all is good, each
    model file named by position gets its mapping printed, one line per file."""
    expand_policies(args)
    unknown = [p for p in args.policies if not _known(p)]
    if unknown:
        raise GridError(f"--policies: unknown robot policies {', '.join(unknown)}; known: "
                        f"{', '.join(ROBOT_POLICIES)}, reactive@N")
    resolve_files(args)
    loaded = []
    try:
        loaded.append(load_robot_model(args.robot_model, task_of(args)))
    except ModelNotFound as exc:
        raise GridError(f"--robot-model: {exc}") from None
    for policy in dict.fromkeys(args.policies):
        own = robot_policy(policy).robot_model
        if own is not None:
            try:
                loaded.append(load_robot_model(own, task_of(args)))
            except ModelNotFound as exc:
                hint = " (make fit writes it)" if own == "robot_fitted" else ""
                raise GridError(f"--policies: {policy} runs robot model {own}: {exc}"
                                f"{hint}") from None
    for human in dict.fromkeys(args.human_models):
        try:
            loaded.append(load_human_model(args.human_files[human], task_of(args)))
        except ModelNotFound as exc:
            raise GridError(f"--human-models: {exc}") from None
    for spec in plan_cells(args, set()):
        if spec.seed == args.seeds[0]:   # the settings do not depend on the seed otherwise
            check_launch_settings(spec)
    check_held_out(args)
    mappings = (positional_mapping_line(model) for model in loaded)
    for line in dict.fromkeys(m for m in mappings if m):   # once per file, by its line
        print(f"{NAME}: {line}", flush=True)


def _known(policy: str) -> bool:
    try:
        robot_policy(policy)
    except KeyError:
        return False
    return True


def expand_policies(args: argparse.Namespace) -> None:
    """Add ``reactive@N`` for every ``--reactive-budgets`` N to ``args.policies`` (once)."""
    if getattr(args, "policies_expanded", False):
        return
    extra = [reactive_policy_name(b) for b in getattr(args, "reactive_budgets", [])]
    args.policies = list(dict.fromkeys(list(args.policies) + extra))
    args.policies_expanded = True


#: Planners whose decisions depend on the robot model (the held-out rule applies to them).
MODEL_PLANNERS = ("despot", "policy")


def in_sample_streams(args: argparse.Namespace) -> Dict[Tuple[str, str, int], Set[int]]:
    """(policy, human model, seed) -> the grid's episodes on which that policy's robot model
    was fitted (:mod:`ros_hrc.experiment.provenance`); only pairs that overlap appear."""
    resolve_files(args)
    found: Dict[Tuple[str, str, int], Set[int]] = {}
    digests = {human: file_sha256(path) for human, path in args.human_files.items()}
    for policy in dict.fromkeys(args.policies):
        if robot_policy(policy).planner not in MODEL_PLANNERS:
            continue
        model_file = robot_model_of(policy, args.robot_model)
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
        model = shown_path(robot_model_of(policy, args.robot_model))
        raise GridError(f"--policies {policy}: its robot model {model} was fitted on human "
                        f"model {human}, seed {seed}, episodes {ranges_text(episodes)}, which "
                        "this grid would evaluate it on; choose other --seeds (or human "
                        "models), or give --allow-in-sample to run them marked in_sample")


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


def robot_model_of(policy: str, grid_model: str) -> str:
    """The robot model a policy runs with, as an absolute file: its own (pomdp_fitted:
    robot_fitted) or the grid's."""
    own = robot_policy(policy).robot_model
    if own is None:
        return grid_model
    try:
        return str(model_path(own, "robot"))
    except ModelNotFound:
        return own      # validate_grid refuses it, naming the policy


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
        robot_model=robot_model_of(policy, args.robot_model),
        human_choice=args.human_choice,
        max_trials=args.max_trials,
        reactive_budget=args.reactive_budget if budget is None else budget,
        scenarios=args.scenarios, depth=args.depth, lambda_=args.lambda_, record_bag=args.bag,
        extra_args=extra)


def task_of(args: argparse.Namespace) -> tasks.Task:
    """The task of the grid (``--task``; the default task for a namespace without one)."""
    return tasks.get(getattr(args, "task", None) or tasks.DEFAULT_TASK)


def task_launch_args(args: argparse.Namespace) -> List[str]:
    """The cells' hrc.launch argument for a task other than the default (none for it)."""
    task = task_of(args)
    return [] if task.name == tasks.DEFAULT_TASK else [f"task:={task.name}"]


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


def plan_alone_cells(args: argparse.Namespace, alone: "AloneEpisodes") -> List[CellSpec]:
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


class AloneEpisodes:
    """The human alone on each stream: ``no_robot`` rows by (human model, seed, episode),
    from the grid's own ``no_robot`` rows and from ``<out>/alone/`` (episodes run only for
    the counterfactual). Recorded once per stream, reused by every policy and resumed run."""

    def __init__(self, store: ResultsStore, out: Path, grid_has_alone: bool) -> None:
        self.store = store
        self.grid_has_alone = grid_has_alone
        self.directory = out / ALONE_DIRECTORY
        self._own: Optional[ResultsStore] = None
        self.rows: Dict[Tuple[str, int, int], EpisodeRow] = {}
        if self.directory.exists():
            self._own = ResultsStore(self.directory)
            for row in self._own.episodes():
                self.rows[stream_of(row)] = row
        for row in store.episodes():
            if row.robot_policy == ALONE_POLICY:
                self.rows[stream_of(row)] = row

    @property
    def own_store(self) -> ResultsStore:
        if self._own is None:
            self._own = ResultsStore(self.directory)
        return self._own

    def episodes_of(self, human: str, seed: int) -> Set[int]:
        return {e for (h, s, e) in self.rows if (h, s) == (human, seed)}

    def adopt_into_grid(self, args: argparse.Namespace) -> int:
        """With ``no_robot`` in the grid: its episodes already run for the counterfactual
        (``<out>/alone/``) become the grid's rows, steps included, instead of running again.
        Returns how many were adopted."""
        if not self.grid_has_alone or self._own is None:
            return 0
        done = self.store.done()
        wanted = [row for row in self._own.episodes()
                  if row.human_model in args.human_models and row.seed in args.seeds
                  and row.episode < args.episodes and row.key not in done]
        if not wanted:
            return 0
        steps: Dict[tuple, List[StepRow]] = defaultdict(list)
        keys = {row.key for row in wanted}
        for step in self._own.steps():
            if step.key in keys:
                steps[step.key].append(step)
        for row in wanted:
            self.store.add(row, steps[row.key])
        return len(wanted)

    def add(self, row: EpisodeRow, steps: Sequence[StepRow]) -> EpisodeRow:
        """Record a ``no_robot`` episode (paired with itself) where it belongs."""
        row = pair_alone(row)
        (self.store if self.grid_has_alone else self.own_store).add(row, steps)
        self.rows[stream_of(row)] = row
        return row


class PairedRecorder:
    """What the cells' episodes go through: a ``no_robot`` episode is the human alone
    (:class:`AloneEpisodes`); any other is set against it (:func:`episode.pair`), marked
    ``in_sample`` when its robot model was fitted on that stream, and stored."""

    def __init__(self, store: ResultsStore, alone: AloneEpisodes,
                 in_sample: Optional[Dict[Tuple[str, str, int], Set[int]]] = None) -> None:
        self.store = store
        self.alone = alone
        self.in_sample = in_sample or {}

    def add(self, row: EpisodeRow, steps: Sequence[StepRow]) -> None:
        if row.robot_policy == ALONE_POLICY:
            self.alone.add(row, steps)
            return
        alone = self.alone.rows.get(stream_of(row))
        if alone is None:   # the gate runs only streams whose alone episode is in
            raise RuntimeError(f"episode {row.key}: no human-alone episode on its stream")
        marked = row.episode in self.in_sample.get((row.robot_policy, row.human_model,
                                                    row.seed), ())
        self.store.add(pair(row, alone, in_sample=marked), steps)

    def done(self) -> Set[Tuple[str, str, int, int]]:
        return self.store.done()

    def gate(self, cell: CellSpec) -> Optional[CellSpec]:
        """A robot cell's episodes restricted to the streams whose alone episode is in (an
        alone cell that failed leaves its streams for the next run); None if none is."""
        if cell.robot_policy == ALONE_POLICY:
            return cell
        have = self.alone.episodes_of(cell.human_model, cell.seed)
        kept = EpisodeRanges.of(e for e in cell.episodes if e in have)
        if not kept:
            return None
        return dataclasses.replace(cell, episodes=kept)


class Stopper:
    """SIGINT / SIGTERM to hrc_experiment: every worker gets SIGTERM (each stops its own
    stack), no new cell starts, and the run ends with what was recorded."""

    def __init__(self) -> None:
        self.signum: Optional[int] = None
        self._lock = threading.Lock()
        self._workers: Set[subprocess.Popen] = set()
        self._previous: Dict[int, object] = {}

    @property
    def stopping(self) -> bool:
        return self.signum is not None

    def install(self) -> None:
        """Catch SIGINT and SIGTERM (main thread only) until :meth:`uninstall`."""
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._previous[sig] = signal.signal(sig, self._on_signal)

    def uninstall(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)  # type: ignore[arg-type]
        self._previous.clear()

    def _on_signal(self, signum: int, frame) -> None:
        self.stop(signum)

    def stop(self, signum: int) -> None:
        """Stop the run: SIGTERM to every worker (again on a second signal)."""
        if self.signum is None:
            self.signum = signum
        with self._lock:
            workers = list(self._workers)
        for proc in workers:
            self._terminate(proc)

    @staticmethod
    def _terminate(proc: subprocess.Popen) -> None:
        if proc.poll() is None:
            try:
                proc.send_signal(signal.SIGTERM)
            except ProcessLookupError:
                pass

    def add(self, proc: subprocess.Popen) -> None:
        with self._lock:
            self._workers.add(proc)
        if self.stopping:   # the signal came while it was starting
            self._terminate(proc)

    def discard(self, proc: subprocess.Popen) -> None:
        with self._lock:
            self._workers.discard(proc)


def _run_worker(cell: CellSpec, deliver, log, stopper: Optional[Stopper] = None,
                on_all_delivered=None) -> None:
    """Run one cell in its own process; ``deliver(row, steps)`` per episode as it ends;
    ``on_all_delivered()`` once its last episode is in (its stack is still shutting down)."""
    spec_file = write_spec(cell, Path(cell.log_dir))
    proc = subprocess.Popen(worker_command(spec_file), stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if stopper is not None:
        stopper.add(proc)
    try:
        errors: List[str] = []
        reader = threading.Thread(target=lambda: errors.extend(proc.stderr), daemon=True)
        reader.start()
        delivered = 0
        for line in proc.stdout:
            try:
                episode = decode_episode(line)
            except (ValueError, KeyError) as exc:   # a line cut short: the episode reruns
                errors.append(f"unreadable episode line ({exc}): {line[:80]!r}\n")
                continue
            if episode is not None:
                deliver(*episode)
                delivered += 1
                if delivered == len(cell.episodes) and on_all_delivered is not None:
                    on_all_delivered()
        proc.wait()
        reader.join(5.0)
    except BaseException:
        # An episode could not be recorded (a full disk): the worker must not run on, nor
        # its stack: SIGTERM makes it stop the stack; the reason goes up.
        Stopper._terminate(proc)
        for _ in proc.stdout:       # drained, so that its last lines never block it
            pass
        proc.wait()
        raise
    finally:
        if stopper is not None:
            stopper.discard(proc)
    if errors:
        log.write("".join(errors))
    if proc.returncode != 0 and not (stopper is not None and stopper.stopping):
        last = errors[-1].strip() if errors else f"exit code {proc.returncode}"
        raise RuntimeError(last)


def run_local_cell(cell: CellSpec, deliver, log, stopper: Optional[Stopper] = None,
                   on_all_delivered=None, program: str = NAME) -> None:
    """Run one cell on this machine, as :func:`_run_worker` does, but a failed attempt (its
    stack failed: a port taken by another program between its pick and its bind, a node that
    died) runs again with the episodes still missing, on fresh ports, up to
    :data:`MAX_ATTEMPTS` attempts, as on a cluster; then RuntimeError with the last reason.
    Each attempt is written in the cell's worker log, a retry said on stderr (``program``
    names the command). An episode that cannot be recorded (a full disk) is not retried: its
    OSError goes up at once."""
    name = cell_name(cell)
    wanted = EpisodeRanges.of(cell.episodes)
    delivered: Set[int] = set()

    def take(row, steps) -> None:
        # (Attempts run one after another, each without the episodes delivered before it:
        # none comes twice.)
        delivered.add(row.episode)
        deliver(row, steps)
        if len(delivered) == len(wanted) and on_all_delivered is not None:
            on_all_delivered()

    for attempt in range(1, MAX_ATTEMPTS + 1):
        failure = ""
        missing = without(wanted, delivered)
        log.write(f"{program}: {name}: attempt {attempt} of {MAX_ATTEMPTS} "
                  f"({len(missing)} episodes)\n")
        log.flush()
        try:
            _run_worker(dataclasses.replace(cell, episodes=missing), take, log, stopper)
        except RuntimeError as exc:
            failure = str(exc)
        if len(delivered) == len(wanted) or (stopper is not None and stopper.stopping):
            return
        failure = failure or "the worker ended without all its episodes"
        log.write(f"{program}: {name}: attempt {attempt} failed: {failure}\n")
        log.flush()
        if attempt < MAX_ATTEMPTS:
            say(f"{program}: cell {name}: {failure}; its {len(wanted) - len(delivered)} "
                f"episodes still missing run again (attempt {attempt + 1} of {MAX_ATTEMPTS})")
    raise RuntimeError(f"failed {MAX_ATTEMPTS} times, the last: "
                       f"{failure.removeprefix('failed: ')}")


def run_grid(cells: List[CellSpec], store, jobs: int,
             stopper: Optional[Stopper] = None, program: str = NAME,
             gate: Optional[Callable[[CellSpec], Optional[CellSpec]]] = None,
             worker: Optional[Callable[..., None]] = None,
             status: Callable[[], str] = lambda: "") -> dict:
    """Run the cells side by side; record episodes as they come (``store.add(row, steps)``).
    Returns run figures. ``program`` names the progress bar and the messages (hrc_fit runs
    grids too). A robot cell starts once the ``no_robot`` cells of its (human model, seed) in
    ``cells`` are over (the human alone comes first); ``gate(cell)`` then gives the cell to
    run (fewer episodes, or None: nothing to run). ``worker`` runs one cell (by default
    :func:`run_local_cell`, local processes; on a cluster,
    :meth:`ros_hrc.experiment.cluster.ClusterRun.run_cell`); ``status()`` leads the progress
    bar's text."""
    worker = worker or functools.partial(run_local_cell, program=program)
    from tqdm import tqdm

    stopper = stopper or Stopper()
    total = sum(len(c.episodes) for c in cells)
    started = time.monotonic()
    figures = {"episodes": 0, "simulated_seconds": 0.0}
    failures: List[str] = []
    lock = threading.Lock()   # the store and the bar, from every worker's thread
    logs = Path(cells[0].log_dir)
    logs.mkdir(parents=True, exist_ok=True)
    with tqdm(total=total, unit="episode", desc=program, dynamic_ncols=True,
              mininterval=0.5 if sys.stderr.isatty() else 10.0) as bar:

        def deliver(row, steps) -> None:
            with lock:
                store.add(row, steps)
                figures["episodes"] += 1
                figures["simulated_seconds"] += row.sim_seconds
                bar.set_postfix_str(f"{status()}{row.human_model}/{row.robot_policy} "
                                    f"seed {row.seed}: "
                                    f"{row.end_reason} in {row.steps} steps")
                bar.update(1)

        # `jobs` cells step at a time. A cell whose episodes are all in gives its place to the
        # next one while its stack shuts down, so that start-up and shut-down overlap.
        stepping = threading.BoundedSemaphore(max(1, jobs))
        # The human alone first: a robot cell waits for the no_robot cells of its stream.
        alone_over: Dict[Tuple[str, int], threading.Event] = {}
        alone_left: Dict[Tuple[str, int], int] = defaultdict(int)
        for cell in cells:
            if cell.robot_policy == ALONE_POLICY:
                alone_over.setdefault((cell.human_model, cell.seed), threading.Event())
                alone_left[(cell.human_model, cell.seed)] += 1

        def alone_cell_over(cell: CellSpec, counted: List[bool]) -> None:
            key = (cell.human_model, cell.seed)
            with lock:
                if counted:
                    return
                counted.append(True)
                alone_left[key] -= 1
                if alone_left[key] == 0:
                    alone_over[key].set()

        def run(cell: CellSpec) -> None:
            if cell.robot_policy == ALONE_POLICY:
                counted: List[bool] = []
                try:
                    # Its robots may start once its episodes are in, while its stack stops.
                    run_cell(cell, lambda: alone_cell_over(cell, counted))
                finally:
                    alone_cell_over(cell, counted)
                return
            over = alone_over.get((cell.human_model, cell.seed))
            while over is not None and not over.wait(0.5):
                if stopper.stopping:
                    return
            if gate is not None:
                with lock:
                    gated = gate(cell)
                if gated is None:
                    return
                cell = gated
            run_cell(cell)

        def run_cell(cell: CellSpec, all_delivered: Callable[[], None] = lambda: None) -> None:
            stepping.acquire()
            released = threading.Event()

            def release() -> None:
                if not released.is_set():
                    released.set()
                    stepping.release()
                    all_delivered()
            try:
                if stopper.stopping:
                    return
                name = cell_name(cell)
                cell_logs = Path(cell.log_dir)
                cell_logs.mkdir(parents=True, exist_ok=True)
                with open(cell_logs / f"{name}.worker.log", "a") as log:
                    try:
                        worker(cell, deliver, log, stopper, on_all_delivered=release)
                    except (RuntimeError, OSError) as exc:
                        with lock:
                            failures.append(f"{name}: {exc}")
                            bar.write(f"{program}: cell failed: {failures[-1]}")
            finally:
                release()

        with ThreadPoolExecutor(max_workers=2 * max(1, jobs)) as pool:
            list(pool.map(run, cells))
    wall = time.monotonic() - started
    episodes, sim = figures["episodes"], figures["simulated_seconds"]
    return {"episodes": episodes, "planned": total, "wall_seconds": wall,
            "simulated_seconds": sim, "failed_cells": failures, "jobs": jobs,
            "episodes_per_minute": episodes / wall * 60.0 if wall > 0 else 0.0,
            "speedup_over_real_time": sim / wall if wall > 0 else 0.0}


def report(store: ResultsStore, out: Path, plots: bool) -> None:
    """Summary (CSV and Markdown) and plots from everything recorded so far."""
    rows = store.episodes()
    if not rows:
        print(f"{NAME}: no episodes recorded yet in {out}")
        return
    summary = summarize(rows)
    csv_path, md_path = write_summary(summary, out / "summary.csv", out / "summary.md")
    print(Path(md_path).read_text())
    written = [str(store.episodes_path), str(store.steps_path), str(csv_path), str(md_path)]
    if plots:
        written.append(plot_outcomes(summary, out / "outcomes.png"))
        written.append(plot_success(summary, out / "success.png"))
        written.append(plot_time_gain(rows, out / "time_gain.png"))
        written.append(plot_belief(store.steps(), out / "belief.png"))
    print(f"{NAME}: written " + ", ".join(str(p) for p in written))


def open_results(directory: Path, argument: str):
    """The lock of a results directory (:func:`lock_directory`), or an HrcError in one line
    naming ``argument`` (another run holds it, or it cannot be made)."""
    try:
        return lock_directory(directory)
    except DirectoryLocked as exc:
        raise GridError(str(exc)) from None
    except OSError as exc:
        raise GridError(f"{argument} {directory}: {exc.strerror or exc}") from None


def run_stoppable(cells: List[CellSpec], store, jobs: int, words: Sequence[str],
                  out: Path, program: str = NAME,
                  gate: Optional[Callable[[CellSpec], Optional[CellSpec]]] = None,
                  cluster: Optional[str] = None, cluster_wait: Optional[float] = None
                  ) -> Tuple[Optional[dict], Optional[int]]:
    """:func:`run_grid` under SIGINT and SIGTERM: ``(figures, None)``, or, when a signal
    stopped it, ``(None, 128 + signal)`` after saying what is kept and how to resume.
    ``cluster`` (``--cluster``): the cells run as Ray tasks there
    (:mod:`ros_hrc.experiment.cluster`, the only place Ray is imported); a cluster that cannot
    be joined is one line and ``(None, 2)``."""
    stopper = Stopper()
    figures = None
    remote = None
    try:
        if cluster is not None:
            from ros_hrc.experiment.cluster import ClusterRun
            # Joined before the handlers go in: ray.init installs its own for SIGTERM.
            remote = ClusterRun(cluster, program, slots=jobs,
                                **({} if cluster_wait is None else {"no_node_wait": cluster_wait}))
            try:
                remote.connect()
            except HrcError as exc:
                print(f"{program}: {' '.join(str(exc).split())}", file=sys.stderr, flush=True)
                return None, 2
        stopper.install()
        try:
            if remote is None:
                figures = run_grid(cells, store, jobs, stopper, program=program, gate=gate)
            else:
                figures = run_grid(cells, store, remote.in_flight_limit, stopper,
                                   program=program, gate=gate, worker=remote.run_cell,
                                   status=remote.status)
                figures["cluster"] = remote.report()
        finally:
            stopper.uninstall()
    except KeyboardInterrupt:   # a signal before the handlers were in place
        stopper.stop(signal.SIGINT)
    finally:
        if remote is not None:
            remote.close()
    if not stopper.stopping:
        return figures, None
    name = signal.Signals(stopper.signum).name  # type: ignore[arg-type]
    print(f"\n{program}: stopped by {name}; {len(store.done())} episodes are kept in {out}. "
          f"Resume with: {shlex.join([program] + list(words))}", file=sys.stderr, flush=True)
    return None, 128 + int(stopper.signum)  # type: ignore[arg-type]


def _error(text: object) -> int:
    print(f"{NAME}: {' '.join(str(text).split())}", file=sys.stderr, flush=True)
    return 2


def file_error_line(exc: OSError) -> str:
    """``<file>: <why>`` of an I/O error (a full disk), for one line."""
    where = f"{exc.filename}: " if exc.filename else ""
    return f"{where}{exc.strerror or exc}"


def main(argv: Optional[list] = None) -> int:
    words = own_arguments(argv)
    try:
        args = build_parser().parse_args(words)
        validate_grid(args)
        if args.cluster is not None:
            check_cluster(args.cluster)
    except HrcError as exc:
        return _error(exc)
    except KeyboardInterrupt:
        return 130
    out = Path(args.out)        # absolute: validate_grid resolved it
    if args.cluster is None:    # on a cluster, 0 is the cluster's slots
        args.jobs = args.jobs or os.cpu_count() or 1
    try:
        lock = open_results(out, "--out")
    except HrcError as exc:
        return _error(exc)
    with lock:
        try:
            return _run_locked(args, out, words)
        except OSError as exc:      # a results file cannot be written: a full disk, ...
            _error(file_error_line(exc))
            return 1


def _run_locked(args: argparse.Namespace, out: Path, words: List[str]) -> int:
    try:
        store = ResultsStore(out)
        alone = AloneEpisodes(store, out, grid_has_alone=ALONE_POLICY in args.policies)
    except (OSError, ValueError) as exc:
        return _error(exc)
    adopted = alone.adopt_into_grid(args)
    cells = plan_alone_cells(args, alone) + plan_cells(args, store.done())
    counterfactual = sum(len(c.episodes) for c in cells if c.log_dir != str(out / "logs"))
    total = sum(len(c.episodes) for c in cells) - counterfactual
    grid = len(args.human_models) * len(args.policies) * len(args.seeds) * args.episodes
    print(f"{NAME}: {len(args.human_models)} human models x {len(args.policies)} robot policies "
          f"x {len(args.seeds)} seeds x {args.episodes} episodes = {grid} episodes; "
          f"{grid - total} already in {out}, {total} to run"
          + (f" ({adopted} taken from {alone.directory})" if adopted else "")
          + (f", and {counterfactual} of the human alone ({ALONE_POLICY}, for the "
             f"counterfactual, into {alone.directory})" if counterfactual else "")
          + (f", on {min(args.jobs, len(cells) or 1)} stacks side by side"
             if args.cluster is None else f", on the Ray cluster --cluster {args.cluster}"),
          flush=True)
    figures = None
    if cells:
        recorder = PairedRecorder(store, alone, args.in_sample)
        figures, stopped = run_stoppable(cells, recorder, args.jobs, words, out,
                                         gate=recorder.gate, cluster=args.cluster,
                                         cluster_wait=args.cluster_wait)
        if stopped is not None:
            return stopped
        print(f"{NAME}: {figures['episodes']} episodes in {figures['wall_seconds']:.1f} s "
              f"(the human-alone ones included): {figures['episodes_per_minute']:.1f} "
              f"episodes/min, {figures['simulated_seconds']:.1f} simulated s, "
              f"speed-up over real time x{figures['speedup_over_real_time']:.1f}")
        write_text_atomically(out / "run.json", json.dumps(figures, indent=2) + "\n")
    report(store, out, plots=not args.no_plots)
    if figures and figures["failed_cells"]:
        print(f"{NAME}: {len(figures['failed_cells'])} cells failed (logs in {out / 'logs'}); "
              "run again to retry them", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
