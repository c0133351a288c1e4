"""hrc_perturb_humans: humans we did not build by hand, perturbed from a task's types.

A selector trained on the task's ten types is only worth its claim if it survives humans that
are not those types (issue #30's study, part (c)). This writes, for each type, a copy whose
transition rows are drawn around the type's own: in every row of every action, the live
entries (above 0) but the task's floors get a Dirichlet draw of the mass they share, centred
on the type's values with ``concentration`` c (larger c: closer to the type; c = 20 moves an
entry of 0.5 by about 0.11, one standard deviation). A floor is the task's
(:attr:`Task.model_floor <ros_hrc.tasks.definition.Task.model_floor>`: FABRIC's 0.01, which
its human's draw folds into the row's largest entry, ``FabricReaction.row``; the seed has
none), never "the row's smallest entry": a row of the seed's such as [0.3, 0.7] is drawn
whole. The floors stay exactly as they are and every drawn entry stays above them, so the
draw's folding rule still folds the floors and nothing else; a zero stays a zero (a
transition the type cannot make stays impossible). A row with fewer than two entries to
draw stays the type's; a type none of whose rows can move is refused (nothing written).
The rewards stay, so the human's own policy is the type's rewards solved on the new rows.

Each file keeps its type's name (``<out>/<type>.pomdpx``): a task's ``true_type`` is the file's
stem, so a study names the type a human was perturbed from, and ``oracle`` is told that type
(an approximate upper bound: the perturbed human is not the type it was trained on). For each
the tool prints how far it moved: the largest change of any T entry and the rows moved.

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

#: What keeps a drawn entry above the row's floor (or above 0), so it is never folded away
#: with the floors nor made impossible.
ABOVE_FLOOR = 1e-4


def drawn_entries(row: np.ndarray, floor: float = 0.0) -> Optional[np.ndarray]:
    """The mask of the row's entries a draw moves: the live ones (above 0) but the task's
    floors (entries equal to ``floor``; 0: none) and any within :data:`ABOVE_FLOOR` of the
    floor (kept as they are: a draw could fold them away); None when fewer than two."""
    drawn = row > floor + ABOVE_FLOOR
    if floor > 0:
        drawn &= row != floor
    return drawn if drawn.sum() >= 2 else None


def perturb_rows(table: np.ndarray, concentration: float, rng: np.random.Generator,
                 floor: float = 0.0) -> np.ndarray:
    """A transition table (S x S') with each row's :func:`drawn_entries` redrawn around
    their values (Dirichlet, ``concentration``), each kept above ``floor`` +
    :data:`ABOVE_FLOOR`; the row sums, the floors and the zeros are unchanged."""
    out = np.array(table, dtype=float)
    for i, row in enumerate(out):
        drawn = drawn_entries(row, floor)
        if drawn is None:
            continue
        excess = row[drawn] - floor - ABOVE_FLOOR
        share = rng.dirichlet(concentration * excess / excess.sum())
        out[i, drawn] = floor + ABOVE_FLOOR + excess.sum() * share
    return out


def perturb_model(model: Model, concentration: float, rng: np.random.Generator,
                  label: str, floor: float = 0.0) -> Model:
    """The human model with every action's rows perturbed (:func:`perturb_rows`)."""
    tables = [sp.csr_matrix(perturb_rows(t.toarray(), concentration, rng, floor))
              for t in model.T]
    return dataclasses.replace(model, T=tables, name=label)


@dataclasses.dataclass(frozen=True)
class Movement:
    """How far a perturbed human is from its type: the largest change of any T entry, the
    rows (of every action) that differ, those that could, and all of them."""

    largest_change: float
    rows_moved: int
    rows_movable: int
    rows: int

    @property
    def share_moved(self) -> float:
        """The share of the rows that can move which did (a draw moves each: 1)."""
        return self.rows_moved / self.rows_movable if self.rows_movable else 0.0

    def text(self) -> str:
        return (f"largest change of a T entry {self.largest_change:.3f}; rows moved "
                f"{self.rows_moved} of the {self.rows_movable} that can move "
                f"({self.share_moved:.0%}; {self.rows_moved / self.rows:.0%} of all {self.rows})")


def rows_movable(model: Model, floor: float = 0.0) -> int:
    """How many rows (of every action) have two or more entries to draw."""
    return sum(drawn_entries(row, floor) is not None for t in model.T for row in t.toarray())


def movement(original: Model, perturbed: Model, floor: float = 0.0) -> Movement:
    """How far ``perturbed`` moved from ``original`` (same states and actions)."""
    change = np.array([abs(p.toarray() - o.toarray()) for o, p in zip(original.T, perturbed.T)])
    moved = change.max(axis=2) > 0
    return Movement(float(change.max(initial=0.0)), int(moved.sum()),
                    rows_movable(original, floor), int(moved.size))


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
        for stem, model in loaded:
            if not rows_movable(model, task.model_floor):
                besides = (f" besides the task's floors ({task.model_floor:g})"
                           if task.model_floor else "")
                raise GridError(f"--human-models: {stem}: none of its rows can move (none has "
                                f"two or more live entries{besides}): perturbed, it would be "
                                f"the type itself")
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
        perturbed = perturb_model(model, args.concentration, rng, label, task.model_floor)
        try:
            save_pomdpx(perturbed, target)
        except OSError as exc:
            return say_one_line(NAME, f"{target}: {exc.strerror or exc}")
        print(f"{NAME}: wrote {target}: "
              f"{movement(model, perturbed, task.model_floor).text()}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
