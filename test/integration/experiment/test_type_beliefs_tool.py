"""tools/type_beliefs.py run as a user runs it, on a study's steps.csv: the table names each
human, the plot is written, a run without the policy's steps or without steps.csv is refused.
(The replay itself, in-process: test/unit/experiment/test_type_beliefs.py.)"""
import csv
import subprocess
import sys
from pathlib import Path

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
