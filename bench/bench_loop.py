#!/usr/bin/env python3
"""Benchmark of the whole loop, headless: per-step latency of the full loop and steps/s.

Starts `roslaunch ros_hrc hrc.launch` (world on real_time_factor 0, no pause between steps,
auto mode, episodes going on) with its own roscore on a free port, listens to /hrc/status and
times the gaps between consecutive steps: one gap is a whole step — MDP decision, human
action in the world, one world snapshot, the decision (DESPOT, over hrc_human's link to it),
robot action, outcome snapshot, answers. Prints p50 / p99 of the step latency, steps per
second, the mean DESPOT decision time, where a step's time goes (each part's wall time, from
/hrc/status), what carrying a decision costs beside DESPOT's own part and what each robot
action takes (medians); writes bench/results/loop.json.

    python bench/bench_loop.py [--steps 60] [--time-per-step 0.05] [--human-model humanModel]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

from common import free_port, init_node_when_master_is_up, percentile, write_result  # bench/common.py

from ros_hrc.experiment.stack import stop_launched
from ros_hrc.loop.effects import STEP_TIMINGS as STEP_PARTS






def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=60, help="steps to time (after 3 warm-up steps)")
    parser.add_argument("--time-per-step", type=float, default=0.05, help="DESPOT's budget, s")
    parser.add_argument("--human-model", default="humanModel")
    parser.add_argument("--timeout", type=float, default=300.0, help="give up after this, s")
    parser.add_argument("--launch-arg", action="append", default=[], metavar="NAME:=VALUE",
                        help="one more hrc.launch argument (repeatable), e.g. viz:=false")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).resolve().parent / "results" / "loop.json")
    args = parser.parse_args(argv)

    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}")
    pomdp_port, human_port = free_port(), free_port()
    launch = subprocess.Popen(
        ["roslaunch", "--port", str(port), "ros_hrc", "hrc.launch", "gui:=false",
         "real_time_factor:=0", "step_delay:=0", "mode:=auto", "on_episode_end:=reset",
         f"time_per_step:={args.time_per_step}", f"human_model:={args.human_model}",
         f"pomdp_port:={pomdp_port}", f"human_port:={human_port}",
         "read_stdin:=false"] + args.launch_arg,
        env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True)
    os.environ["ROS_MASTER_URI"] = env["ROS_MASTER_URI"]
    import rospy  # after ROS_MASTER_URI is set
    from ros_hrc.msg import Status

    stamps, decisions, parts, sim_times, robot_actions = [], [], [], [], []
    done = threading.Event()
    warmup = 3

    def on_status(msg):
        stamps.append(time.perf_counter())
        decisions.append(msg.decision_ms)
        parts.append({part: getattr(msg, f"{part}_ms") for part in STEP_PARTS})
        robot_actions.append(msg.robot_action)
        sim_times.append((msg.epoch, msg.sim_time))
        if len(stamps) >= args.steps + warmup + 1:
            done.set()

    try:
        init_node_when_master_is_up("bench_loop")
        rospy.Subscriber("/hrc/status", Status, on_status, queue_size=1000)
        print(f"loop benchmark: waiting for {args.steps} steps of {args.human_model} ...",
              flush=True)
        if not done.wait(args.timeout):
            print(f"only {len(stamps)} steps in {args.timeout} s", file=sys.stderr)
            return 1
    finally:
        stop_launched(launch, grace=30)

    timed = stamps[warmup:]
    gaps = [(b - a) * 1000.0 for a, b in zip(timed, timed[1:])]
    result = {
        "benchmark": "loop",
        "when": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "steps": len(gaps),
        "human_model": args.human_model,
        "despot_time_per_step_s": args.time_per_step,
        "step_latency_p50_ms": percentile(gaps, 50),
        "step_latency_p99_ms": percentile(gaps, 99),
        "step_latency_mean_ms": statistics.fmean(gaps),
        "steps_per_s": len(gaps) / (timed[-1] - timed[0]),
        "despot_decision_mean_ms": statistics.fmean(decisions[warmup:]),
        # What carrying a decision costs, besides the planner's own time: the decision's round
        # trip from hrc_human less the POMDP process's own part (median over the steps: a
        # load spike on a shared machine moves it less than the mean).
        "decision_transport_p50_ms": percentile(
            [p["decide"] - d for p, d in zip(parts[warmup:], decisions[warmup:])], 50),
        # The robot's action, from hrc_human's call to its answer, per action (rIdle moves
        # nothing and takes no call).
        "robot_action_p50_ms": {
            action: percentile([p["robot"] for p, a in zip(parts[warmup:], robot_actions[warmup:])
                                if a == action], 50)
            for action in sorted(set(robot_actions[warmup:]) - {"rIdle", ""})},
        # Where a step's wall time goes (the steps' own /hrc/status figures).
        "parts_p50_ms": {part: percentile([p[part] for p in parts[warmup:]], 50) for part in STEP_PARTS},
        "parts_mean_ms": {part: statistics.fmean(p[part] for p in parts[warmup:]) for part in STEP_PARTS},
    }
    # The world's pace while the agents act: simulated seconds of a step over the wall time
    # of its two actions (steps within one epoch: a reset puts the clock on).
    simulated = acting = 0.0
    for (epoch_a, sim_a), (epoch_b, sim_b), part in zip(sim_times[warmup:], sim_times[warmup + 1:],
                                                         parts[warmup + 1:]):
        if epoch_a == epoch_b:
            simulated += sim_b - sim_a
            acting += (part["human"] + part["robot"]) / 1000.0
    result["simulated_s_per_step"] = simulated / max(1, len(gaps))
    result["world_pace_while_acting"] = simulated / acting if acting else 0.0
    print(f"  full-loop step latency  p50 {result['step_latency_p50_ms']:.1f} ms   "
          f"p99 {result['step_latency_p99_ms']:.1f} ms   mean {result['step_latency_mean_ms']:.1f} ms")
    print(f"  steps per second (headless, real_time_factor 0)  {result['steps_per_s']:.2f}")
    print(f"  DESPOT decision (mean, as reported)  {result['despot_decision_mean_ms']:.1f} ms")
    print(f"  simulated time per step {result['simulated_s_per_step']:.2f} s; the world ran "
          f"x{result['world_pace_while_acting']:.0f} real time while the agents acted")
    print("  where a step goes (mean ms): " + ", ".join(
        f"{part} {ms:.1f}" for part, ms in result["parts_mean_ms"].items()))
    print(f"  carrying a decision (p50, beside DESPOT's own part) "
          f"{result['decision_transport_p50_ms']:.1f} ms; the robot's action (p50): " + ", ".join(
              f"{a} {ms:.1f} ms" for a, ms in result["robot_action_p50_ms"].items()))
    write_result(args.out, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
