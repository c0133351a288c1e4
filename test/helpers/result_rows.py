"""The rows of a study's CSV files, for tests that set two runs side by side
(test_cluster.py, test_grid_stacks.py), and rows made up for the tests of the results files
(test_results.py, test_results_full_disk.py)."""
import csv
from pathlib import Path

from ros_hrc.experiment.rows import EpisodeRow, StepRow

#: Columns that measure this machine's speed, not the episode.
TIMED_COLUMNS = frozenset({"mean_decision_ms", "wall_seconds"})


def rows_of(path: Path, drop=frozenset()) -> list:
    """The rows of a CSV file as dicts, without the ``drop`` columns, in the file's order."""
    with open(path, newline="") as f:
        return [{k: v for k, v in row.items() if k not in drop} for row in csv.DictReader(f)]


def episode(human="careful", policy="pomdp", seed=0, number=0, outcome="human", **over):
    """An episode row; outcome is who succeeded, or the end reason of a failure."""
    success = outcome in ("human", "robot")
    values = dict(human_model=human, robot_policy=policy, seed=seed, episode=number,
                  success=int(success), succeeded_by=outcome if success else "none",
                  end_reason="success" if success else outcome, steps=12, sim_seconds=6.5,
                  robot_discounted_reward=-3.25, intrusive_actions=1, warnings=0,
                  zero_probability_observations=1, mean_decision_ms=4.5, wall_seconds=9.75)
    values.update(over)
    return EpisodeRow(**values)


def steps_of(row, needs=(0, 1, 1, 0), beliefs=(0.1, 0.4, 0.8, 0.3)):
    return [StepRow(row.human_model, row.robot_policy, row.seed, row.episode, i, "idle",
                    "evaluating", "S2" if n else "S0", "rIdle", "O3", b, n, 0)
            for i, (n, b) in enumerate(zip(needs, beliefs))]
