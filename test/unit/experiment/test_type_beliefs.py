"""tools/type_beliefs.py: the type belief of a study's pomdp_types episodes, replayed from
steps.csv on the shipped seed model of types."""
import csv
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[3]
COLUMNS = ["human_model", "robot_policy", "seed", "episode", "step", "robot_action",
           "observation"]


def write_steps(path: Path, rows):
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(COLUMNS)
        writer.writerows(rows)


def run(*args):
    return subprocess.run([sys.executable, str(ROOT / "tools" / "type_beliefs.py"), *args],
                          capture_output=True, text=True)


def test_a_replayed_episode_is_the_exact_belief_step_by_step(tmp_path):
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import type_beliefs
    finally:
        sys.path.remove(str(ROOT / "tools"))
    from ros_hrc.models import load_robot_model
    from ros_hrc.pomdp.belief import update
    from ros_hrc.pomdp.typed import TypeLayout
    model = load_robot_model("robot_types", "seed")
    layout = TypeLayout.of(model)
    steps = [{"observation": "O7", "robot_action": "rIdle"},
             {"observation": "O7", "robot_action": "rStop_all"},
             {"observation": "O11", "robot_action": "rIdle"}]
    got = type_beliefs.episode_type_beliefs(model, layout, steps)
    b = model.initial_belief
    previous = model.index("action", "rIdle")          # the robot process's first action
    for row, replayed in zip(steps, got):
        b, _ = update(model, b, previous, model.index("observation", row["observation"]))
        previous = model.index("action", row["robot_action"])
        assert np.allclose(replayed, layout.type_marginal(b))


def test_the_table_names_each_human_and_refuses_a_run_without_the_policy(tmp_path):
    write_steps(tmp_path / "steps.csv", [
        ["persistent_failer", "pomdp_types", 2, 0, 0, "rIdle", "O7"],
        ["persistent_failer", "pomdp_types", 2, 0, 1, "rStop_all", "O7"],
        ["expert", "pomdp_types", 2, 0, 0, "rIdle", "O11"],
        ["expert", "pomdp_considerate", 2, 0, 0, "rIdle", "O11"]])
    done = run(str(tmp_path), "--plot", str(tmp_path / "beliefs.png"))
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stdout.splitlines() if line.startswith("| ")]
    assert [line.split(" | ")[0] for line in lines[1:]] == ["| persistent_failer", "| expert"]
    assert (tmp_path / "beliefs.png").stat().st_size > 0
    refused = run(str(tmp_path), "--policy", "pomdp")
    assert refused.returncode == 2 and "no pomdp steps" in refused.stderr
    refused = run(str(tmp_path / "nowhere"))
    assert refused.returncode == 2 and "no steps.csv" in refused.stderr
