"""The model names hrc.launch's --ros-args and docs/settings.md list are the model files that
ship, task by task (before: 5 human models listed of the 16 seed and 10 fabric ones, and the
robot models said to be in models/robot/ alone)."""
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
SHIPPED = {("seed", "human"): ROOT / "models" / "human",
           ("seed", "robot"): ROOT / "models" / "robot",
           ("fabric", "human"): ROOT / "models" / "fabric" / "human",
           ("fabric", "robot"): ROOT / "models" / "fabric" / "robot"}


def shipped(folder):
    return sorted({p.stem for p in folder.iterdir() if p.suffix in (".pomdp", ".pomdpx")})


def listed(doc, task, folder):
    """The names ``doc`` lists for ``task`` in ``folder``."""
    relative = folder.relative_to(ROOT).as_posix()
    found = re.search(rf"{task}, in {re.escape(relative)}/: ([^;)]*)", doc)
    assert found, (task, relative, doc)
    return found.group(1).split(", ")


def ros_args_docs():
    done = subprocess.run(["roslaunch", "ros_hrc", "hrc.launch", "--ros-args"],
                          capture_output=True, text=True, timeout=120,
                          stdin=subprocess.DEVNULL)
    assert done.returncode == 0, done.stderr
    return {line.split(" (default")[0].strip(): line for line in done.stdout.splitlines()
            if line.startswith("  ")}


@pytest.fixture(scope="module")
def docs():
    ros_args = ros_args_docs()
    reference = (ROOT / "docs" / "settings.md").read_text(encoding="utf-8")
    rows = {name: next(line for line in reference.splitlines()
                       if line.startswith(f"| `{name}` |"))
            for name in ("human_model", "robot_model")}
    return ros_args, rows


@pytest.mark.parametrize("task, kind", sorted(SHIPPED))
def test_the_listed_models_are_the_shipped_files(docs, task, kind):
    ros_args, rows = docs
    folder = SHIPPED[(task, kind)]
    assert listed(ros_args[f"{kind}_model"], task, folder) == shipped(folder)
    assert listed(rows[f"{kind}_model"], task, folder) == shipped(folder)
