#!/usr/bin/env python3
"""Benchmark of the websocket link alone (no ROS, no planner, no world).

* round trip: a MessageClient sends a realistic ``step`` (with the MDP's belief) and waits for
  the server's ``ack`` (matched by correlation id; the server's reply goes out through the
  peer's outbox and writer thread) — the cost the link adds to each hop of one loop step —
  p50 / p99 / mean / max in ms, and the request/response rate;
* one-way throughput: the client sends messages back to back, the server's handler counts
  them: messages per second through the link;
* codec: encode + decode of the same ``step`` message without a socket (the Sans-I/O share);
* connect: a new client's connection until it is served, with the launch's link token (the
  hello with its HMAC proof and the server's proof back) and without one: what the token
  costs, once per connection.

Every server and client here uses a link token, as the stack's do.

Prints a table and writes bench/results/link.json. Usage:
    python bench/bench_link.py [--count 5000] [--out bench/results/link.json]
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import threading
import time
from pathlib import Path
from typing import Dict

import websockets

from ros_hrc.link.protocol import Ack, Message, Step, decode, encode
from ros_hrc.link.token import TOKEN_BYTES
from ros_hrc.link.transport import MessageClient, MessageServer, Peer

#: A launch's token, as hrc_check makes it (the bench needs no file).
TOKEN = os.urandom(TOKEN_BYTES).hex()

from common import percentile, write_result  # bench/common.py

HUMAN_STATES = ("task_assigned", "success", "failed_to_grasp", "no_attention", "evaluating",
                "tired", "recovery", "warningTheRobot")


def sample_step(n: int) -> Step:
    """A step as despot_mdp sends it: action, state, reward, an 8-state belief, its epoch."""
    belief = {s: 0.2 / 7 for s in HUMAN_STATES}
    belief["evaluating"] = 0.8
    return Step(step=n, action="graspAttempt", state="evaluating", reward=-1.0, state_index=4,
                belief=belief, manual=False, epoch=1)


def bench_round_trip(count: int, warmup: int) -> Dict[str, float]:
    def ack(msg: Message, peer: Peer) -> Message:
        return Ack(step=msg.step, of=msg.type, action="rPoint_obj", success=True, result="ok",
                   episode=1)

    with MessageServer(0, ack, name="bench-server", token=TOKEN) as server, \
            MessageClient(server.url, "bench-client", token=TOKEN) as client:
        for i in range(warmup):
            client.request(sample_step(i), timeout=10)
        latencies = []
        started = time.perf_counter()
        for i in range(count):
            t0 = time.perf_counter()
            client.request(sample_step(i), timeout=10)
            latencies.append((time.perf_counter() - t0) * 1e3)
        elapsed = time.perf_counter() - started
    latencies.sort()
    return {"p50_ms": percentile(latencies, 50), "p99_ms": percentile(latencies, 99),
            "mean_ms": statistics.fmean(latencies), "max_ms": latencies[-1],
            "round_trips_per_s": count / elapsed}


def bench_one_way(count: int) -> Dict[str, float]:
    received = 0
    done = threading.Event()

    def count_it(msg: Message, peer: Peer) -> None:
        nonlocal received
        received += 1  # handler calls are serialised by the server
        if received == count:
            done.set()

    with MessageServer(0, count_it, name="bench-sink", token=TOKEN) as server, \
            MessageClient(server.url, "bench-source", token=TOKEN) as client:
        assert server.wait_for_client(10, who="bench-source")
        started = time.perf_counter()
        for i in range(count):
            client.send(sample_step(i))
        if not done.wait(60):
            raise RuntimeError(f"only {received} of {count} messages arrived")
        elapsed = time.perf_counter() - started
    return {"messages_per_s": count / elapsed}


def bench_connect(count: int, token) -> Dict[str, float]:
    """ms from a new client's start until it is connected (and, with a token, both proofs
    checked)."""
    times = []
    with MessageServer(0, lambda msg, peer: None, name="bench-door", token=token) as server:
        for _ in range(count):
            t0 = time.perf_counter()
            client = MessageClient(server.url, "bench-visitor", token=token).connect(10)
            times.append((time.perf_counter() - t0) * 1e3)
            client.close()
    times.sort()
    return {"p50_ms": percentile(times, 50), "p99_ms": percentile(times, 99)}


def bench_codec(count: int) -> Dict[str, float]:
    msg = sample_step(7)
    text = encode(msg)
    started = time.perf_counter()
    for _ in range(count):
        decode(encode(msg))
    elapsed = time.perf_counter() - started
    return {"encode_decode_us": elapsed / count * 1e6, "frame_bytes": len(text.encode())}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=5000, help="messages per measurement")
    parser.add_argument("--warmup", type=int, default=200, help="round trips not measured")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).resolve().parent / "results" / "link.json")
    args = parser.parse_args(argv)

    round_trip = bench_round_trip(args.count, args.warmup)
    one_way = bench_one_way(args.count)
    codec = bench_codec(args.count)
    connects = max(20, args.count // 25)
    with_token = bench_connect(connects, TOKEN)
    without_token = bench_connect(connects, None)

    print(f"link benchmark: {args.count} messages, 127.0.0.1, step frame of "
          f"{codec['frame_bytes']} bytes")
    print(f"  round trip step->ack  p50 {round_trip['p50_ms']:.3f} ms   "
          f"p99 {round_trip['p99_ms']:.3f} ms   mean {round_trip['mean_ms']:.3f} ms   "
          f"max {round_trip['max_ms']:.3f} ms")
    print(f"  request/response      {round_trip['round_trips_per_s']:.0f} round trips/s")
    print(f"  one-way throughput    {one_way['messages_per_s']:.0f} messages/s")
    print(f"  encode+decode         {codec['encode_decode_us']:.1f} us per message (no socket)")
    print(f"  connect (x{connects})        with the link token p50 {with_token['p50_ms']:.2f} ms "
          f"p99 {with_token['p99_ms']:.2f} ms; without p50 {without_token['p50_ms']:.2f} ms "
          f"p99 {without_token['p99_ms']:.2f} ms")

    result = {
        "benchmark": "link",
        "when": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "count": args.count,
        "round_trip": round_trip,
        "one_way": one_way,
        "codec": codec,
        "connect": {"with_token": with_token, "without_token": without_token},
        "environment": {
            "python": platform.python_version(),
            "websockets": websockets.__version__,
            "cpus": os.cpu_count(),
            "machine": platform.machine(),
        },
    }
    write_result(args.out, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
