#!/usr/bin/env python3
"""`make bench`: every benchmark in turn; each prints its figures and writes
bench/results/<name>.json. `make bench ARGS="link loop"` runs only those."""
import importlib.util
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))  # the benchmarks share bench/common.py
ORDER = ["pomdp", "world", "link", "loop", "experiment"]


def main() -> int:
    wanted = sys.argv[1:] or ORDER
    failed = []
    for name in wanted:
        path = HERE / f"bench_{name}.py"
        if not path.exists():
            print(f"=== {name}: no {path.name}, skipped")
            continue
        print(f"=== bench {name}", flush=True)
        spec = importlib.util.spec_from_file_location(f"bench_{name}", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        if module.main([]) != 0:
            failed.append(name)
    if failed:
        print(f"benchmarks that failed: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
