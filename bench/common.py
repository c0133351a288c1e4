"""What the benchmarks share: percentiles and writing a result file."""
import json
from pathlib import Path
from typing import Iterable


def percentile(values: Iterable[float], q: float) -> float:
    """Nearest-rank percentile (q in 0..100)."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q / 100 * len(ordered)) - 1))]


def write_result(path: Path, result: dict) -> None:
    """Write a benchmark's figures as JSON and say where."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(f"  written to {path}")


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now (for a benchmark's own roscore)."""
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def init_node_when_master_is_up(name: str, wait: float = 60.0) -> None:
    """rospy.init_node, retried while the roscore the benchmark launched is starting."""
    import time
    import rospy  # imported late: the caller sets ROS_MASTER_URI first
    deadline = time.monotonic() + wait
    while True:
        try:
            rospy.init_node(name, anonymous=True, disable_signals=True)
            return
        except Exception:  # the master is not up yet
            if time.monotonic() > deadline:
                raise
            time.sleep(0.5)
