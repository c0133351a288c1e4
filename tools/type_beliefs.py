#!/usr/bin/env python3
"""Where a robot model of human types puts its belief on each human of an episode study.

Reads an ``hrc_experiment`` run's ``steps.csv`` (the ``pomdp_types`` rows: the robot's action
and observation of every step) and replays each episode's belief exactly on the robot model of
types, as the robot process does (an update with the previous action and the step's
observation; a zero-probability observation keeps the prediction). The belief is a function of
the actions and observations alone (the model's 56 states are below DESPOT's exact-belief
size), so the replay gives the robot's own type belief, step by step.

Prints, per human model, the mean type belief after the first step and at the episode's end,
its entropy in bits (log2 of the number of types when uniform), and how often each type is the
belief's top at the end; ``--plot FILE`` draws the end belief per human (a heat map).

    python tools/type_beliefs.py results/types_episodes [--model robot_types] [--task seed]
        [--plot docs/img/type_beliefs.png]
"""
from __future__ import annotations

import argparse
import csv
import sys
from collections import defaultdict
from pathlib import Path
from typing import Dict, List, Sequence

import numpy as np

from ros_hrc.experiment.episode import TYPES_POLICY
from ros_hrc.models import load_robot_model
from ros_hrc.pomdp.belief import ExactBelief, ZeroProbabilityObservation
from ros_hrc.pomdp.typed import TypeLayout


def episode_type_beliefs(model, layout: TypeLayout, steps: Sequence[dict],
                         first_action: str = "rIdle") -> List[np.ndarray]:
    """The type belief after each of an episode's steps (rows in step order)."""
    belief = ExactBelief(model)
    previous = model.index("action", first_action)
    out = []
    for row in steps:
        observation = model.index("observation", row["observation"])
        try:
            belief.update(previous, observation)
        except ZeroProbabilityObservation:
            belief.predict(previous)
        out.append(layout.type_marginal(belief.probabilities()))
        previous = model.index("action", row["robot_action"])
    return out


def entropy_bits(p: np.ndarray) -> float:
    q = p[p > 0]
    return float(-(q * np.log2(q)).sum())


def read_episodes(run: Path, policy: str) -> Dict[str, Dict[tuple, List[dict]]]:
    """human model -> (seed, episode) -> its step rows in order, for ``policy``."""
    episodes: Dict[str, Dict[tuple, List[dict]]] = defaultdict(lambda: defaultdict(list))
    with open(run / "steps.csv", newline="") as handle:
        for row in csv.DictReader(handle):
            if row["robot_policy"] == policy:
                episodes[row["human_model"]][(row["seed"], int(row["episode"]))].append(row)
    for by_episode in episodes.values():
        for rows in by_episode.values():
            rows.sort(key=lambda r: int(r["step"]))
    return episodes


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path, help="an hrc_experiment --out folder with steps.csv")
    parser.add_argument("--model", default="robot_types", help="the robot model of types")
    parser.add_argument("--task", default="seed")
    parser.add_argument("--policy", default=TYPES_POLICY)
    parser.add_argument("--plot", type=Path, help="write the end beliefs' heat map here")
    args = parser.parse_args(argv)
    if not (args.run / "steps.csv").is_file():
        print(f"type_beliefs: no steps.csv in {args.run}", file=sys.stderr)
        return 2
    model = load_robot_model(args.model, args.task)
    layout = TypeLayout.of(model)
    if layout is None:
        print(f"type_beliefs: {args.model} is not a robot model of types", file=sys.stderr)
        return 2
    episodes = read_episodes(args.run, args.policy)
    if not episodes:
        print(f"type_beliefs: no {args.policy} steps in {args.run / 'steps.csv'}",
              file=sys.stderr)
        return 2
    types = list(layout.types)
    print(f"| human | episodes | entropy after step 1 / at the end (bits; uniform "
          f"{np.log2(len(types)):.2f}) | mean end belief (top 3) | top type at the end |")
    print("|---|--:|--:|---|---|")
    ends = {}
    for human, by_episode in episodes.items():
        first, last, tops = [], [], defaultdict(int)
        for rows in by_episode.values():
            trajectory = episode_type_beliefs(model, layout, rows)
            first.append(trajectory[0])
            last.append(trajectory[-1])
            tops[types[int(np.argmax(trajectory[-1]))]] += 1
        mean_end = np.mean(last, axis=0)
        ends[human] = mean_end
        top3 = ", ".join(f"{types[i]} {mean_end[i]:.2f}" for i in np.argsort(-mean_end)[:3])
        top_counts = ", ".join(f"{t} {n}" for t, n in sorted(tops.items(), key=lambda x: -x[1]))
        print(f"| {human} | {len(last)} | {np.mean([entropy_bits(p) for p in first]):.2f} / "
              f"{np.mean([entropy_bits(p) for p in last]):.2f} | {top3} | {top_counts} |")
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        humans = list(ends)
        grid = np.array([ends[h] for h in humans])
        fig, ax = plt.subplots(figsize=(1.0 + 0.9 * len(types), 1.2 + 0.5 * len(humans)))
        image = ax.imshow(grid, cmap="viridis", vmin=0, vmax=1, aspect="auto")
        ax.set_xticks(range(len(types)), types, rotation=35, ha="right")
        ax.set_yticks(range(len(humans)), humans)
        for i in range(len(humans)):
            for j in range(len(types)):
                ax.text(j, i, f"{grid[i, j]:.2f}", ha="center", va="center", fontsize=8,
                        color="white" if grid[i, j] < 0.5 else "black")
        ax.set_xlabel("type of the robot's model (the fit set)")
        ax.set_title("The robot's belief over types at the episode's end\n"
                     "(mean over episodes; rows: held-out humans, of no type in the model)")
        fig.colorbar(image, ax=ax, fraction=0.03)
        fig.tight_layout()
        fig.savefig(args.plot, dpi=110)
        print(f"type_beliefs: wrote {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
