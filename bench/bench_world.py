#!/usr/bin/env python3
"""Benchmark of the PyBullet world: physics speed headless and predicate-service latency.

1. In process (no ROS): physics steps per second with nobody moving (belt running) and with
   the human and robot acting back to back; the real-time factor the stepping thread reaches
   when asked for "as fast as possible" (0) and for real time (1.0); the latency of a
   predicate query (``is_ov``: field-of-view cone plus a ray test) while that thread runs.
2. Through ROS: starts ``roslaunch ros_hrc world.launch`` (headless, real_time_factor 1.0) with
   its own roscore on a free port, and times ``/human/is_ov`` calls as the observer node makes
   them (persistent connection), plus calls that open a new connection each time.

Prints the figures and writes bench/results/world.json.

    python bench/bench_world.py [--calls 300] [--seconds 5] [--no-ros]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from common import free_port, init_node_when_master_is_up, percentile, write_result  # bench/common.py

from ros_hrc.experiment.stack import stop_launched






#: Runs per physics figure (the median is printed).
REPEATS = 5


def in_process(seconds: float, calls: int) -> dict:
    from ros_hrc.world import World, WorldConfig

    result = {}
    plan = [("human", "look_around"), ("robot", "point_to_obj"), ("human", "grasp"),
            ("human", "walk_away"), ("human", "reset"), ("human", "warn_robot"),
            ("robot", "reset"), ("human", "attempt_grasp")]
    with World(WorldConfig(seed=0)) as world:
        world.advance(0.5)   # warm-up: PyBullet's first steps are slower
        idle, acting = [], []
        # Each figure is the median of REPEATS runs: a shared VM's speed wanders by ±20 %.
        for _ in range(REPEATS):
            first_step, start = world.step_count, time.perf_counter()
            world.advance(seconds)
            idle.append((world.step_count - first_step) / (time.perf_counter() - start))

            world.reset()
            first_step, start = world.step_count, time.perf_counter()
            while (world.step_count - first_step) * world.time_step < seconds:
                for agent, action in plan:
                    world.run(agent, action)
            acting.append((world.step_count - first_step) / (time.perf_counter() - start))
        result["steps_per_s_idle"] = statistics.median(idle)
        result["steps_per_s_acting"] = statistics.median(acting)
        result["steps_per_s_acting_runs"] = acting
        result["time_step_s"] = world.time_step
        result["substeps"] = world.config.substeps

        for factor, key in ((0.0, "rtf_reached_max"), (1.0, "rtf_reached_at_1")):
            world.reset()
            world.start(real_time_factor=factor)
            time.sleep(0.2)  # let it get going
            sim0, wall0 = world.sim_time, time.perf_counter()
            time.sleep(min(seconds, 3.0))
            result[key] = (world.sim_time - sim0) / (time.perf_counter() - wall0)
            if factor == 1.0:
                latencies = []
                for _ in range(calls):
                    t0 = time.perf_counter()
                    world.query("is_ov")
                    latencies.append((time.perf_counter() - t0) * 1000.0)
                result["query_p50_ms_in_process"] = percentile(latencies, 50)
                result["query_p99_ms_in_process"] = percentile(latencies, 99)
            world.stop()
    return result


def through_ros(calls: int) -> dict:
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}")
    launch = subprocess.Popen(
        ["roslaunch", "--port", str(port), "ros_hrc", "world.launch", "gui:=false",
         "real_time_factor:=1.0"],
        env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True)
    os.environ["ROS_MASTER_URI"] = env["ROS_MASTER_URI"]
    import rospy  # after ROS_MASTER_URI is set
    from std_srvs.srv import Trigger

    try:
        init_node_when_master_is_up("bench_world")
        rospy.wait_for_service("/human/is_ov", timeout=60)
        persistent = rospy.ServiceProxy("/human/is_ov", Trigger, persistent=True)
        for _ in range(20):
            persistent()  # warm-up
        latencies = []
        for _ in range(calls):
            t0 = time.perf_counter()
            persistent()
            latencies.append((time.perf_counter() - t0) * 1000.0)
        persistent.close()
        fresh = []
        for _ in range(max(20, calls // 6)):
            t0 = time.perf_counter()
            rospy.ServiceProxy("/human/is_ov", Trigger)()
            fresh.append((time.perf_counter() - t0) * 1000.0)
        return {"service_calls": calls,
                "service_p50_ms": percentile(latencies, 50),
                "service_p99_ms": percentile(latencies, 99),
                "service_mean_ms": statistics.fmean(latencies),
                "service_new_connection_p50_ms": percentile(fresh, 50),
                "service_new_connection_p99_ms": percentile(fresh, 99)}
    finally:
        stop_launched(launch, grace=30)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per physics run")
    parser.add_argument("--calls", type=int, default=300, help="predicate calls to time")
    parser.add_argument("--no-ros", action="store_true", help="skip the ROS service latency")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).resolve().parent / "results" / "world.json")
    args = parser.parse_args(argv)

    print("world benchmark: physics in process ...", flush=True)
    result = {"benchmark": "world", "when": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
              "cpus": os.cpu_count()}
    result.update(in_process(args.seconds, args.calls))
    dt = result["time_step_s"]
    runs = ", ".join(f"{x:.0f}" for x in result["steps_per_s_acting_runs"])
    print(f"  physics steps/s headless (median of {REPEATS} runs): {result['steps_per_s_idle']:.0f} idle (belt running), "
          f"{result['steps_per_s_acting']:.0f} while human and robot act "
          f"(= {result['steps_per_s_idle'] * dt:.1f}x / {result['steps_per_s_acting'] * dt:.1f}x real time "
          f"at {1 / dt:.0f} Hz; motions at {1 / (dt * result['substeps']):.0f} Hz)")
    print(f"  acting runs: {runs} physics steps/s")
    print(f"  real-time factor reached: {result['rtf_reached_max']:.2f} when asked for 0 (as fast as possible), "
          f"{result['rtf_reached_at_1']:.3f} when asked for 1.0")
    print(f"  is_ov query in process (loop at 1.0): p50 {result['query_p50_ms_in_process']:.3f} ms, "
          f"p99 {result['query_p99_ms_in_process']:.3f} ms")
    if not args.no_ros:
        print("world benchmark: /human/is_ov through ROS (world.launch, real_time_factor 1.0) ...", flush=True)
        result.update(through_ros(args.calls))
        print(f"  /human/is_ov service call, persistent connection: p50 {result['service_p50_ms']:.2f} ms, "
              f"p99 {result['service_p99_ms']:.2f} ms ({args.calls} calls)")
        print(f"  /human/is_ov with a new connection per call: p50 {result['service_new_connection_p50_ms']:.2f} ms, "
              f"p99 {result['service_new_connection_p99_ms']:.2f} ms")
    write_result(args.out, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
