#!/usr/bin/env python3
"""Benchmark of the episode coordinator alone (Sans-I/O: no threads, no ROS, no sockets): the
wall time the coordinator itself adds to one step, from the MDP's step request through its
five calls, each answered at once, to the MDP's answer; and to one reset (drain, world and
planner reset, the episode's start). Episodes of ``--steps`` steps (``max_steps``,
``on_episode_end:=reset``), the seed's task.

``--before FILE``: the same with the ``Coordinator`` of FILE (e.g. an older
``loop/coordinator.py``, from ``git show``), side by side.

Prints a table and writes bench/results/coordinator.json. Usage:
    python bench/bench_coordinator.py [--episodes 400] [--steps 10] [--before FILE]
"""
from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path
from typing import Dict, List

from common import percentile, write_result
from ros_hrc.loop.coordinator import Coordinator, CoordinatorConfig
from ros_hrc.loop.effects import (ActHuman, ActRobot, Call, Decide, Decision, MdpReset,
                                  MdpStepDone, ObserveWorld, Outcome, Snapshot, StepRequest)

SNAPSHOT = Snapshot({"is_ov": True, "is_ir": True}, sim_time=1.0)


def answer_of(call: Call):
    if isinstance(call, (ActHuman, ActRobot)) or not isinstance(call, (ObserveWorld, Decide)):
        return Outcome(True, "done")
    if isinstance(call, ObserveWorld):
        return SNAPSHOT
    return Decision("rPoint_obj")


def run(coordinator_class, episodes: int, steps: int) -> Dict[str, List[float]]:
    """Step and reset wall times (µs) over ``episodes`` episodes of ``steps`` steps."""
    c = coordinator_class(CoordinatorConfig(max_steps=steps, on_episode_end="reset"))
    times: Dict[str, List[float]] = {"step": [], "reset": []}
    out: list = []

    def settle(effects) -> list:
        """Answer every call at once (as an adapter would, but in this thread)."""
        seen = []
        while effects:
            seen += effects
            calls = [e for e in effects if isinstance(e, Call)]
            effects = []
            for call in calls:
                c.call_done(call.id, answer_of(call))
                effects += c.effects()
        return seen

    started = time.perf_counter()
    c.mdp_connected("mdp")
    out = settle(c.effects())
    times["reset"].append((time.perf_counter() - started) * 1e6)
    n = 0
    while len(times["step"]) < episodes * steps:
        reset = [e for e in out if isinstance(e, MdpReset)]
        if reset:
            n = 0
        started = time.perf_counter()
        c.step_requested("mdp", StepRequest(epoch=c.epoch, step=n, action="lookAround",
                                            state="evaluating", reply=n))
        out = settle(c.effects())
        spent = (time.perf_counter() - started) * 1e6
        done = [e for e in out if isinstance(e, MdpStepDone)]
        assert done, out
        # A step that ended the episode also carried the next reset (on_episode_end:=reset).
        times["reset" if done[0].episode_over else "step"].append(spent)
        n += 1
    return times


def load_before(path: Path):
    spec = importlib.util.spec_from_file_location("ros_hrc.loop._coordinator_before", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module      # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module.Coordinator


def figures(times: List[float]) -> Dict[str, float]:
    return {"p50_us": percentile(times, 50), "p99_us": percentile(times, 99),
            "mean_us": sum(times) / len(times), "count": len(times)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=400)
    p.add_argument("--steps", type=int, default=10)
    p.add_argument("--before", type=Path, help="a coordinator.py to compare with")
    p.add_argument("--out", type=Path, default=Path(__file__).parent / "results" /
                   "coordinator.json")
    args = p.parse_args(argv)
    if args.episodes < 1 or args.steps < 2:
        p.error("--episodes must be at least 1 and --steps at least 2")
    kinds = {"now": Coordinator}
    if args.before is not None:
        if not args.before.is_file():
            p.error(f"--before {args.before}: no such file")
        kinds = {"before": load_before(args.before), "now": Coordinator}
    result = {}
    for _ in range(2):          # the first round warms up; the second is measured
        result = {name: {part: figures(t) for part, t in
                         run(cls, args.episodes, args.steps).items()}
                  for name, cls in kinds.items()}
    print(f"coordinator alone, {args.episodes} episodes of {args.steps} steps, seed task:")
    print(f"{'':8} {'part':6} {'p50 µs':>8} {'p99 µs':>8} {'mean µs':>8}")
    for name, parts in result.items():
        for part, f in parts.items():
            print(f"{name:8} {part:6} {f['p50_us']:8.1f} {f['p99_us']:8.1f} {f['mean_us']:8.1f}")
    write_result(args.out, {"python": sys.version.split()[0], **result})
    return 0


if __name__ == "__main__":
    sys.exit(main())
