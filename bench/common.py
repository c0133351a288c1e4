"""What the benchmarks share: percentiles and writing a result file."""
import json
from pathlib import Path
from typing import Iterable

from ros_hrc.link.transport import free_port  # noqa: F401  (the benchmarks' own roscores)


def percentile(values: Iterable[float], q: float) -> float:
    """Nearest-rank percentile (q in 0..100)."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q / 100 * len(ordered)) - 1))]


def write_result(path: Path, result: dict) -> None:
    """Write a benchmark's figures as JSON and say where."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(f"  written to {path}")


def init_node_when_master_is_up(name: str, wait: float = 60.0) -> None:
    """rospy.init_node, retried while the roscore the benchmark launched is starting."""
    from ros_hrc.nodes.common import init_node_when_master_is_up as init  # needs ROS
    init(name, wait)
