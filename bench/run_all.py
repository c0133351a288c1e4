#!/usr/bin/env python3
"""`make bench`: every benchmark in turn; each prints its figures and writes
bench/results/<name>.json. `make bench ARGS="link loop"` runs only those.

Each benchmark runs in a process of its own: several are ROS nodes (one rospy.init_node per
process) and each starts its own roscore on a free port.
"""
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ORDER = ["pomdp", "world", "link", "loop", "experiment", "learning"]


def main() -> int:
    wanted = sys.argv[1:] or ORDER
    failed = []
    for name in wanted:
        path = HERE / f"bench_{name}.py"
        if not path.exists():
            print(f"=== {name}: no {path.name} (known: {', '.join(ORDER)})")
            failed.append(name)
            continue
        print(f"=== bench {name}", flush=True)
        if subprocess.run([sys.executable, str(path)], stdin=subprocess.DEVNULL).returncode != 0:
            failed.append(name)
    if failed:
        print(f"benchmarks that failed: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
