"""hrc_fit: fit the robot model's T and O to the world, by running episodes through the stack.

    hrc_fit --human-models humanModel,distracted,walker --episodes 100 --seed 0 \\
            --prior robot --strength 5 --out models/robot/robot_fitted.pomdp

It runs ``--episodes`` episodes per human model through the real stack (one ``hrc.launch`` per
human model, as ``hrc_experiment`` does) with the exploring robot (``planner:=explore``: a
uniformly random robot action each step, seeded), so that every robot action is tried in every
state the humans reach. From each episode it counts what the robot model describes:

* transitions ``(s, a, s')``: the robot's true state at a step (the observer's label, by the
  task's tracker: the seed's :class:`ros_hrc.tasks.seed.RobotStateTracker`), the robot's action
  then, and the label at the next step. The first step starts from the model's start state
  with the task's idle action (the seed's ``rIdle``), as the robot process does (its first
  belief update). An episode that ends in success adds one more transition into the task's
  success state (the seed's S1: the robot's grasp or the human's ended it); one that
  ends otherwise (the object left the belt, the step limit) adds none: nothing says where the
  human would have gone.
* observations ``(a, s', o)``: the action before the step, the step's label, and the
  observation the observer sent.

It combines the counts with the prior model as a Dirichlet prior of ``--strength``
pseudo-counts per row (:func:`ros_hrc.pomdp.fit.fit_model`: rows the episodes never reached keep
the prior's), keeps the prior's rewards, discount and start, and writes a Cassandra ``.pomdp``
whose header says how it was made (human models, episodes, seed, prior, strength, counts),
with one machine-readable ``# hrc-fitted-on: {...}`` line per human model
(:mod:`ros_hrc.experiment.provenance`): ``hrc_experiment`` refuses to evaluate the model on
those streams unless ``--allow-in-sample``.

With ``--types`` each human model is a type (:mod:`ros_hrc.pomdp.typed`): T and O are fitted
on each human model's episodes alone (the same episodes, the same ``--prior`` and
``--strength``) and the fitted models are composed into one POMDP whose hidden state is (type,
state), states ``<state>__<type>``, with a uniform prior over the types: a robot that plans on
it infers which human it works with. Its header keeps one ``# hrc-fitted-on:`` line per human
model, as the pooled fit's. ``make fit-types`` regenerates the shipped
``models/robot/robot_types.pomdp`` (``ARGS="--task fabric"``: ``models/fabric/robot/``).

The episodes are kept in ``--runs`` (a results directory as ``hrc_experiment`` writes, with a
``fit.json`` naming the configuration), so running the same command again reuses them and
only refits; a ``--runs`` holding another configuration (or steps labelled by other labelling
code) is refused. The stack is seeded
(the human MDP, the exploring robot, a deterministic world), so the same seed gives the same
episodes and the same model. ``make fit`` regenerates the shipped
``models/robot/robot_fitted.pomdp``. No ROS here: the stacks run as ``hrc_experiment``'s cells.
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import inspect
import json
import os
import shlex
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp

from ros_hrc.command_line import counted, own_arguments, seed_argument
from ros_hrc.errors import HrcError, ModelError
from ros_hrc.experiment.arguments import (MAX_JOBS, MAX_STEP_LIMIT, OneLineParser, at_least,
                                          file_error_line, names_argument, say_one_line)
from ros_hrc.experiment.zoo import zoo_argument
from ros_hrc.experiment.cluster import add_argument as add_cluster_argument
from ros_hrc.experiment.pool import add_stack_argument
from ros_hrc.experiment.cluster import check_reachable as check_cluster
from ros_hrc import tasks
from ros_hrc.experiment.grid import task_launch_args, task_of, training_humans
from ros_hrc.experiment.pool import run_stoppable
from ros_hrc.experiment.provenance import FittedStreams, file_sha256
from ros_hrc.experiment.recording import open_results
from ros_hrc.experiment.stack import MAX_EPISODES, CellSpec, EpisodeRanges
from ros_hrc.experiment.rows import EpisodeRow, StepRow
from ros_hrc.experiment.store import ResultsStore
from ros_hrc import settings
from ros_hrc.tasks import seed as task
from ros_hrc.tasks.schedule import type_name
from ros_hrc.models import (ModelNotFound, load_human_model, load_robot_model, model_path,
                                 shown_path)
from ros_hrc.model_files import user_path
from ros_hrc.pomdp.output import check_writable, write_text_atomically
from ros_hrc.pomdp.fit import ExperienceCounts, fit_model, support_lines, write_fitted
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.type_names import check_type_name
from ros_hrc.pomdp.typed import compose
from ros_hrc.tasks.utility import utility_rewards

NAME = "hrc_fit"
POLICY = "explore"
#: hrc_fit fits on the zoo's fit set; hrc_experiment evaluates on the held-out humans.
DEFAULT_HUMANS = zoo_argument("fit")
CONFIG_FILE = "fit.json"
#: The files written by default, in the task's robot models folder.
POOLED_FILE, TYPES_FILE = "robot_fitted.pomdp", "robot_types.pomdp"


class FitError(HrcError):
    """hrc_fit cannot run: one line naming the argument or the file."""


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog=NAME, description=__doc__.split("\n\n")[0],
                      formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--human-models", type=names_argument, default=None,
                   help=f"human scenarios or .pomdpx files, comma-separated (the task's: "
                        f"{DEFAULT_HUMANS} for the seed, every shipped type for fabric)")
    p.add_argument("--episodes", type=at_least(1, MAX_EPISODES), default=100,
                   help="episodes per human model (100)")
    p.add_argument("--seed", type=seed_argument, default=0,
                   help="seed of the stacks: the human MDP and the exploring robot (0)")
    p.add_argument("--step-limit", type=at_least(1, MAX_STEP_LIMIT), default=None,
                   help="steps before an episode ends (the task's, as hrc_experiment: 15 for "
                        "the seed, 300 for fabric)")
    p.add_argument("--prior", default=None,
                   help="the robot model whose rows are the prior and whose rewards are kept "
                        "(a scenario name of the task's robot models or a file; the task's: "
                        "robot for the seed)")
    p.add_argument("--strength", type=_non_negative, default=5.0,
                   help="the prior's pseudo-counts per row; 0: the episodes' frequencies "
                        "wherever a row has any (5)")
    p.add_argument("--jobs", type=at_least(0, MAX_JOBS), default=0,
                   help="stacks run side by side (0: one per core; with --cluster, one per "
                        "ros_hrc slot of the cluster)")
    add_cluster_argument(p)
    add_stack_argument(p)
    settings.add_argument(p, "task")     # (#22) the task the episodes and the prior are of
    p.add_argument("--types", action="store_true",
                   help="fit T and O per human model, each a type, and compose them into one "
                        "model whose hidden state is (type, state), a uniform prior over the "
                        "types (the same episodes as without --types)")
    p.add_argument("--rewards", choices=("prior", "utility"), default="prior",
                   help="the fitted model's rewards: the prior's (prior), or the task's "
                        "utility per step, as a sequence's tasks are scored (utility: "
                        "ros_hrc.tasks.utility.utility_rewards, its time per step the "
                        "episodes' mean); docs/learning.md")
    p.add_argument("--runs", default=None,
                   help="where the episodes are kept, and found again (results/fit for the "
                        "seed, results/fit_TASK for another task)")
    p.add_argument("--out", default=None,
                   help=f"the .pomdp to write (in the task's robot models folder: "
                        f"{POOLED_FILE}, with --types {TYPES_FILE}; the seed's: "
                        f"models/robot/)")
    return p


def _non_negative(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number >= 0, got {text!r}") from None
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a number >= 0, got {text!r}")
    return value


def labels_fingerprint(which: tasks.Task) -> str:
    """A digest of the task's labelling code: steps recorded under other labels must not be
    counted (the steps keep the label they were given)."""
    tracker = type(which.new_tracker(which.default_human_model))
    text = inspect.getsource(tracker)
    if tracker is task.RobotStateTracker:    # the seed's thresholds live beside its class
        text += repr((task.EVALUATING_MAY_NEED_HELP, task.EVALUATING_NEEDS_HELP))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def configuration(args: argparse.Namespace) -> dict:
    """What decides the episodes: a ``--runs`` directory holds the episodes of one of these."""
    return {"human_models": list(args.human_models), "seed": args.seed,
            "step_limit": args.step_limit, "policy": POLICY,
            "labels": labels_fingerprint(task_of(args))}


def default_out(which: tasks.Task, types: bool) -> Path:
    """The file written when ``--out`` is not given: in the task's robot models folder."""
    return Path(which.model_dirs["robot"]) / (TYPES_FILE if types else POOLED_FILE)


def default_runs(which: tasks.Task) -> str:
    """Where the episodes are kept when ``--runs`` is not given: one folder per task (a
    folder holds the episodes of one configuration)."""
    return "results/fit" if which.name == tasks.DEFAULT_TASK else f"results/fit_{which.name}"


def check_arguments(args: argparse.Namespace) -> Model:
    """The models load and fit the task; the output is a .pomdp that can be written; with
    ``--types``, every human model names a type of its own. Every file argument is made
    absolute here, once, against the directory the command runs in (``args.prior``,
    ``args.out``, ``args.runs``, ``args.human_files``: the stacks run elsewhere). Returns the
    prior."""
    which = task_of(args)
    if args.out is None:
        args.out = str(default_out(which, args.types))
    if Path(args.out).suffix != ".pomdp":
        raise FitError(f"--out {args.out}: the fitted model is written as a Cassandra .pomdp")
    args.out = str(user_path(args.out))
    args.runs = str(user_path(args.runs or default_runs(which)))
    try:
        check_writable(args.out)        # not after hours of episodes
    except OSError as exc:
        raise FitError(f"--out {file_error_line(exc)}") from None
    try:
        # Not given: the task's own robot, humans and step limit.
        if args.prior is None:
            args.prior = which.default_robot_model
        if args.human_models is None:
            args.human_models = training_humans(which)
        if args.step_limit is None:
            args.step_limit = which.study_step_limit
        args.prior = str(model_path(args.prior, "robot", which))
        prior = load_robot_model(args.prior, which)
    except ModelNotFound as exc:
        raise FitError(f"--prior: {exc}") from None
    args.human_files = {}
    for human in dict.fromkeys(args.human_models):
        try:
            args.human_files[human] = str(model_path(human, "human", task_of(args)))
            load_human_model(args.human_files[human], task_of(args))
        except ModelNotFound as exc:
            raise FitError(f"--human-models: {exc}") from None
    if args.types:
        check_types(args.human_models)
        if args.rewards != "prior":
            raise FitError("--rewards utility: a model of human types keeps the prior's "
                           "rewards; fit the pooled model with it")
    if args.rewards == "utility" and not (which.robot_success_state
                                          and which.robot_warned_state):
        raise FitError(f"--rewards utility: task {which.name} names no success or warned "
                       f"robot state, so its utility has no per-step model")
    return prior


def seconds_per_step(episodes: Sequence[EpisodeRow]) -> float:
    """The simulated seconds an episode's step takes, on average over ``episodes``: the time
    a model of the utility charges a step (:func:`ros_hrc.tasks.utility.utility_rewards`)."""
    steps = sum(r.steps for r in episodes)
    if not steps:
        raise FitError("the episodes have no steps: no time per step to price")
    return sum(r.sim_seconds for r in episodes) / steps


def with_utility_rewards(model: Model, which: tasks.Task, step_seconds: float) -> Model:
    """``model`` with the task's utility as its rewards (T, O and the rest kept)."""
    R = utility_rewards(which, step_seconds)
    if list(model.states) != list(which.robot_states) or \
            list(model.actions) != list(which.robot_actions):
        raise FitError(f"the model's states and actions are not task {which.name}'s in its "
                       f"order: its utility cannot be written onto it")
    priced = dataclasses.replace(model, R=[sp.csr_matrix(np.asarray(r)) for r in R])
    priced.validate()
    return priced


def check_types(human_models: Sequence[str]) -> None:
    """FitError unless each human model names a type of its own (its scenario name or its
    file's stem) that a composed model's state names can carry."""
    seen: Dict[str, str] = {}
    for human in dict.fromkeys(human_models):
        name = type_name(human)
        try:
            check_type_name(name)
        except ModelError as exc:
            raise FitError(f"--human-models {human}: {exc}") from None
        if name in seen:
            raise FitError(f"--human-models: {seen[name]} and {human} are both type {name} "
                           "(--types names each type by its scenario name or file stem)")
        seen[name] = human


def plan_cells(args: argparse.Namespace, done: set) -> List[CellSpec]:
    """One cell per human model, the exploring robot, episodes not yet in ``--runs``."""
    cells = []
    for human in args.human_models:
        recorded = {e for h, p, seed, e in done if (h, p, seed) == (human, POLICY, args.seed)}
        missing = EpisodeRanges.missing(args.episodes, recorded)
        if missing:
            cells.append(CellSpec(human_model=human, robot_policy=POLICY, seed=args.seed,
                                  episodes=missing, step_limit=args.step_limit,
                                  log_dir=str(Path(args.runs) / "logs"),
                                  human_model_file=args.human_files[human],
                                  robot_model=str(args.prior),
                                  extra_args=task_launch_args(args)))
    return cells


def count_experience(model: Model, episodes: Iterable[EpisodeRow],
                     steps: Iterable[StepRow]) -> ExperienceCounts:
    """The transitions and observations of the given episodes (module docstring)."""
    by_episode: Dict[Tuple[str, str, int, int], List[StepRow]] = defaultdict(list)
    for step in steps:
        by_episode[(step.human_model, step.robot_policy, step.seed, step.episode)].append(step)
    start = model.states[int(model.initial_belief.argmax())]
    which = tasks.of_robot_states(model.states)
    counts = ExperienceCounts.for_model(model)
    for row in episodes:
        trace = sorted(by_episode.get((row.human_model, row.robot_policy, row.seed, row.episode),
                                      []), key=lambda s: s.step)
        # The robot starts idle: the task's idle action (the seed's rIdle).
        action = which.robot_idle_action
        state = start
        for step in trace:
            counts.add_step(state, action, step.robot_state, step.observation, model)
            state, action = step.robot_state, step.robot_action
        if trace and row.end_reason == "success":
            counts.add_transition(state, action, which.robot_success_state, model)
    return counts


@dataclass
class TypeExperience:
    """What one type (``--types``: one human model) contributed: its episodes, its steps and
    their counts."""
    human_model: str
    episodes: int
    steps: int
    counts: ExperienceCounts


def count_types(model: Model, human_models: Sequence[str], episodes: Iterable[EpisodeRow],
                steps: Iterable[StepRow]) -> Dict[str, TypeExperience]:
    """Each human model's experience on its own (:func:`count_experience`), by type name, in
    the order of ``human_models``."""
    episodes_of: Dict[str, List[EpisodeRow]] = defaultdict(list)
    steps_of: Dict[str, List[StepRow]] = defaultdict(list)
    for row in episodes:
        episodes_of[row.human_model].append(row)
    for step in steps:
        steps_of[step.human_model].append(step)
    return {type_name(human): TypeExperience(human, len(episodes_of[human]),
                                             len(steps_of[human]),
                                             count_experience(model, episodes_of[human],
                                                              steps_of[human]))
            for human in dict.fromkeys(human_models)}


def fit_types(prior: Model, experience: Mapping[str, TypeExperience], strength: float,
              name: str) -> Model:
    """One model per type fitted to that type's counts alone (:func:`fit_model`, the same
    prior and strength), composed into one model of types with a uniform prior over them."""
    return compose({t: fit_model(prior, e.counts, strength, name=t)
                    for t, e in experience.items()}, name=name)


def header_lines(args: argparse.Namespace, prior_path: str, episodes: int, steps: int,
                 counts: ExperienceCounts, step_seconds: Optional[float] = None) -> List[str]:
    """The pooled fit's header; ``step_seconds``: its rewards are the task's utility, a step
    priced at that many simulated seconds (``--rewards utility``)."""
    kept = ("rewards, discount, start, names: the prior's" if step_seconds is None else
            f"discount, start, names: the prior's; rewards: the task's utility per step "
            f"(ros_hrc.tasks.utility.utility_rewards), {step_seconds:.4f} simulated s a step "
            f"(the episodes' mean)")
    return [
        f"The robot model fitted to the world by hrc_fit: T and O are Dirichlet posterior "
        f"means of {prior_path} (strength {args.strength:g} pseudo-counts per row) and "
        f"{episodes} episodes of the stack;",
        f"{kept}. Regenerate with `make fit`:",
        *how_lines(args),
        f"experience: {steps} steps; {counts.n_transitions} transitions, "
        f"{counts.n_observations_counted} observations",
        *provenance_lines(args),
    ]


def types_header_lines(args: argparse.Namespace, prior_path: str, model: Model,
                       experience: Mapping[str, TypeExperience]) -> List[str]:
    which = task_of(args)
    make = "make fit-types" + ("" if which.name == tasks.DEFAULT_TASK
                               else f' ARGS="--task {which.name}"')
    n = len(experience)
    return [
        f"A robot model of {n} human types, fitted to the world by hrc_fit --types: one model "
        f"per human model (a type), whose T and O are Dirichlet posterior means of "
        f"{prior_path} (strength {args.strength:g} pseudo-counts per row) and that human "
        f"model's episodes of the stack alone,",
        f"composed (ros_hrc.pomdp.typed) into one POMDP whose hidden state is (type, state): "
        f"states <state>__<type>, {n} types x {model.n_states // n} states = {model.n_states}, "
        "a uniform prior over the types, no transition between types;",
        f"rewards, discount, start, names: the prior's, in every type. Regenerate with "
        f"`{make}`:",
        *how_lines(args),
        f"types: {', '.join(experience)}",
        *[f"experience of type {t}: {e.episodes} episodes, {e.steps} steps; "
          f"{e.counts.n_transitions} transitions, {e.counts.n_observations_counted} "
          f"observations" for t, e in experience.items()],
        *provenance_lines(args),
    ]


def how_lines(args: argparse.Namespace) -> List[str]:
    """The header's command, episodes and robot: how the episodes were made."""
    which = task_of(args)
    tracker = type(which.new_tracker(which.default_human_model))
    labels = ("ros_hrc.loop.task.RobotStateTracker" if tracker is task.RobotStateTracker
              else f"{tracker.__module__}.{tracker.__qualname__}")
    return [
        f"  hrc_fit {shlex.join(args.words)}" if args.words else "  hrc_fit",
        f"human models: {', '.join(args.human_models)}; episodes per model: {args.episodes}; "
        f"step limit: {args.step_limit}; seed: {args.seed}",
        "robot: planner:=explore (a uniformly random action each step); true states: the "
        f"observer's labels ({labels})",
    ]


def provenance_lines(args: argparse.Namespace) -> List[str]:
    """The header's last lines: the streams fitted on, for people and for hrc_experiment."""
    return [
        "the streams fitted on, one line per human model (hrc_experiment refuses to evaluate "
        "this model on them unless --allow-in-sample):",
        *fitted_on_lines(args),
        "",
    ]


def fitted_on_lines(args: argparse.Namespace) -> List[str]:
    """The machine-readable header lines (:mod:`ros_hrc.experiment.provenance`): each human
    model (by its file's contents), the seed and the episodes fitted on."""
    return [FittedStreams(human, file_sha256(args.human_files[human]), args.seed,
                          (0, args.episodes)).line()
            for human in dict.fromkeys(args.human_models)]


def _error(text: object) -> int:
    return say_one_line(NAME, text)


def main(argv: Optional[Sequence[str]] = None) -> int:
    words = own_arguments(argv)
    try:
        args = build_parser().parse_args(words)
        args.words = list(words)
        prior = check_arguments(args)
        if args.cluster is not None:
            check_cluster(args.cluster)
    except HrcError as exc:
        return _error(exc)
    runs = Path(args.runs)          # absolute: check_arguments resolved it
    if args.cluster is None:    # on a cluster, 0 is the cluster's slots
        args.jobs = args.jobs or os.cpu_count() or 1
    try:
        with open_results(runs, "--runs"):
            return _run_locked(args, runs, prior, words)
    except HrcError as exc:
        return _error(exc)
    except OSError as exc:      # a file that cannot be written: a full disk, ...
        _error(file_error_line(exc))
        return 1


def _run_locked(args: argparse.Namespace, runs: Path, prior: Model, words: List[str]) -> int:
    config_path = runs / CONFIG_FILE
    config = configuration(args)
    if config_path.exists():
        try:
            kept = json.loads(config_path.read_text())
        except (OSError, ValueError) as exc:
            raise FitError(f"{config_path}: unreadable ({exc})") from None
        if kept != config:
            raise FitError(f"--runs {runs} holds the episodes of another configuration "
                           f"({json.dumps(kept)}); choose another --runs or delete it")
    try:
        store = ResultsStore(runs)
    except (OSError, ValueError) as exc:
        raise FitError(exc) from None
    write_text_atomically(config_path, json.dumps(config) + "\n")
    cells = plan_cells(args, store.done())
    wanted = len(args.human_models) * args.episodes
    todo = sum(len(c.episodes) for c in cells)
    print(f"{NAME}: {counted(len(args.human_models), 'human model')} x "
          f"{counted(args.episodes, 'episode')} with the exploring robot = "
          f"{counted(wanted, 'episode')}; {wanted - todo} already in {runs}, {todo} to "
          f"run" + ("" if args.cluster is None else f", on the Ray cluster --cluster "
                                                     f"{args.cluster}"), flush=True)
    if cells:
        figures, stopped = run_stoppable(cells, store, args.jobs, words, runs, program=NAME,
                                         cluster=args.cluster, cluster_wait=args.cluster_wait,
                                         fresh_stacks=args.fresh_stacks)
        if stopped is not None:
            return stopped
        if figures and figures["failed_cells"]:
            raise FitError(f"{len(figures['failed_cells'])} stacks failed (logs in "
                           f"{runs / 'logs'}): {figures['failed_cells'][0]}; run again to retry")
    humans = set(args.human_models)

    def wanted_row(r) -> bool:      # no set of every key: --episodes may be large
        return (r.human_model in humans and r.robot_policy == POLICY and r.seed == args.seed
                and r.episode < args.episodes)
    episodes = [r for r in store.episodes() if wanted_row(r)]
    steps = [s for s in store.steps() if wanted_row(s)]
    if len(episodes) < wanted:
        raise FitError(f"only {len(episodes)} of {wanted} episodes are in {runs}; run again")
    prior_path = shown_path(args.prior)
    out = Path(args.out)
    if args.types:
        experience = count_types(prior, args.human_models, episodes, steps)
        fitted = fit_types(prior, experience, args.strength, name=out.stem)
        write_fitted(fitted, out, types_header_lines(args, prior_path, fitted, experience))
        for name, share in experience.items():
            for line in support_lines(prior, share.counts):
                print(f"{NAME}: type {name}: {line}")
        kind = f"{len(experience)} types, {fitted.n_states} states"
    else:
        counts = count_experience(prior, episodes, steps)
        fitted = fit_model(prior, counts, args.strength, name=out.stem)
        step_seconds = seconds_per_step(episodes) if args.rewards == "utility" else None
        if step_seconds is not None:
            fitted = with_utility_rewards(fitted, task_of(args), step_seconds)
        write_fitted(fitted, out, header_lines(args, prior_path, len(episodes), len(steps),
                                               counts, step_seconds))
        for line in support_lines(prior, counts):
            print(f"{NAME}: {line}")
        kind = f"{fitted.n_states} states"
    print(f"{NAME}: wrote {out} ({kind}; {len(episodes)} episodes, {len(steps)} steps, prior "
          f"{prior_path}, strength {args.strength:g})", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
