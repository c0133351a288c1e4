#!/usr/bin/env python3
"""Parse time of every model in models/, Tiger and RockSample_7_8 (generated on the fly).

    python bench/parse_times.py [--json] [--repeat N]

Prints one row per model: file, states, actions, observations, best-of-N parse seconds.
``parse_times()`` returns the same rows for a combined benchmark (``bench/run_all.py``).
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Dict, List, Optional, Sequence

ROOT = Path(__file__).resolve().parents[1]


def _rocksample_text() -> str:
    spec = importlib.util.spec_from_file_location("make_rocksample_pomdpx",
                                                  ROOT / "bench" / "make_rocksample_pomdpx.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.rocksample_pomdpx(7, 8)


def parse_times(repeat: int = 3) -> List[Dict[str, object]]:
    """Best-of-``repeat`` parse time of each benchmark model."""
    from ros_hrc.pomdp.io import load_model

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        rocksample = Path(tmp) / "RockSample_7_8.pomdpx"
        rocksample.write_text(_rocksample_text())
        paths = sorted((ROOT / "models").glob("*/*.pomdp*"))
        paths += [ROOT / "test" / "fixtures" / "tiger.95.pomdp", rocksample]
        for path in paths:
            best = float("inf")
            for _ in range(repeat):
                start = time.perf_counter()
                model = load_model(path)
                best = min(best, time.perf_counter() - start)
            rows.append({"model": path.name, "states": model.n_states,
                         "actions": model.n_actions, "observations": model.n_observations,
                         "parse_seconds": round(best, 4)})
    return rows


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description="Parse time of the benchmark models.")
    parser.add_argument("--json", action="store_true", help="one JSON object per line")
    parser.add_argument("--repeat", type=int, default=3, help="best of N parses (default 3)")
    args = parser.parse_args(argv)
    rows = parse_times(args.repeat)
    if args.json:
        for row in rows:
            print(json.dumps(row))
        return 0
    print(f"{'model':<28} {'states':>7} {'actions':>7} {'obs':>5} {'parse s':>9}")
    for row in rows:
        print(f"{row['model']:<28} {row['states']:>7} {row['actions']:>7} "
              f"{row['observations']:>5} {row['parse_seconds']:>9.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
