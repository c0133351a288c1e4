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
be written is one line naming it, exit status 1; a full disk under the run (the results',
every stack's logs, ``$ROS_HOME``) stops it within seconds, in one line naming the disk and
what was kept, exit status 1. ``--out`` is locked for the whole run: a second run on the same directory is
refused. SIGINT or SIGTERM stops every cell's stack, keeps what was recorded and exits 130 or
143; the same command then resumes.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import List, Optional, Sequence

from ros_hrc import tasks
from ros_hrc.command_line import counted, own_arguments
from ros_hrc.errors import HrcError
from ros_hrc.experiment.arguments import (MAX_JOBS, MAX_STEP_LIMIT, OneLineParser, at_least,
                                          file_error_line, names_argument, say_one_line)
from ros_hrc.experiment.cluster import add_argument as add_cluster_argument
from ros_hrc.experiment.cluster import check_reachable as check_cluster
from ros_hrc.experiment.episode import DEFAULT_POLICIES as POLICIES_BY_DEFAULT
from ros_hrc.experiment.episode import ALONE_POLICY, policy_names, robot_policy
from ros_hrc.experiment.grid import (DEFAULT_HUMANS, GridError, apply_task_defaults,
                                     check_held_out, expand_policies, plan_alone_cells,
                                     plan_cells, resolve_files, task_of)
from ros_hrc.experiment.plots import (NothingToPlot, plot_belief, plot_outcomes, plot_success,
                                      plot_time_gain)
from ros_hrc.experiment.pool import add_stack_argument, finish_run, run_stoppable, say_written
from ros_hrc.experiment.recording import AloneEpisodes, PairedRecorder, open_results
from ros_hrc.experiment.stack import MAX_EPISODES, check_launch_settings
from ros_hrc.experiment.statistics import headline, summarize, write_summary
from ros_hrc.experiment.store import ResultsStore
from ros_hrc.model_files import user_path
from ros_hrc.experiment.sequence_rows import CEILING
from ros_hrc.experiment.sequences import (ceiling_model, MAX_SEQUENCE, model_selectors, PER_TYPE,
                                          STUDY_ROBOTS,
                                          SELECTOR_MODEL_FILE,
                                          check_trained_elsewhere, expand_selectors,
                                          load_study_library, resolve_schedules,
                                          plan_sequence_cells, selector_model_file)
from ros_hrc.experiment.sequence_study import run_sequences
from ros_hrc import registry, settings
from ros_hrc.models import (ModelNotFound, load_human_model, load_robot_model,
                                 positional_mapping_line)
from ros_hrc.settings import SettingError
from ros_hrc.pomdp.planner import planner_class

NAME = "hrc_experiment"
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


class GridParser(OneLineParser):
    """The grid's parser: what ``--task`` changes (its humans, its policies) is filled in once
    the task is known (:func:`apply_task_defaults`)."""

    def parse_known_args(self, args=None, namespace=None):  # type: ignore[override]
        parsed, rest = super().parse_known_args(args, namespace)
        apply_task_defaults(parsed)
        return parsed, rest


def seeds_argument(text: str) -> List[int]:
    """Seeds, comma-separated, each as hrc.launch's ``seed`` takes it."""
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
                   help=f"robot policies, comma-separated, of {', '.join(policy_names())}, "
                        f"reactive@N, an installed package's or module:NAME (docs/extending.md; "
                        f"the task's: {DEFAULT_POLICIES} for the seed, "
                        f"{','.join(tasks.get('fabric').study_policies)} for fabric)")
    p.add_argument("--reactive-budgets", type=budgets_argument, default=[],
                   help="also run the reactive robot with each of these budgets (policies "
                        "reactive@N), e.g. 1..10 or 2,4,8 (none: no sweep, the default); the "
                        "summary names the best. The seed's budget is observations before it "
                        "helps; fabric's is simulated seconds without success (its "
                        "reactive_wait, the authors' 15)")
    p.add_argument("--seeds", type=seeds_argument, default=seeds_argument(DEFAULT_SEEDS),
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
    add_stack_argument(p)
    p.add_argument("--bag", action=argparse.BooleanOptionalAction, default=False,
                   help="also record /hrc/status as a rosbag (default: no)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_sequence_arguments(p)
    return p


#: The selectors of a sequence study when --selectors is not given (the issue's study).
DEFAULT_SELECTORS = "bpr,bandit,random,oracle,fixed"
#: Sequences per cell when --episodes is not given with --sequence: the issue's "at least 5
#: independent repetitions" (each sequence is L tasks, paired task by task across selectors).
DEFAULT_SEQUENCES = 5
#: Options that mean something only in a sequence study, and those only in an episode one.
SEQUENCE_ONLY = ("selectors", "library", "schedule", "selector_model",
                 "ceiling_models") + settings.LEARNING_SETTINGS
EPISODE_ONLY = ("policies", "reactive_budgets")


def add_sequence_arguments(p: argparse.ArgumentParser) -> None:
    """The options of a sequence study (``--sequence L``; docs/experiments.md, "Sequences")."""
    p.add_argument("--sequence", type=at_least(1, MAX_SEQUENCE), default=None, metavar="L",
                   help="run sequences of L tasks instead of episodes: a cell is (schedule, "
                        "selector, seed), its stack up for the whole sequence (tasks:=L), the "
                        "robot's selector choosing a library policy before each task; "
                        f"--episodes N is then N independent sequences per cell "
                        f"({DEFAULT_SEQUENCES})")
    p.add_argument("--selectors", type=names_argument, default=None,
                   help=f"with --sequence: selectors, comma-separated, of "
                        f"{', '.join(registry.BUILT_IN[registry.SELECTORS])} (docs/selectors.md), "
                        f"{', '.join(STUDY_ROBOTS)} (docs/learning.md; {CEILING} needs "
                        "--ceiling-models), fixed (every library policy, as fixed:<policy>), "
                        "an installed package's or module:Class (docs/extending.md); default "
                        f"{DEFAULT_SELECTORS}")
    p.add_argument("--library", default=None,
                   help="with --sequence: the policy library, a manifest or a folder holding "
                        "library.toml (auto: the task's)")
    p.add_argument("--schedule", type=names_argument, default=None,
                   help=f"with --sequence: who plays the tasks, comma-separated: {PER_TYPE} "
                        "(one cell per --human-models type, the default), fabric (FABRIC's "
                        "10 types x 30 tasks; --sequence 300 plays it whole) or a schedule file")
    p.add_argument("--ceiling-models", default=None, metavar="DIR",
                   help="with --sequence and --selectors pomdp_ceiling: a folder of robot "
                        "models, <human>.pomdp each fitted on other seeds of that human (the "
                        "ceiling: a robot that knows its human; docs/learning.md)")
    for name in settings.LEARNING_SETTINGS:
        # The learning robot's settings, as hrc.launch takes them (checked by its table).
        settings.add_argument(p, name, default=None,
                              help=f"with --sequence: the learning robot's {name} "
                                   f"(hrc.launch's; default {settings.default(name)})")
    p.add_argument("--selector-model", default=None,
                   help="with --sequence: the selector model of the BPRs and the oracle (auto: "
                        "selector_model.json beside the library's manifest; make "
                        "train-selector writes it)")


def check_mode(args: argparse.Namespace, words: Sequence[str]) -> None:
    """Options of the other mode are refused (one line); a sequence study's defaults set."""
    given = {w.split("=", 1)[0][2:].replace("-", "_") for w in words if w.startswith("--")}
    if args.sequence is None:
        stray = [n for n in SEQUENCE_ONLY if n in given]
        if stray:
            raise GridError(f"--{stray[0].replace('_', '-')} needs --sequence L (a selector "
                            "chooses between the tasks of a sequence)")
        return
    stray = [n for n in EPISODE_ONLY if n in given]
    if stray:
        raise GridError(f"--{stray[0].replace('_', '-')} is for episodes; with --sequence the "
                        "robot's policies are the library's, chosen by --selectors")
    if "episodes" not in given:
        args.episodes = DEFAULT_SEQUENCES
    args.selectors = args.selectors or names_argument(DEFAULT_SELECTORS)
    args.library = args.library or "auto"
    args.schedule = args.schedule or [PER_TYPE]
    args.selector_model = args.selector_model or "auto"
    if args.ceiling_models:
        args.ceiling_models = str(user_path(args.ceiling_models))


def validate_sequences(args: argparse.Namespace) -> List[str]:
    """Check a sequence study before any stack starts: the human models against the task,
    the library (loaded and checked, ``--library``), the selectors (``fixed`` expanded), the
    schedules, the selector model (a selector that needs one without one names
    ``make train-selector``; one of another task or library refused by its loader; one
    trained on the study's seeds refused: :func:`check_trained_elsewhere`), every cell's
    launch settings. HrcError with one line; returns warning lines."""
    resolve_files(args)
    for human in dict.fromkeys(args.human_models):
        try:
            load_human_model(args.human_files[human], task_of(args))
        except ModelNotFound as exc:
            raise GridError(f"--human-models: {exc}") from None
    library = load_study_library(args)
    args.library_manifest = str(library.manifest)
    args.library_policies = library.names()
    args.selectors = expand_selectors(args.selectors, library.names())
    resolve_schedules(args)
    if CEILING in args.selectors:
        # The ceiling knows its one human: per type only, each human's model checked now.
        if args.schedule != [PER_TYPE]:
            raise GridError(f"--selectors {CEILING}: the ceiling knows one human, so it plays "
                            f"--schedule {PER_TYPE} alone")
        for human in dict.fromkeys(args.human_models):
            ceiling_model(args, human)
    args.selector_model_file = selector_model_file(args, library)
    users = model_selectors(args.selectors)
    warnings: List[str] = []
    if users and args.selector_model_file is None:
        expected = Path(library.manifest).parent / SELECTOR_MODEL_FILE
        raise GridError(f"--selectors {','.join(users)}: no selector model {expected}; make "
                        "train-selector writes it, or give --selector-model")
    if args.selector_model_file is not None and users:
        from ros_hrc.agents.selector_model import load_selector_model
        try:
            model = load_selector_model(args.selector_model_file, task_of(args).name,
                                        library.names())
        except HrcError as exc:
            raise GridError(f"--selector-model: {exc}") from None
        warnings += check_trained_elsewhere(args, model.header.get("seeds", ()))
        warnings += adopt_model_trials(args, model.header.get("max_trials"))
    for spec in plan_sequence_cells(args, set())[:1]:
        check_launch_settings(spec)
    return warnings


def adopt_model_trials(args: argparse.Namespace, model_trials: Optional[int]) -> List[str]:
    """A selector model's μ, σ and signatures are of its policies as DESPOT planned them with
    the trials its header names: the study plans with the same. Without ``--max-trials`` the
    study takes the model's (the returned line says so); another number is refused in one
    line (GridError). A model whose header names none (older files) changes nothing."""
    if not model_trials:
        return []
    model_trials = int(model_trials)
    file = args.selector_model_file
    if not args.max_trials:
        args.max_trials = model_trials
        return [f"DESPOT plans with {model_trials} trials per decision, as the selector model "
                f"{file} was trained (--max-trials to choose)"]
    if args.max_trials != model_trials:
        raise GridError(f"--max-trials {args.max_trials}: the selector model {file} was trained "
                        f"with DESPOT at {model_trials} trials per decision, and its utilities "
                        f"are of the policies planned so; give --max-trials {model_trials}, or "
                        f"retrain it with --max-trials {args.max_trials}")
    return []


def validate_grid(args: argparse.Namespace) -> None:
    """Check the whole grid before any stack starts: the policies, every human model and the
    robot model against the task's tables, every cell's launch settings. Raises HrcError with
    one line naming the argument or the file and the offending names. Once all is good, each
    model file named by position gets its mapping printed, one line per file."""
    expand_policies(args)
    for policy in dict.fromkeys(args.policies):
        try:
            found = robot_policy(policy)
        except KeyError as exc:
            raise GridError(f"--policies: {exc}") from None
        try:
            planner_class(found.planner)
        except ValueError as exc:
            raise GridError(f"--policies: {policy}: {exc}") from None
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


def report(store: ResultsStore, out: Path, plots: bool, written_before: Sequence[Path] = ()
           ) -> None:
    """Summary (CSV and Markdown) and plots from everything recorded so far; the terminal
    gets the headline table and where the rest is, then the list of what the run's end wrote
    (``written_before``: run.json)."""
    rows = store.episodes()
    if not rows:
        print(f"{NAME}: no episodes recorded yet in {out}")
        return
    summary = summarize(rows)
    csv_path, md_path = write_summary(summary, out / "summary.csv", out / "summary.md")
    print(headline(summary))
    print(f"{NAME}: the whole summary (paired tests, best reactive budget, other measures): "
          f"{md_path}")
    written = [store.episodes_path, store.steps_path, *written_before, csv_path, md_path]
    if plots:
        for name, draw in (("outcomes.png", lambda path: plot_outcomes(summary, path)),
                           ("success.png", lambda path: plot_success(summary, path)),
                           ("time_gain.png", lambda path: plot_time_gain(rows, path)),
                           ("belief.png", lambda path: plot_belief(store.steps(), path))):
            try:
                written.append(draw(out / name))
            except NothingToPlot as why:
                print(f"{NAME}: {name} left out: {str(why).split(': ', 1)[-1]}")
    say_written(NAME, out, written)


def _error(text: object) -> int:
    return say_one_line(NAME, text)


def main(argv: Optional[list] = None) -> int:
    words = own_arguments(argv)
    try:
        args = build_parser().parse_args(words)
        check_mode(args, words)
        if args.sequence is None:
            validate_grid(args)
        else:
            for line in validate_sequences(args):
                print(f"{NAME}: {line}", file=sys.stderr, flush=True)
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
            if args.sequence is not None:
                return run_sequences(args, out, words, NAME)
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
    print(f"{NAME}: {counted(len(args.human_models), 'human model')} x "
          f"{counted(len(args.policies), 'robot policy', 'robot policies')} x {counted(len(args.seeds), 'seed')} "
          f"x {counted(args.episodes, 'episode')} = {counted(grid, 'episode')}; "
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
        figures, stopped = run_stoppable(cells, recorder, args.jobs, words, out, program=NAME,
                                         gate=recorder.gate, cluster=args.cluster,
                                         cluster_wait=args.cluster_wait,
                                         fresh_stacks=args.fresh_stacks)
        if stopped is not None:
            return stopped
        print(f"{NAME}: {figures['episodes']} episodes in {figures['wall_seconds']:.1f} s "
              f"(the human-alone ones included): {figures['episodes_per_minute']:.1f} "
              f"episodes/min, {figures['simulated_seconds']:.1f} simulated s, "
              f"speed-up over real time x{figures['speedup_over_real_time']:.1f}")
    return finish_run(NAME, figures, store, out, words,
                      lambda written: report(store, out, plots=not args.no_plots,
                                             written_before=written))


if __name__ == "__main__":
    sys.exit(main())
