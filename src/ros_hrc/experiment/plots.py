"""The plots of an experiment, as PNG files.

:func:`plot_outcomes` (the counterfactual outcomes per human model and robot policy, stacked,
with the success rate's interval and the human-alone rate), :func:`plot_time_gain` (the time
gained against the human alone, per episode pair) and :func:`plot_belief` (the robot's belief
that the human needs help against the truth, one line per robot policy on the same human). Both draw on a bare ``Figure`` rendered by Agg
(matplotlib, imported on first use), so they work headless and leave pyplot's global state
alone. No ROS.
"""
from __future__ import annotations

import math
import os
import warnings
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Union

from ros_hrc.experiment.rows import EpisodeKey, StepRow
from ros_hrc.experiment.store import ResultsWarning, ensure_parent
from ros_hrc.pomdp.output import write_atomically

class NothingToPlot(ValueError):
    """A plot has no data to show (e.g. a grid of the human alone has no robot to compare):
    the report leaves it out with one line, it is no failure of the run."""


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


def _suptitle(fig, text: str) -> None:
    """The figure's title, wrapped to the figure's width: one line of it ran past both edges
    of a figure of one or two panels (``outcomes.png``, ``time_gain.png``). About ten
    characters of the title's font (large, 12 pt) fit an inch."""
    import textwrap

    fig.suptitle(textwrap.fill(text, max(20, int(fig.get_figwidth() * 10))))


def _wrapped(name: str, width: int = 22) -> str:
    """A long model name over lines of at most ``width`` characters, broken after its
    underscores (fabric's ``expert_nontired_noncollaborative``), so panel titles do not run
    into each other."""
    lines = [""]
    for part in name.split("_"):
        piece = part if not lines[-1] else "_" + part
        if lines[-1] and len(lines[-1]) + len(piece) > width:
            lines[-1] += "_"
            lines.append(part)
        else:
            lines[-1] += piece
    return "\n".join(lines)


def _ordered(values: Iterable[Any]) -> List[Any]:
    return list(dict.fromkeys(values))


def _policy_colours(policies: Sequence[str]) -> Dict[str, Any]:
    """A colour of its own for each policy: tab10 up to ten, tab20 up to twenty (the study
    has fourteen: ten reactive budgets, three POMDP robots and the human alone), then evenly
    spaced along a continuous map; never one colour for two policies."""
    from matplotlib import colormaps

    n = len(policies)
    if n <= 10:
        return {p: colormaps["tab10"](i) for i, p in enumerate(policies)}
    if n <= 20:
        return {p: colormaps["tab20"](i) for i, p in enumerate(policies)}
    cmap = colormaps["turbo"]
    return {p: cmap(i / (n - 1)) for i, p in enumerate(policies)}


#: The belief plot's line dashes and markers, one of each per policy in turn.
LINE_STYLES = ("-", (0, (5, 2)), (0, (1, 1.5)), (0, (6, 2, 1, 2)))
MARKERS = ("o", "s", "^", "D", "v", "P", "X")
#: Colours of the counterfactual outcomes: good for the human in greens, bad in reds.
OUTCOME_COLOURS = {"both_succeed": "#9bd49b", "rescued": "#2e8b57", "pre_empted": "#e8a33d",
                   "hindered": "#c0392b", "both_fail": "#7f7f7f"}
OUTCOME_LABELS = {"both_succeed": "both succeed", "rescued": "rescued",
                  "pre_empted": "pre-empted", "hindered": "hindered", "both_fail": "both fail"}


def plot_outcomes(summary: Sequence[Mapping[str, Any]], png_path: Union[str, os.PathLike]) -> str:
    """Success against the counterfactual: per human model (pooled entries included), one
    stacked bar per robot policy with the share of its episodes in each counterfactual
    outcome (both succeed, rescued, pre-empted, hindered, both fail), the success rate's
    interval as a whisker and the human-alone success rate as a dashed line. Returns the
    PNG's path."""
    if not summary:
        raise NothingToPlot("plot_outcomes: the summary is empty, nothing to plot")
    from ros_hrc.experiment.paired import OUTCOMES

    humans = _ordered(e["human_model"] for e in summary)
    policies = _ordered(e["robot_policy"] for e in summary)
    by_key = {(e["human_model"], e["robot_policy"]): e for e in summary}
    columns = min(len(humans), 3)
    rows = (len(humans) + columns - 1) // columns
    fig = _new_figure(max(6.0, 0.55 * len(policies) * columns + 2.5), 3.2 * rows + 0.8)
    axes = fig.subplots(rows, columns, squeeze=False, sharey=True)
    for index, human in enumerate(humans):
        ax = axes[index // columns][index % columns]
        present = [p for p in policies if (human, p) in by_key]
        xs = range(len(present))
        bottoms = [0.0] * len(present)
        for outcome in OUTCOMES:
            shares = [by_key[(human, p)][outcome] / by_key[(human, p)]["n"] for p in present]
            ax.bar(xs, shares, 0.7, bottom=bottoms, color=OUTCOME_COLOURS[outcome],
                   label=OUTCOME_LABELS[outcome] if index == 0 else "_nolegend_")
            bottoms = [b + v for b, v in zip(bottoms, shares)]
        for x, p in zip(xs, present):
            e = by_key[(human, p)]
            # Success = both succeed + rescued + pre-empted: the top of those three segments.
            rate, low, high = e["success_rate"], e["success_low"], e["success_high"]
            if math.isfinite(low) and math.isfinite(high):
                ax.errorbar([x], [rate], yerr=[[rate - low], [high - rate]], color="black",
                            capsize=3, linewidth=1,
                            label="success, 95 % CI" if index == 0 and x == 0 else "_nolegend_")
            alone = e["alone_successes"] / e["n"] if e["n"] else math.nan
            ax.hlines(alone, x - 0.35, x + 0.35, colors="black", linestyles="dashed",
                      linewidth=1,
                      label="success alone" if index == 0 and x == 0 else "_nolegend_")
        ax.set_xticks(list(xs), present, rotation=45, ha="right", fontsize="small")
        ns = sorted({by_key[(human, p)]["n"] for p in present})
        n_text = f"n = {ns[0]}" if len(ns) == 1 else f"n = {ns[0]}–{ns[-1]}"
        ax.set_title(f"{_wrapped(human)}\n({n_text})", fontsize="small")
        ax.set_ylim(0, 1.02)
        ax.grid(axis="y", alpha=0.3)
        ax.set_axisbelow(True)
    for index in range(len(humans), rows * columns):
        axes[index // columns][index % columns].set_visible(False)
    for r in range(rows):
        axes[r][0].set_ylabel("share of episodes")
    fig.legend(loc="outside lower center", ncol=4, fontsize="small")
    _suptitle(fig, "Each robot against the same human alone: counterfactual outcomes per episode")
    return _save(fig, png_path)


def plot_success(summary: Sequence[Mapping[str, Any]], png_path: Union[str, os.PathLike]) -> str:
    """Success per human model at a glance: one row per human model (the pooled entries
    last), one marker per robot policy at its success rate with its Wilson interval, the
    policies spread a little within the row, so that many humans and policies (fabric's ten
    types, a swept baseline) fit one figure. Returns the PNG's path."""
    if not summary:
        raise NothingToPlot("plot_success: the summary is empty, nothing to plot")
    humans = _ordered(e["human_model"] for e in summary)
    policies = _ordered(e["robot_policy"] for e in summary)
    colours = _policy_colours(policies)
    by_key = {(e["human_model"], e["robot_policy"]): e for e in summary}
    spread = 0.6 / max(1, len(policies) - 1) if len(policies) > 1 else 0.0
    fig = _new_figure(7.5, 0.42 * len(humans) + 1.8)
    ax = fig.subplots()
    for j, policy in enumerate(policies):
        ys, rates, lows, highs = [], [], [], []
        for i, human in enumerate(humans):
            e = by_key.get((human, policy))
            if e is None:
                continue
            # The first human on top; within a row the policies from top to bottom.
            ys.append(len(humans) - 1 - i + 0.3 - j * spread)
            rates.append(e["success_rate"])
            lows.append(e["success_rate"] - e["success_low"]
                        if math.isfinite(e["success_low"]) else 0.0)
            highs.append(e["success_high"] - e["success_rate"]
                         if math.isfinite(e["success_high"]) else 0.0)
        ax.errorbar(rates, ys, xerr=[lows, highs], fmt="o", markersize=4, capsize=2,
                    elinewidth=0.8, color=colours[policy], label=policy)
    ax.set_yticks(range(len(humans)), list(reversed(humans)), fontsize="small")
    ax.set_ylim(-0.6, len(humans) - 0.4)
    ax.set_xlim(0, 1.02)
    ax.set_xlabel("success rate (95 % Wilson interval)")
    ax.grid(axis="x", alpha=0.3)
    for y in range(len(humans) - 1):
        ax.axhline(y + 0.5, color="0.85", linewidth=0.6)
    ax.set_axisbelow(True)
    fig.legend(loc="outside lower center", ncol=min(len(policies), 6), fontsize="small")
    _suptitle(fig, "Success per human model and robot policy")
    return _save(fig, png_path)


def plot_time_gain(rows: Iterable[Any], png_path: Union[str, os.PathLike]) -> str:
    """Time against the counterfactual: per human model, the distribution of the time gain
    (simulated seconds the human alone took minus those with the robot, on the episodes where
    both succeeded) of each robot policy, as a box with every episode as a dot, and how many
    pairs each has. Returns the PNG's path."""
    rows = [r for r in rows if r.robot_policy != "no_robot"]
    if not rows:
        raise NothingToPlot("plot_time_gain: no robot episodes, nothing to plot")
    humans = _ordered(r.human_model for r in rows)
    policies = _ordered(r.robot_policy for r in rows)
    colours = _policy_colours(policies)
    columns = min(len(humans), 3)
    n_rows = (len(humans) + columns - 1) // columns
    fig = _new_figure(max(6.0, 0.55 * len(policies) * columns + 2.5), 3.2 * n_rows + 0.6)
    axes = fig.subplots(n_rows, columns, squeeze=False)
    for index, human in enumerate(humans):
        ax = axes[index // columns][index % columns]
        for x, policy in enumerate(policies):
            gains = [r.time_gain for r in rows if (r.human_model, r.robot_policy) ==
                     (human, policy) and math.isfinite(r.time_gain)]
            if gains:
                ax.boxplot([gains], positions=[x], widths=0.6, showfliers=False,
                           medianprops={"color": "black"})
                jitter = [x + 0.25 * (((i * 7919) % 101) / 100 - 0.5) for i in range(len(gains))]
                ax.scatter(jitter, gains, s=6, color=colours[policy], alpha=0.6, zorder=3)
            ax.annotate(f"{len(gains)}", (x, 0), xycoords=("data", "axes fraction"),
                        xytext=(0, 2), textcoords="offset points", ha="center",
                        fontsize="x-small")
        ax.axhline(0.0, color="0.4", linewidth=0.8)
        ax.set_xticks(range(len(policies)), policies, rotation=45, ha="right",
                      fontsize="small")
        ax.set_xlim(-0.6, len(policies) - 0.4)
        ax.set_title(human, fontsize="medium")
        ax.grid(axis="y", alpha=0.3)
    for index in range(len(humans), n_rows * columns):
        axes[index // columns][index % columns].set_visible(False)
    for r in range(n_rows):
        axes[r][0].set_ylabel("time gain (s): alone − with robot")
    _suptitle(fig, "Time to success against the same human alone (pairs where both succeed; "
                   "the number of pairs under each box)")
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
        raise NothingToPlot("plot_belief: no step rows, nothing to plot")
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
    # Policies often agree step by step (the same observations, the same belief): each line
    # has a dash and a hollow marker of its own, the first drawn widest and largest, so a line
    # drawn over another leaves the other's edges showing.
    widest = max(len(runs) - 1, 1)
    for index, (policy, rows) in enumerate(runs.items()):
        beliefs = [r.belief_needs_help for r in rows]
        if all(math.isnan(b) for b in beliefs):
            ax.plot([], [], color=colours[policy], label=f"{policy} (no belief reported)")
            continue
        size = (len(runs) - 1 - index) / widest        # 1 for the first line, 0 for the last
        ax.plot([r.step for r in rows], beliefs, color=colours[policy],
                linestyle=LINE_STYLES[index % len(LINE_STYLES)],
                marker=MARKERS[index % len(MARKERS)], markerfacecolor="none",
                markersize=4 + 5 * size, markeredgewidth=1.2, linewidth=1.2 + 2.8 * size,
                label=policy, clip_on=False, zorder=2 + index)
    ax.set_ylim(0, 1)
    ax.set_xlim(edges[0], edges[-1])
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # steps are whole numbers
    ax.set_xlabel("Step")
    ax.set_ylabel("Robot's belief P(needs help)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1), borderaxespad=0)
    # Two lines: one would run past the figure's left edge for fabric's long type names.
    ax.set_title(f"Belief that the human needs help\n{human_model}, seed {seed}, "
                 f"episode {number}")
    return _save(fig, png_path)


def plot_learning_curves(curve: Sequence[Mapping[str, Any]], png_path: Union[str, os.PathLike],
                         best_fixed: Optional[Mapping[str, str]] = None) -> str:
    """A sequence study's learning curves: per schedule (a row of panels), the success rate
    and the mean utility per task index of each selector (a line, its 95 % interval a band:
    Wilson for success, bootstrap percentile for utility), over the sequences
    (:func:`ros_hrc.experiment.sequence_statistics.learning_curve`). Of the ``fixed:<policy>``
    selectors only the schedule's best in hindsight (``best_fixed``) is drawn, dashed, so
    the adaptive ones stand out against it. Returns the PNG's path."""
    best_fixed = best_fixed or {}
    shown = [e for e in curve if not e["selector"].startswith("fixed:")
             or best_fixed.get(e["schedule"]) == e["selector"]]
    if not shown:
        raise NothingToPlot("plot_learning_curves: no task recorded, nothing to plot")
    schedules = _ordered(e["schedule"] for e in shown)
    selectors = _ordered(e["selector"] for e in shown)
    colours = _policy_colours(selectors)
    fig = _new_figure(10.0, 2.6 * len(schedules) + 0.9)
    axes = fig.subplots(len(schedules), 2, squeeze=False, sharex=True)
    for row, schedule in enumerate(schedules):
        for selector in selectors:
            points = sorted((e for e in shown if (e["schedule"], e["selector"])
                             == (schedule, selector)), key=lambda e: e["task_index"])
            if not points:
                continue
            xs = [e["task_index"] for e in points]
            fixed = selector.startswith("fixed:")
            for col, name in enumerate(("success", "utility")):
                ax = axes[row][col]
                ax.plot(xs, [e[name] for e in points], color=colours[selector],
                        linestyle="--" if fixed else "-", linewidth=1.2,
                        label=f"{selector} (best fixed)" if fixed else selector)
                ax.fill_between(xs, [e[f"{name}_low"] for e in points],
                                [e[f"{name}_high"] for e in points], color=colours[selector],
                                alpha=0.15, linewidth=0)
        axes[row][0].set_ylabel(_wrapped(schedule), fontsize="small")
        axes[row][0].set_ylim(-0.02, 1.02)
        for ax in axes[row]:
            ax.grid(alpha=0.3)
    axes[0][0].set_title("success rate (95 % Wilson interval)", fontsize="medium")
    axes[0][1].set_title("utility per task (95 % bootstrap interval)", fontsize="medium")
    from matplotlib.ticker import MaxNLocator
    for ax in axes[-1]:
        ax.set_xlabel("task in the sequence")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    handles, labels = axes[0][1].get_legend_handles_labels()
    seen = dict(zip(labels, handles))
    for r in range(1, len(schedules)):
        h, l = axes[r][1].get_legend_handles_labels()
        seen.update((label, handle) for label, handle in zip(l, h) if label not in seen)
    fig.legend(list(seen.values()), list(seen.keys()), loc="outside lower center",
               ncol=min(len(seen), 5), fontsize="small")
    _suptitle(fig, "Learning curves: each selector over the tasks of a sequence")
    return _save(fig, png_path)
