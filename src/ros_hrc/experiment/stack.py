"""One cell of an experiment grid on a whole stack of its own (the ROS side of experiments).

A cell is (human model, robot policy, seed). :func:`run_cell` starts ``hrc.launch`` headless
on simulated time, as fast as the machine goes, with a roscore and websocket ports of its own
(so several cells run side by side), then for each episode: ``/hrc/reset``, read the world's
clock, collect ``/hrc/status`` until the episode is over (success, the object left the belt, or
the step limit), score it, and hand the row over. The MDP and the robot run exactly as in
``roslaunch ros_hrc hrc.launch``: nothing is simulated around them.

Each cell runs in a process of its own (``python -m ros_hrc.experiment.stack SPEC_JSON``, what
``hrc_experiment`` starts): rospy allows one node per process. The ROS side of a cell, the node
that resets and watches the stack, is :mod:`ros_hrc.nodes.experiment_cell`, imported only
once ``ROS_MASTER_URI`` points at the cell's own master. The process writes one line per episode on
its standard output, ``EPISODE {json}``, as soon as the episode ends.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, List, Optional, Sequence

from ros_hrc.experiment.episode import ROBOT_POLICIES
from ros_hrc.experiment.results import EpisodeRow, StepRow
from ros_hrc.link.transport import free_port
from ros_hrc.model_files import resolve_model
from ros_hrc.pomdp.io import load_model


@dataclass
class CellSpec:
    """What one worker runs."""
    human_model: str
    robot_policy: str
    seed: int
    episodes: Sequence[int]             # episode numbers still to record (resume skips others)
    step_limit: int = 20
    log_dir: str = "."
    robot_model: str = "robot"
    human_choice: str = "optimal"
    time_per_step: float = 0.05
    max_trials: int = 0
    reactive_budget: int = 8
    extra_args: List[str] = field(default_factory=list)   # more hrc.launch arguments
    episode_timeout: float = 600.0      # wall seconds without a step before giving up
    record_bag: bool = False            # rosbag of /hrc/status next to the logs


class CellFailed(RuntimeError):
    """The stack of a cell did not come up or stopped stepping."""


def launch_arguments(spec: CellSpec, ports: dict) -> List[str]:
    """``hrc.launch`` arguments for a cell: headless, simulated time, fastest pace, the
    driver decides when episodes end (so the MDP never waits for a reset by itself)."""
    if spec.robot_policy not in ROBOT_POLICIES:
        raise ValueError(f"unknown robot policy {spec.robot_policy!r}; known: "
                         f"{', '.join(ROBOT_POLICIES)}")
    return [
        f"human_model:={spec.human_model}", f"robot_model:={spec.robot_model}",
        f"planner:={ROBOT_POLICIES[spec.robot_policy]}", f"seed:={spec.seed}",
        "mode:=auto", "gui:=false", "use_sim_time:=true", "real_time_factor:=0",
        "step_delay:=0", "max_steps:=0", "on_episode_end:=continue", "read_stdin:=false",
        f"human_choice:={spec.human_choice}", f"time_per_step:={spec.time_per_step}",
        f"max_trials:={spec.max_trials}", f"reactive_budget:={spec.reactive_budget}",
        f"pomdp_port:={ports['pomdp']}", f"robot_port:={ports['robot']}",
        f"human_port:={ports['human']}",
    ] + list(spec.extra_args)


def stop_launched(proc: subprocess.Popen, grace: float = 60.0) -> None:
    """Stop a roslaunch (or rosbag) started with ``start_new_session=True`` as Ctrl-C would:
    SIGINT to its whole process group, SIGKILL if it is still there after ``grace`` s."""
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(grace)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def run_cell(spec: CellSpec, deliver: Callable[[object, list], None]) -> int:
    """Run the cell's episodes; ``deliver(episode_row, step_rows)`` for each one as it ends.
    Returns how many episodes were delivered; raises CellFailed if the stack fails."""
    if not spec.episodes:
        return 0
    model = load_model(str(resolve_model(spec.robot_model, "robot")))
    ports = {name: free_port() for name in ("master", "pomdp", "robot", "human")}
    log_dir = Path(spec.log_dir)
    log_dir.mkdir(parents=True, exist_ok=True)
    name = f"{spec.human_model}-{spec.robot_policy}-seed{spec.seed}"
    os.environ["ROS_MASTER_URI"] = f"http://127.0.0.1:{ports['master']}"
    os.environ["ROS_LOG_DIR"] = str(log_dir / "ros")
    cmd = ["roslaunch", "-p", str(ports["master"]), "ros_hrc", "hrc.launch"]
    cmd += launch_arguments(spec, ports)
    with open(log_dir / f"{name}.log", "wb") as log:
        proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=log,
                                stderr=subprocess.STDOUT, start_new_session=True)
    try:
        from ros_hrc.nodes.experiment_cell import drive_cell   # rospy: ROS_MASTER_URI is set
        return drive_cell(spec, model, proc, deliver, name, log_dir)
    finally:
        stop_launched(proc)


#: Prefix of a worker's stdout line carrying a finished episode.
EPISODE_LINE = "EPISODE "


def encode_episode(row: EpisodeRow, steps: list) -> str:
    return EPISODE_LINE + json.dumps({"episode": row.as_dict(),
                                      "steps": [s.as_dict() for s in steps]})


def decode_episode(line: str):
    """(EpisodeRow, [StepRow]) from a worker's line, or None for any other line."""
    if not line.startswith(EPISODE_LINE):
        return None
    data = json.loads(line[len(EPISODE_LINE):])
    return (EpisodeRow.from_dict(data["episode"]),
            [StepRow.from_dict(s) for s in data["steps"]])


def worker_command(spec: CellSpec) -> List[str]:
    """The command that runs ``spec`` in a process of its own."""
    return [sys.executable, "-m", "ros_hrc.experiment.stack", json.dumps(asdict(spec))]


def main(argv: Optional[list] = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    spec_dict = json.loads(argv[0])
    spec_dict["episodes"] = list(spec_dict["episodes"])
    spec = CellSpec(**spec_dict)

    def deliver(row, steps) -> None:
        print(encode_episode(row, steps), flush=True)

    try:
        run_cell(spec, deliver)
    except (CellFailed, OSError, ValueError) as exc:
        print(f"cell {spec.human_model}/{spec.robot_policy}/seed {spec.seed} failed: {exc}",
              file=sys.stderr, flush=True)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
