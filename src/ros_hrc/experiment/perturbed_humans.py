"""hrc_perturb_humans: humans we did not build by hand, perturbed from a task's types.

A selector trained on the task's ten types is only worth its claim if it survives humans that
are not those types (issue #30's study, part (c)). This writes, for each type, a copy whose
transition rows are drawn around the type's own: in every row of every action, the entries
above the row's floor (the authors' 0.01, which the fabric human's draw folds into the row's
largest entry, ``FabricReaction.row``) get a Dirichlet draw of the mass they share, centred
on the type's values with ``concentration`` c (larger c: closer to the type; c = 20 moves an
entry of 0.5 by about 0.11, one standard deviation). The floors stay exactly as they are, so
the draw's folding rule still applies; a row with one entry above its floor is left alone.
The rewards stay, so the human's own policy is the type's rewards solved on the new rows.

Each file keeps its type's name (``<out>/<type>.pomdpx``): a task's ``true_type`` is the file's
stem, so a study names the type a human was perturbed from, and ``oracle`` is told that type
(an approximate upper bound: the perturbed human is not the type it was trained on).

No ROS: models in, models out.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import List, Optional

import numpy as np
import scipy.sparse as sp

from ros_hrc import settings, tasks
from ros_hrc.command_line import own_arguments, seed_argument
from ros_hrc.errors import HrcError
from ros_hrc.experiment.arguments import OneLineParser, names_argument, say_one_line
from ros_hrc.experiment.grid import GridError, task_humans
from ros_hrc.model_files import user_path
from ros_hrc.models import ModelNotFound, load_human_model, model_path
from ros_hrc.pomdp.model import Model
from ros_hrc.pomdp.pomdpx_writer import save as save_pomdpx

NAME = "hrc_perturb_humans"

#: What keeps a drawn entry above the row's floor, so it is never folded away with them.
ABOVE_FLOOR = 1e-4


def perturb_rows(table: np.ndarray, concentration: float, rng: np.random.Generator) -> np.ndarray:
    """A transition table (S x S') with each row's entries above its floor redrawn around
    their values (Dirichlet, ``concentration``); the row sums and the floors are unchanged."""
    out = np.array(table, dtype=float)
    for i, row in enumerate(out):
        live = row > 0
        if not live.any():
            continue
        floor = row[live].min()
        free = live & (row > floor)
        if free.sum() < 2:
            continue
        excess = row[free] - floor - ABOVE_FLOOR
        if (excess <= 0).any():
            continue          # an entry a hair above the floor: drawing could fold it away
        share = rng.dirichlet(concentration * excess / excess.sum())
        out[i, free] = floor + ABOVE_FLOOR + excess.sum() * share
    return out


def perturb_model(model: Model, concentration: float, rng: np.random.Generator,
                  label: str) -> Model:
    """The human model with every action's rows perturbed (:func:`perturb_rows`)."""
    tables = [sp.csr_matrix(perturb_rows(t.toarray(), concentration, rng)) for t in model.T]
    return dataclasses.replace(model, T=tables, name=label)


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog=NAME, description=__doc__.splitlines()[0])
    settings.add_argument(p, "task")
    p.add_argument("--human-models", type=names_argument, default=None,
                   help="the types to perturb, comma-separated (the task's shipped types)")
    p.add_argument("--concentration", type=float, default=20.0,
                   help="the Dirichlet concentration c: larger is closer to the type (20)")
    p.add_argument("--seed", type=seed_argument, default=0,
                   help="the draw's seed; one seed, one set of humans (0)")
    p.add_argument("--out", required=True,
                   help="the folder to write <type>.pomdpx into (made if missing)")
    return p


def main(argv: Optional[list] = None) -> int:
    try:
        args = build_parser().parse_args(own_arguments(argv))
        if not args.concentration > 0:
            raise GridError(f"--concentration: must be > 0, got {args.concentration}")
        task = tasks.get(args.task)
        types: List[str] = list(args.human_models or task_humans(task))
        loaded = []
        for human in types:
            try:
                path = model_path(human, "human", task)
                loaded.append((Path(path).stem, load_human_model(path, task)))
            except ModelNotFound as exc:
                raise GridError(f"--human-models: {exc}") from None
        out = user_path(args.out)
        out.mkdir(parents=True, exist_ok=True)
    except HrcError as exc:
        return say_one_line(NAME, exc)
    except OSError as exc:
        return say_one_line(NAME, f"--out {args.out}: {exc.strerror or exc}")
    rng = np.random.default_rng([args.seed, int(args.concentration * 1000)])
    for stem, model in loaded:
        label = (f"{stem} perturbed: transition rows drawn Dirichlet(c={args.concentration:g}) "
                 f"around the type's, seed {args.seed}, by {NAME}")
        target = out / f"{stem}.pomdpx"
        try:
            save_pomdpx(perturb_model(model, args.concentration, rng, label), target)
        except OSError as exc:
            return say_one_line(NAME, f"{target}: {exc.strerror or exc}")
        print(f"{NAME}: wrote {target}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
