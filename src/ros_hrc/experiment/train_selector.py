"""hrc_train_selector: the selector model from our own runs (``make train-selector``).

For every (human type, library policy) pair of the task, plays ``--tasks-per-pair`` tasks (K,
FABRIC's 50 by default: ``exp4_7000t`` = 10 types x 14 policies x 50 tasks) through the real
stack, each pair as one ``fixed:<policy>`` sequence of K tasks on the trainer's own seeds, then
writes the selector model (``ros_hrc.agents.selector_model``: the utility's mean and standard
deviation per pair, the signature codes' distribution per pair) with a header that says how,
from what, on which seeds and by which command.

    hrc_train_selector --task fabric [--tasks-per-pair 50] [--seeds 4] [--leave-out TYPE]
                       [--out models/fabric/selector_model.json] [--runs DIR]

The runs are a sequence study of their own (``hrc_experiment --sequence K --selectors fixed
--schedule per-type``, into ``--runs``), so they resume as a study does: the same command
again runs only the pairs not yet recorded, and a later model (another ``--leave-out``) is
written from the runs already there. ``--leave-out TYPE`` writes a model without that type,
for the study's types the selector was not trained on. The study refuses to evaluate a model
on the seeds it was trained on (docs/experiments.md, "Sequences"): the trainer's default seed
is 4, the study's 2 (hrc_fit's 0; 1 and 3 were spent on tuning, docs/experiments.md).
"""
from __future__ import annotations

import argparse
import datetime
import os
import shlex
import sys
from pathlib import Path
from typing import List, Optional, Sequence

from ros_hrc import settings, tasks
from ros_hrc.agents.selector_model import (TrainingTask, from_tasks, load_selector_model,
                                           write_selector_model)
from ros_hrc.command_line import counted, own_arguments
from ros_hrc.errors import HrcError
from ros_hrc.experiment.arguments import (MAX_JOBS, MAX_STEP_LIMIT, OneLineParser, at_least,
                                          file_error_line, names_argument, say_one_line)
from ros_hrc.experiment.cli import DEFAULT_SEEDS as STUDY_SEEDS
from ros_hrc.experiment.cli import seeds_argument
from ros_hrc.experiment.cli import build_parser as study_parser
from ros_hrc.experiment.cli import check_mode, validate_sequences
from ros_hrc.experiment.cluster import add_argument as add_cluster_argument
from ros_hrc.experiment.cluster import check_reachable as check_cluster
from ros_hrc.experiment.grid import GridError, training_humans
from ros_hrc.experiment.recording import open_results
from ros_hrc.experiment.sequence_rows import SequenceStore, TaskRow
from ros_hrc.experiment.sequence_study import run_sequences
from ros_hrc.experiment.sequences import FIXED, PER_TYPE, SELECTOR_MODEL_FILE
from ros_hrc.experiment.stack import EXPERIMENT_TRIALS
from ros_hrc.model_files import MODELS_DIR, user_path

NAME = "hrc_train_selector"
#: Tasks per (type, policy) pair: FABRIC's training set, ``exp4_7000t.mat`` (10 types x 14
#: policies x 50 tasks = 7000; issue #30).
DEFAULT_TASKS_PER_PAIR = 50
#: The trainer's seeds: not the study's (2), nor hrc_fit's (0), nor 1 and 3 (spent on tuning
#: the considerate model): a selector model is never evaluated on the streams it learnt from.
DEFAULT_SEEDS = "4"


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog=NAME, description=__doc__.split("\n\n")[0],
                      formatter_class=argparse.RawDescriptionHelpFormatter)
    settings.add_argument(p, "task")
    p.add_argument("--library", default="auto",
                   help="the policy library, a manifest or a folder holding library.toml "
                        "(auto: the task's)")
    p.add_argument("--human-models", type=names_argument, default=None,
                   help="the human types, comma-separated (the seed: the zoo's fit set, "
                        "never the study's held-out humans; fabric: its ten types)")
    p.add_argument("--tasks-per-pair", type=at_least(1, 100000),
                   default=DEFAULT_TASKS_PER_PAIR,
                   help=f"tasks per (type, policy) pair ({DEFAULT_TASKS_PER_PAIR}, FABRIC's)")
    p.add_argument("--seeds", type=seeds_argument, default=seeds_argument(DEFAULT_SEEDS),
                   help=f"the trainer's seeds, comma-separated ({DEFAULT_SEEDS}; the study's "
                        f"are {STUDY_SEEDS}): each pair plays one sequence per seed")
    p.add_argument("--leave-out", default=None, metavar="TYPE",
                   help="write a model without this type (the study's untrained types); "
                        "default --out then selector_model_without_TYPE.json")
    p.add_argument("--out", default=None,
                   help="the selector model file (the task's: selector_model.json beside the "
                        "library's manifest)")
    p.add_argument("--runs", default=None,
                   help="the training runs' results directory (results/train_selector_TASK)")
    p.add_argument("--step-limit", type=at_least(1, MAX_STEP_LIMIT), default=None,
                   help="steps before a task ends (the task's)")
    settings.add_argument(p, "max_trials", default=EXPERIMENT_TRIALS,
                          help=f"DESPOT's trials per decision, no time budget "
                               f"({EXPERIMENT_TRIALS}, the study's default): the study that "
                               "uses the model must plan with the same (the header says it)")
    p.add_argument("--jobs", type=at_least(0, MAX_JOBS), default=0,
                   help="stacks side by side (0: one per core)")
    add_cluster_argument(p)
    return p


def study_words(args: argparse.Namespace) -> List[str]:
    """The sequence study the training runs are: every pair a fixed:<policy> sequence."""
    words = ["--task", args.task, "--sequence", str(args.tasks_per_pair), "--selectors", FIXED,
             "--schedule", PER_TYPE, "--library", args.library,
             "--seeds", ",".join(map(str, args.seeds)), "--episodes", "1",
             "--out", args.runs, "--jobs", str(args.jobs), "--no-plots",
             "--max-trials", str(args.max_trials)]
    if args.human_models:
        words += ["--human-models", ",".join(args.human_models)]
    if args.step_limit is not None:
        words += ["--step-limit", str(args.step_limit)]
    if args.cluster is not None:
        words += ["--cluster", args.cluster]
    return words


def training_tasks(rows: Sequence[TaskRow], types: Sequence[str], policies: Sequence[str],
                   seeds: Sequence[int], tasks_per_pair: int) -> List[TrainingTask]:
    """The training tasks of the runs' rows: those of ``fixed:<policy>`` sequences of
    ``tasks_per_pair`` tasks on ``seeds``, of the wanted types and policies (the runs' folder
    may hold others: another --leave-out, other seeds)."""
    out = []
    for row in rows:
        if (row.selector == f"{FIXED}:{row.policy}" and row.true_type in types
                and row.policy in policies and row.seed in seeds and row.episode == 0
                and row.task_index <= tasks_per_pair):
            out.append(TrainingTask(human_type=row.true_type, policy=row.policy,
                                    utility=row.utility, signature=row.signature_codes))
    return out


def _say(text: object) -> int:
    return say_one_line(NAME, text)


def main(argv: Optional[list] = None) -> int:
    words = own_arguments(argv)
    try:
        args = build_parser().parse_args(words)
        task = tasks.get(args.task)
        types = list(args.human_models or training_humans(task))
        if args.leave_out is not None:
            if args.leave_out not in types:
                raise GridError(f"--leave-out: {args.leave_out!r} is not one of the types "
                                f"{', '.join(types)}")
            types.remove(args.leave_out)
        args.human_models = types
        args.runs = str(user_path(args.runs or f"results/train_selector_{task.name}"))
        study = study_parser().parse_args(study_words(args))
        check_mode(study, study_words(args))
        validate_sequences(study)
        manifest = Path(study.library_manifest)
        default_out = manifest.parent / (SELECTOR_MODEL_FILE if args.leave_out is None else
                                         f"selector_model_without_{args.leave_out}.json")
        out = user_path(args.out) if args.out else default_out
        if not out.parent.is_dir():
            raise GridError(f"--out {args.out}: no folder {out.parent}")
        if args.cluster is not None:
            check_cluster(args.cluster)
    except HrcError as exc:
        return _say(exc)
    shared = sorted(set(args.seeds) & set(seeds_argument(STUDY_SEEDS)))
    if shared:
        _say(f"warning: seeds {','.join(map(str, shared))} are the study's too; "
             "hrc_experiment will refuse this model's selectors on them")
    policies = [s[len(FIXED) + 1:] for s in study.selectors]
    print(f"{NAME}: {counted(len(types), 'type')} x {counted(len(policies), 'policy', 'policies')} x "
          f"{counted(len(args.seeds), 'seed')} x {counted(args.tasks_per_pair, 'task')} into "
          f"{args.runs}, then the model to {out}", flush=True)
    if study.cluster is None:        # on a cluster, 0 is the cluster's slots
        study.jobs = study.jobs or os.cpu_count() or 1
    try:
        with open_results(Path(args.runs), "--runs"):
            status = run_sequences(study, Path(args.runs), study_words(args), NAME,
                                   report=False)
            if status != 0:
                return status
            rows = SequenceStore(args.runs).tasks()
    except HrcError as exc:
        return _say(exc)
    except OSError as exc:
        _say(file_error_line(exc))
        return 1
    training = training_tasks(rows, types, policies, args.seeds, args.tasks_per_pair)
    header = {"how": f"hrc_train_selector: every (type, policy) pair played "
                     f"{args.tasks_per_pair} tasks per seed through the real stack as a "
                     "fixed:<policy> sequence; mean and sample std of the task utility, the "
                     "signature codes counted per pair with an additive prior",
              "from": f"{Path(args.runs) / 'tasks.csv'}: {len(training)} tasks",
              "seeds": list(args.seeds), "leave_out": args.leave_out or "",
              "max_trials": args.max_trials or EXPERIMENT_TRIALS,
              "command": shlex.join([NAME] + list(words)),
              "date": datetime.datetime.now(datetime.timezone.utc).isoformat(
                  timespec="seconds")}
    try:
        model = from_tasks(training, task=task.name, policies=policies, types=types,
                           header=header, manifest=_package_relative(manifest))
        write_selector_model(model, out)
        load_selector_model(out, task, policies)      # what the stacks will read, checked
    except (ValueError, HrcError) as exc:
        return _say(exc)
    except OSError as exc:
        _say(file_error_line(exc))
        return 1
    print(f"{NAME}: wrote {out}: {len(types)} types x {len(policies)} policies from "
          f"{len(training)} tasks on seeds {','.join(map(str, args.seeds))}", flush=True)
    return 0


def _package_relative(path: Path) -> str:
    """A file as the model names it: relative to the package's root when inside it."""
    try:
        return str(Path(path).resolve().relative_to(MODELS_DIR.parent))
    except ValueError:
        return str(path)


if __name__ == "__main__":
    sys.exit(main())
