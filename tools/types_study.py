#!/usr/bin/env python3
"""The robot model of human types against the considerate robot and the best reactive budget,
per human, on the same human streams (issue #31's README table).

Reads a finished ``hrc_experiment`` run with the policies ``pomdp_types``,
``pomdp_considerate``, reactive budgets and ``no_robot``. The best reactive budget of a row is
chosen on the row's own episodes by the study's rule (``statistics.best_reactive``: success,
then fewer pre-emptions, then time), which favours the baseline. Success and pre-emption are
compared pair by pair (the same seed and episode: the same human stream) with McNemar's exact
test (``paired.mcnemar_exact``); q is Benjamini-Hochberg over the table's rows, one family per
test and baseline (``scipy.stats.false_discovery_control``), as the study's summary does.

    python tools/types_study.py results/types_episodes [--humans a,b,...] [--label held-out]

``--humans``: the rows, in this order (default: the zoo's held-out humans of the run, then any
other human with ``pomdp_types`` episodes); the last row pools them.
"""
from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path
from typing import Dict, List, Sequence

from scipy import stats

from ros_hrc.experiment.episode import TYPES_POLICY
from ros_hrc.experiment.paired import mcnemar_exact
from ros_hrc.experiment.statistics import best_reactive
from ros_hrc.experiment.store import ResultsStore
from ros_hrc.experiment.zoo import ZOO_HELD_OUT

CONSIDERATE = "pomdp_considerate"


def fmt(p: float) -> str:
    return "< 0.001" if p < 0.001 else f"{p:.3f}"


def shown(human: str) -> str:
    """A human model as the table names it: a file by its stem."""
    return Path(human).stem if human.endswith((".pomdpx", ".pomdp")) else human


def main(argv: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--humans", help="the rows, comma-separated (a human model as the run "
                                         "names it, or its file's stem)")
    parser.add_argument("--label", default="pooled", help="the pooled row's name")
    args = parser.parse_args(argv)
    if not (args.run / "episodes.csv").is_file():
        print(f"types_study: no episodes.csv in {args.run}", file=sys.stderr)
        return 2
    by: Dict[tuple, Dict[tuple, object]] = defaultdict(dict)
    for row in ResultsStore(args.run).episodes():
        by[(row.human_model, row.robot_policy)][(row.seed, row.episode)] = row
    typed = list(dict.fromkeys(h for h, policy in by if policy == TYPES_POLICY))
    if args.humans:
        wanted = args.humans.split(",")
        humans = [h for w in wanted for h in typed if w in (h, shown(h))]
        if len(humans) != len(wanted):
            print(f"types_study: --humans: not every one has {TYPES_POLICY} episodes in "
                  f"{args.run} (it has: {', '.join(map(shown, typed))})", file=sys.stderr)
            return 2
    else:
        humans = [h for h in ZOO_HELD_OUT if h in typed] + [h for h in typed
                                                            if h not in ZOO_HELD_OUT]
    if not humans:
        print(f"types_study: no {TYPES_POLICY} episodes in {args.run}", file=sys.stderr)
        return 2

    def paired(group, policy, other, measure):
        first, second = [], []
        for human in group:
            for key, row in by[(human, policy)].items():
                if key in by[(human, other)]:
                    first.append(measure(row))
                    second.append(measure(by[(human, other)][key]))
        return first, second

    def success(row):
        return bool(row.success)

    def pre_empted(row):
        return row.outcome == "pre_empted"

    table: List[dict] = []
    for label, group in [(shown(h), [h]) for h in humans] + [(args.label, humans)]:
        episodes = [r for (human, _), rows in by.items() if human in group for r in rows.values()]
        reference = best_reactive(episodes)
        entry = {"label": label, "reference": reference,
                 "alone": sum(bool(r.success) for h in group for r in by[(h, "no_robot")].values()),
                 "against": sum(r.against_warning > 0
                                for h in group for r in by[(h, TYPES_POLICY)].values())}
        for name, other in (("considerate", CONSIDERATE), ("best", reference)):
            for measure in (success, pre_empted):
                first, second = paired(group, TYPES_POLICY, other, measure)
                entry[(name, measure.__name__)] = [sum(first), sum(second), len(first),
                                                   mcnemar_exact(first, second).p_value]
        table.append(entry)
    for key in [k for k in table[0] if isinstance(k, tuple)]:
        q = stats.false_discovery_control([e[key][3] for e in table], method="bh")
        for entry, value in zip(table, q):
            entry[key].append(float(value))

    print("| Human (alone) | Success: types / considerate / best reactive | p (q) vs considerate "
          "| p (q) vs best reactive | Pre-empted: types / considerate / best reactive "
          "| p (q) vs considerate | p (q) vs best reactive | Types acts against a warning |")
    print("|---|--:|--:|--:|--:|--:|--:|--:|")
    for e in table:
        types, considerate, n, p_c, q_c = e[("considerate", "success")]
        _, reactive, _, p_r, q_r = e[("best", "success")]
        pre, pre_c, _, pp_c, pq_c = e[("considerate", "pre_empted")]
        _, pre_r, _, pp_r, pq_r = e[("best", "pre_empted")]
        print(f"| {e['label']} ({e['alone']}/{n}) | {types} / {considerate} / {reactive} "
              f"(`{e['reference']}`) | {fmt(p_c)} ({fmt(q_c)}) | {fmt(p_r)} ({fmt(q_r)}) "
              f"| {pre} / {pre_c} / {pre_r} | {fmt(pp_c)} ({fmt(pq_c)}) "
              f"| {fmt(pp_r)} ({fmt(pq_r)}) | {e['against']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
