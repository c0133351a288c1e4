"""The plots of an experiment, as PNG files.

:func:`plot_outcomes` (success rate and mean steps, grouped bars with 95 % CIs) and
:func:`plot_belief` (the robot's belief that the human needs help against the truth, one line
per robot policy on the same human). Both draw on a bare ``Figure`` rendered by Agg
(matplotlib, imported on first use), so they work headless and leave pyplot's global state
alone. No ROS.
"""
from __future__ import annotations

import math
import os
import warnings
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Union

from ros_hrc.experiment.store import EpisodeKey, ResultsWarning, StepRow, ensure_parent
from ros_hrc.pomdp.output import write_atomically

def _new_figure(width: float, height: float):
    """A Figure outside pyplot: rendered by Agg whatever backend the process chose."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), layout="constrained")


def _save(fig, png_path: Union[str, os.PathLike]) -> str:
    path = os.fspath(png_path)
    ensure_parent(path)
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)  # attach Agg explicitly: no display, no backend lookup
    # Rendered in memory, then written whole or not at all (a full disk keeps the old plot).
    write_atomically(path, lambda f: fig.savefig(f, format="png", dpi=150))
    return path


def _ordered(values: Iterable[Any]) -> List[Any]:
    return list(dict.fromkeys(values))


def _policy_colours(policies: Sequence[str]) -> Dict[str, Any]:
    from matplotlib import colormaps

    cmap = colormaps["tab10"]
    return {p: cmap(i % 10) for i, p in enumerate(policies)}


def plot_outcomes(summary: Sequence[Mapping[str, Any]], png_path: Union[str, os.PathLike]) -> str:
    """Success rate and mean steps, grouped by human model, one bar per robot policy, with
    the summary's confidence intervals as error bars. Returns the PNG's path."""
    if not summary:
        raise ValueError("plot_outcomes: the summary is empty, nothing to plot")
    humans = _ordered(e["human_model"] for e in summary)
    policies = _ordered(e["robot_policy"] for e in summary)
    colours = _policy_colours(policies)
    by_key = {(e["human_model"], e["robot_policy"]): e for e in summary}
    width = 0.8 / len(policies)

    fig = _new_figure(max(8.0, 1.6 * len(humans) * 2 + 2), 4.5)
    ax_rate, ax_steps = fig.subplots(1, 2)
    panels = ((ax_rate, "success_rate", "success_low", "success_high", "Success rate"),
              (ax_steps, "steps_mean", "steps_low", "steps_high", "Mean steps per episode"))
    for ax, mean_key, low_key, high_key, ylabel in panels:
        for j, policy in enumerate(policies):
            xs, heights, below, above = [], [], [], []
            for i, human in enumerate(humans):
                e = by_key.get((human, policy))
                if e is None:
                    continue  # this pair was not run: leave a gap, not a zero bar
                m, lo, hi = e[mean_key], e[low_key], e[high_key]
                xs.append(i - 0.4 + width * (j + 0.5))
                heights.append(m)
                # No interval (n = 1): no error bar rather than a zero-length one.
                below.append(m - lo if math.isfinite(lo) else math.nan)
                above.append(hi - m if math.isfinite(hi) else math.nan)
            ax.bar(xs, heights, width, yerr=[below, above], capsize=3,
                   color=colours[policy], label=policy, error_kw={"elinewidth": 1})
        ax.set_xticks(range(len(humans)), humans)
        ax.set_xlabel("Human model")
        ax.set_ylabel(ylabel)
        ax.grid(axis="y", alpha=0.3)
        ax.set_axisbelow(True)
    ax_rate.set_ylim(0, 1.05)
    ax_steps.set_ylim(bottom=0)
    ax_rate.legend(title="Robot policy", fontsize="small")
    levels = _ordered(e.get("confidence", 0.95) for e in summary)
    ns = [e["n"] for e in summary]
    n_text = f"n = {ns[0]}" if min(ns) == max(ns) else f"n = {min(ns)}–{max(ns)}"
    fig.suptitle("Outcomes by human model and robot policy (mean, "
                 + "/".join(f"{100 * c:g} %" for c in levels)
                 + f" CI; {n_text} episodes per bar)")
    return _save(fig, png_path)


def _select_episode(groups: Mapping[EpisodeKey, List[StepRow]],
                    episode: Optional[Sequence[Any]]) -> EpisodeKey:
    if episode is not None:
        key = tuple(episode)
        if len(key) != 4:
            raise ValueError(f"episode must be (human_model, robot_policy, seed, episode), "
                             f"got {episode!r}")
        if key not in groups:
            raise ValueError(f"no step rows for episode {key}")
        return key  # type: ignore[return-value]
    policies = _ordered(k[1] for k in groups)
    for policy in policies:  # policy by policy, each in order of first appearance
        for key, rows in groups.items():
            if key[1] == policy and any(r.needs_help for r in rows):
                return key
    return next(iter(groups))


def plot_belief(step_rows: Iterable[StepRow], png_path: Union[str, os.PathLike],
                episode: Optional[Sequence[Any]] = None) -> str:
    """The robot's belief that the human needs help (S2..S5), step by step, against the
    human's true need (shaded), for one episode. Returns the PNG's path.

    ``episode`` is a key (human_model, robot_policy, seed, episode); by default the first
    episode of the first policy that has a needs-help step, else the first episode. Every
    robot policy with the same (human_model, seed, episode) gets its own line, so policies
    are compared on the same simulated human. The shaded truth is the union over those runs
    where they agree; where they do not (the robot changed what the human did), the chosen
    run's truth is shown and a ResultsWarning says so.
    """
    groups: Dict[EpisodeKey, List[StepRow]] = {}
    for row in step_rows:
        groups.setdefault(row.key, []).append(row)
    if not groups:
        raise ValueError("plot_belief: no step rows, nothing to plot")
    chosen = _select_episode(groups, episode)
    human_model, _, seed, number = chosen
    same_human = [k for k in groups if (k[0], k[2], k[3]) == (human_model, seed, number)]
    same_human.sort(key=lambda k: k != chosen)  # the chosen run first, the rest in order
    runs = {k[1]: sorted(groups[k], key=lambda r: r.step) for k in same_human}

    # The true need per step: from the chosen run, completed by the others where it ends.
    truth: Dict[int, int] = {}
    conflicts = False
    for rows in runs.values():
        for r in rows:
            if truth.setdefault(r.step, r.needs_help) != r.needs_help:
                conflicts = True
    if conflicts:
        warnings.warn(f"plot_belief: the runs of {human_model}, seed {seed}, episode {number} "
                      f"disagree on when the human needed help; shading the {chosen[1]} run's",
                      ResultsWarning, stacklevel=2)
        truth = {r.step: r.needs_help for r in runs[chosen[1]]}

    from matplotlib.ticker import MaxNLocator

    fig = _new_figure(9.0, 4.0)
    ax = fig.subplots()
    t_steps = sorted(truth)
    # Each step's truth fills [step - 0.5, step + 0.5], so a single needs-help step shows too.
    edges = (t_steps[0] - 0.5, t_steps[-1] + 0.5)
    truth_label = "human needs help (true state S2..S5)"
    if conflicts:
        truth_label += f", {chosen[1]} run"
    # One span per run of needs-help steps (fill_between's where= drops a run's last step).
    start = None
    for s, v in zip(t_steps + [None], [truth[s] for s in t_steps] + [0]):
        if v and start is None:
            start = s
        elif not v and start is not None:
            ax.axvspan(start - 0.5, prev + 0.5, color="0.6", alpha=0.3, linewidth=0,
                       label=truth_label)
            truth_label = "_nolegend_"  # one legend entry for all spans
            start = None
        prev = s
    if truth_label != "_nolegend_":  # no span drawn: still say what shading would mean
        ax.fill_between([], [], color="0.6", alpha=0.3, linewidth=0,
                        label=truth_label + ": never in this episode")

    colours = _policy_colours(list(runs))
    for policy, rows in runs.items():
        beliefs = [r.belief_needs_help for r in rows]
        if all(math.isnan(b) for b in beliefs):
            ax.plot([], [], color=colours[policy], label=f"{policy} (no belief reported)")
            continue
        ax.plot([r.step for r in rows], beliefs, color=colours[policy], marker="o",
                markersize=3, linewidth=1.5, label=policy, clip_on=False)
    ax.set_ylim(0, 1)
    ax.set_xlim(edges[0], edges[-1])
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # steps are whole numbers
    ax.set_xlabel("Step")
    ax.set_ylabel("Robot's belief P(needs help)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1), borderaxespad=0)
    ax.set_title(f"Belief that the human needs help: {human_model}, seed {seed}, "
                 f"episode {number}")
    return _save(fig, png_path)
