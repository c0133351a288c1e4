#!/usr/bin/env python3
"""The robot process's step without the search (issue #41, the extension surface): a reset and
one step of ``RobotAgent`` (belief update, ``act``) with the no-robot baseline, the path where
the planner's abilities were probed with getattr and are now the ``Planner`` interface's calls;
and ``settings.parse("planner", "despot")`` (a registered name of ours, read without the
installed distributions). Prints the best of 9 repeats, in microseconds.

    source env.sh && python bench/bench_robot_step.py NAME
    # the code before, from another checkout:  PYTHONPATH=OTHER/src:$PYTHONPATH python ...
"""
import argparse
import sys
import timeit

import numpy as np

from ros_hrc import settings
from ros_hrc.processes import despot_pomdp


def main() -> None:
    name = sys.argv[1] if len(sys.argv) > 1 else "this checkout"
    args = argparse.Namespace(task="seed", robot_model="robot", planner="none", seed=4,
                              policy_file="", reactive_budget=8, reactive_wait=0.0,
                              time_per_step=0.1, scenarios=50, depth=10, lambda_=0.1,
                              max_trials=20, selector="fixed", bpr_forgetting=0.05)
    model, _, sequence = despot_pomdp.build_robot(args)
    agent = next(iter(sequence.agents.values()))
    a = agent.first_action
    # The first observation most likely after the idle action from the initial belief.
    likely = model.dense_O[a].T @ (model.initial_belief @ model.dense_T[a])
    observation = model.observations[int(np.argmax(likely))]

    def step():
        agent.reset()
        agent.step(observation, elapsed=1.0)

    n = 5000
    step_us = min(timeit.repeat(step, number=n, repeat=9)) / n * 1e6
    m = 20000
    parse_us = min(timeit.repeat(lambda: settings.parse("planner", "despot"), number=m,
                                 repeat=9)) / m * 1e6
    print(f"{name}: RobotAgent reset + step {step_us:.1f} us; settings.parse('planner', "
          f"'despot') {parse_us:.2f} us")


if __name__ == "__main__":
    main()
