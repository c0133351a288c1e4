#!/usr/bin/env python3
"""Write RockSample[n, k] (Smith and Simmons, "Heuristic search value iteration for POMDPs",
UAI 2004) as a factored POMDPX file, so tests and benchmarks can make RockSample_7_8 locally.

    python bench/make_rocksample_pomdpx.py 7 8 -o /tmp/RockSample_7_8.pomdpx

The problem: a rover on an n x n grid knows where k rocks are but not which are good.
* State variables: ``robot_0/robot_1`` (fully observable): cells ``s<x><y>`` (x grows east,
  y grows north; ``s<x>_<y>`` when n > 10) and the terminal ``st``; ``rock<i>_0/rock<i>_1``
  (hidden): ``bad good``, each good with probability 1/2 at the start.
* Actions ``amn ame ams amw`` (move north, east, south, west), ``ac0 .. ac<k-1>`` (check a
  rock with the long-range sensor), ``as`` (sample the rock under the rover). Moving into the
  north, south or west edge leaves the rover where it is; moving east off the grid enters
  ``st`` for good (+10). Sampling a good rock pays +10 and makes it bad; a bad rock costs -10;
  sampling where there is no rock does nothing.
* Observation ``obs_sensor``: ``none`` after every action but a check; a check of rock i from
  distance d reports its true value with probability (1 + eta) / 2, where the sensor's
  efficiency ``eta = 2 ** (-d / d0)`` halves every ``d0`` = 20 cells (the half-efficiency
  distance). Together with the fully observable position the model has 3 x (n*n + 1)
  observations.
* Discount 0.95. RockSample[7, 8] uses the published rock layout and starts at (0, 3); other
  sizes place rocks at random cells (``--seed``) and start at (0, n // 2).

Rewards are three kinds of ``<Func>`` (exit, and one per rock for sampling), each of a reward
variable of its own (``reward_exit``, ``reward_rock<i>``), summed by the reader; the transition of each rock is an identity with one override, so the file exercises
``*``, ``-``, ``identity`` and several state variables.
"""
from __future__ import annotations

import argparse
import math
import random
import sys
from pathlib import Path
from typing import List, Optional, Sequence, Tuple

#: The layout of RockSample[7, 8] used in the literature (x, y), and its start cell.
STANDARD_7_8 = [(2, 0), (0, 1), (3, 1), (6, 3), (2, 4), (3, 4), (5, 5), (1, 6)]
STANDARD_7_8_START = (0, 3)


def _cell(x: int, y: int, n: int) -> str:
    return f"s{x}{y}" if n <= 10 else f"s{x}_{y}"


def _layout(n: int, k: int, seed: int) -> Tuple[List[Tuple[int, int]], Tuple[int, int]]:
    if (n, k) == (7, 8):
        return list(STANDARD_7_8), STANDARD_7_8_START
    start = (0, n // 2)
    cells = [(x, y) for x in range(n) for y in range(n) if (x, y) != start]
    if k > len(cells):
        raise ValueError(f"{k} rocks do not fit on a {n} x {n} grid")
    return random.Random(seed).sample(cells, k), start


def _fmt(p: float) -> str:
    return format(p, ".10g")


def rocksample_pomdpx(n: int, k: int, rocks: Optional[Sequence[Tuple[int, int]]] = None,
                      start: Optional[Tuple[int, int]] = None, half_distance: float = 20.0,
                      discount: float = 0.95, seed: int = 0) -> str:
    """The POMDPX text of RockSample[n, k]."""
    if rocks is None or start is None:
        default_rocks, default_start = _layout(n, k, seed)
        rocks = list(rocks) if rocks is not None else default_rocks
        start = start if start is not None else default_start
    cells = [(x, y) for x in range(n) for y in range(n)]
    names = [_cell(x, y, n) for x, y in cells] + ["st"]
    checks = [f"ac{i}" for i in range(k)]
    actions = ["amn", "ame", "ams", "amw"] + checks + ["as"]
    rock_at = {pos: i for i, pos in enumerate(rocks)}
    out: List[str] = []
    w = out.append

    w('<?xml version="1.0" encoding="ISO-8859-1"?>')
    w(f'<pomdpx version="1.0" id="RockSample_{n}_{k}"')
    w('        xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"')
    w('        xsi:noNamespaceSchemaLocation="pomdpx.xsd">')
    w(f"  <Description>RockSample[{n},{k}] (Smith and Simmons 2004), written by ros_hrc's "
      f"bench/make_rocksample_pomdpx.py. Start {start}; rocks "
      + " ".join(f"{i}:{pos}" for i, pos in enumerate(rocks)) + "</Description>")
    w(f"  <Discount>{discount}</Discount>")
    w("  <Variable>")
    w('    <StateVar vnamePrev="robot_0" vnameCurr="robot_1" fullyObs="true">')
    w(f"      <ValueEnum>{' '.join(names)}</ValueEnum>")
    w("    </StateVar>")
    for i in range(k):
        w(f'    <StateVar vnamePrev="rock{i}_0" vnameCurr="rock{i}_1" fullyObs="false">')
        w("      <ValueEnum>bad good</ValueEnum>")
        w("    </StateVar>")
    w('    <ObsVar vname="obs_sensor"><ValueEnum>none ogood obad</ValueEnum></ObsVar>')
    w(f'    <ActionVar vname="action_robot"><ValueEnum>{" ".join(actions)}</ValueEnum></ActionVar>')
    # One reward variable per <Func>, as SARSOP's own RockSample files have them: its reader
    # refuses a file whose reward variables and functions differ in number.
    w('    <RewardVar vname="reward_exit"/>')
    for i in range(k):
        w(f'    <RewardVar vname="reward_rock{i}"/>')
    w("  </Variable>")

    # Initial belief: the rover's cell is known, every rock is good or bad with 1/2.
    w("  <InitialStateBelief>")
    where = " ".join("1" if name == _cell(*start, n) else "0" for name in names)
    w("    <CondProb><Var>robot_0</Var><Parent>null</Parent><Parameter type=\"TBL\">")
    w(f"      <Entry><Instance>-</Instance><ProbTable>{where}</ProbTable></Entry>")
    w("    </Parameter></CondProb>")
    for i in range(k):
        w(f"    <CondProb><Var>rock{i}_0</Var><Parent>null</Parent><Parameter type=\"TBL\">")
        w("      <Entry><Instance>-</Instance><ProbTable>uniform</ProbTable></Entry>")
        w("    </Parameter></CondProb>")
    w("  </InitialStateBelief>")

    # Transitions: the rover moves deterministically; a rock only changes when sampled.
    w("  <StateTransitionFunction>")
    w("    <CondProb><Var>robot_1</Var><Parent>action_robot robot_0</Parent>"
      '<Parameter type="TBL">')
    w("      <Entry><Instance>* - -</Instance><ProbTable>identity</ProbTable></Entry>")
    for x, y in cells:
        here = _cell(x, y, n)
        moves = {"amn": _cell(x, min(y + 1, n - 1), n), "ams": _cell(x, max(y - 1, 0), n),
                 "amw": _cell(max(x - 1, 0), y, n),
                 "ame": _cell(x + 1, y, n) if x + 1 < n else "st"}
        for action, there in moves.items():
            if there != here:
                w(f"      <Entry><Instance>{action} {here} -</Instance><ProbTable>"
                  + " ".join("1" if name == there else "0" for name in names)
                  + "</ProbTable></Entry>")
    w("    </Parameter></CondProb>")
    for i, (x, y) in enumerate(rocks):
        w(f"    <CondProb><Var>rock{i}_1</Var><Parent>action_robot robot_0 rock{i}_0</Parent>"
          '<Parameter type="TBL">')
        w("      <Entry><Instance>* * - -</Instance><ProbTable>identity</ProbTable></Entry>")
        w(f"      <Entry><Instance>as {_cell(x, y, n)} - -</Instance>"
          "<ProbTable>1 0 1 0</ProbTable></Entry>")
        w("    </Parameter></CondProb>")
    w("  </StateTransitionFunction>")

    # Observations: 'none' unless checking; a check is noisier the farther the rock.
    w("  <ObsFunction>")
    rock_vars = " ".join(f"rock{i}_1" for i in range(k))
    w(f"    <CondProb><Var>obs_sensor</Var><Parent>action_robot robot_1 {rock_vars}</Parent>"
      '<Parameter type="TBL">')
    w("      <Entry><Instance>" + " ".join(["*"] * (k + 2)) + " -</Instance>"
      "<ProbTable>1 0 0</ProbTable></Entry>")
    for i, (rx, ry) in enumerate(rocks):
        for x, y in cells:
            d = math.hypot(x - rx, y - ry)
            right = (1.0 + 2.0 ** (-d / half_distance)) / 2.0
            inst = ["*"] * k
            inst[i] = "-"
            # rows: rock bad, rock good; columns: none ogood obad
            w(f"      <Entry><Instance>ac{i} {_cell(x, y, n)} {' '.join(inst)} -</Instance>"
              f"<ProbTable>0 {_fmt(1 - right)} {_fmt(right)} 0 {_fmt(right)} {_fmt(1 - right)}"
              "</ProbTable></Entry>")
    w("    </Parameter></CondProb>")
    w("  </ObsFunction>")

    # Rewards: exit east, and one function per rock for sampling it.
    w("  <RewardFunction>")
    w("    <Func><Var>reward_exit</Var><Parent>action_robot robot_0</Parent>"
      '<Parameter type="TBL">')
    for y in range(n):
        w(f"      <Entry><Instance>ame {_cell(n - 1, y, n)}</Instance>"
          "<ValueTable>10</ValueTable></Entry>")
    w("    </Parameter></Func>")
    for i, (x, y) in enumerate(rocks):
        w(f"    <Func><Var>reward_rock{i}</Var><Parent>action_robot robot_0 rock{i}_0</Parent>"
          '<Parameter type="TBL">')
        w(f"      <Entry><Instance>as {_cell(x, y, n)} -</Instance>"
          "<ValueTable>-10 10</ValueTable></Entry>")
        w("    </Parameter></Func>")
    w("  </RewardFunction>")
    w("</pomdpx>")
    return "\n".join(out) + "\n"


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("n", type=int, help="grid size")
    parser.add_argument("k", type=int, help="number of rocks")
    parser.add_argument("-o", "--output", help="file to write (default RockSample_<n>_<k>.pomdpx)")
    parser.add_argument("--seed", type=int, default=0, help="rock layout for non-standard sizes")
    args = parser.parse_args(argv)
    path = Path(args.output or f"RockSample_{args.n}_{args.k}.pomdpx")
    path.write_text(rocksample_pomdpx(args.n, args.k, seed=args.seed), encoding="ascii")
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
