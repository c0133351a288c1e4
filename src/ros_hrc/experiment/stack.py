"""One cell of an experiment grid on a whole stack of its own: what a worker runs, and how it
starts and stops that stack. No ROS here.

A cell is (human model, robot policy, seed). Its worker process (``python -m
ros_hrc.nodes.experiment_cell SPEC_JSON``, see :func:`worker_command`; rospy allows one node per
process) starts ``hrc.launch`` headless, the world's clock as fast as the machine goes, with a
roscore and websocket ports of its own (:func:`start_stack`, so several cells run side by
side), drives its episodes, and writes one line per episode on its standard output,
``EPISODE {json}`` (:func:`encode_episode`), as soon as the episode ends. The MDP and the robot
run exactly as in ``roslaunch ros_hrc hrc.launch``: nothing is simulated around them.

Imports point down: the worker (``ros_hrc.nodes.experiment_cell``) imports this module; nothing
in ``ros_hrc.experiment`` imports ``ros_hrc.nodes``.
"""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Sequence

from ros_hrc.experiment.episode import ROBOT_POLICIES
from ros_hrc.experiment.store import EpisodeRow, StepRow
from ros_hrc.link.transport import free_port
from ros_hrc.loop import settings

#: The module a worker process runs (``python -m``).
WORKER_MODULE = "ros_hrc.nodes.experiment_cell"


@dataclass
class CellSpec:
    """What one worker runs. Defaults of the launch settings come from ros_hrc.loop.settings."""
    human_model: str
    robot_policy: str
    seed: int
    episodes: Sequence[int]             # episode numbers still to record (resume skips others)
    step_limit: int = 20
    log_dir: str = "."
    robot_model: str = settings.default("robot_model")
    human_choice: str = settings.default("human_choice")
    time_per_step: float = settings.default("time_per_step")
    max_trials: int = settings.default("max_trials")
    reactive_budget: int = settings.default("reactive_budget")
    scenarios: int = settings.default("scenarios")
    depth: int = settings.default("depth")
    lambda_: float = settings.default("lambda")
    extra_args: List[str] = field(default_factory=list)   # more hrc.launch arguments
    episode_timeout: float = 600.0      # wall seconds without a step before giving up
    record_bag: bool = False            # rosbag of /hrc/status next to the logs

    def to_json(self) -> str:
        return json.dumps(asdict(self))

    @classmethod
    def from_json(cls, text: str) -> "CellSpec":
        data = json.loads(text)
        data["episodes"] = list(data["episodes"])
        return cls(**data)


class CellFailed(RuntimeError):
    """The stack of a cell did not come up or stopped stepping."""


def cell_name(spec: CellSpec) -> str:
    """``<human>-<policy>-seed<seed>``, safe as a file name (a model given as a path keeps its
    stem), for the cell's log files and messages."""
    human = spec.human_model
    if "/" in human or human.endswith((".pomdp", ".pomdpx")):
        human = Path(human).stem
    name = f"{human}-{spec.robot_policy}-seed{spec.seed}"
    return re.sub(r"[^A-Za-z0-9._+-]", "_", name)


def _launch_text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def launch_settings(spec: CellSpec, ports: Mapping[str, int]) -> Dict[str, str]:
    """The ``hrc.launch`` arguments of a cell, name -> text: headless, fastest pace (the world's
    clock stands still between actions, so the pace changes no result); the coordinator ends
    episodes by the world (someone holds the object, it left the belt) or the step limit, and
    starts the next one at once. Nodes keep the wall clock: the steps carry the simulated
    time, and /clock would cost every node a thousand messages a second. Nothing for RViz
    (viz:=false): no one watches a cell.
    ``spec.extra_args`` (``name:=value``) come last and win."""
    if spec.robot_policy not in ROBOT_POLICIES:
        raise ValueError(f"unknown robot policy {spec.robot_policy!r}; known: "
                         f"{', '.join(ROBOT_POLICIES)}")
    values = {
        "human_model": spec.human_model, "robot_model": spec.robot_model,
        "planner": ROBOT_POLICIES[spec.robot_policy].planner, "seed": spec.seed,
        "mode": "auto", "gui": False, "viz": False, "use_sim_time": False, "real_time_factor": 0,
        "step_delay": 0, "max_steps": spec.step_limit, "on_episode_end": "reset",
        "end_on_goal": False, "read_stdin": False,
        "human_choice": spec.human_choice, "time_per_step": spec.time_per_step,
        "max_trials": spec.max_trials, "reactive_budget": spec.reactive_budget,
        "scenarios": spec.scenarios, "depth": spec.depth, "lambda": spec.lambda_,
        "pomdp_port": ports["pomdp"], "robot_port": ports["robot"], "human_port": ports["human"],
    }
    out = {name: _launch_text(value) for name, value in values.items()}
    for word in spec.extra_args:
        name, sep, value = word.partition(":=")
        if not sep or not name:
            raise ValueError(f"extra launch argument {word!r}: expected name:=value")
        out[name] = value
    return out


def launch_arguments(spec: CellSpec, ports: Mapping[str, int]) -> List[str]:
    """``hrc.launch`` arguments for a cell, as ``name:=value`` words."""
    return [f"{name}:={value}" for name, value in launch_settings(spec, ports).items()]


def check_launch_settings(spec: CellSpec) -> Dict[str, Any]:
    """The cell's launch arguments resolved by ros_hrc.loop.settings (on stand-in ports);
    raises SettingError (one line) for a bad one, before any stack starts."""
    stand_in = {"pomdp": settings.default("pomdp_port"), "robot": settings.default("robot_port"),
                "human": settings.default("human_port")}
    return settings.resolve(launch_settings(spec, stand_in))


def pick_ports() -> Dict[str, int]:
    """Free ports for a cell's master and its three websocket links."""
    return {name: free_port() for name in ("master", "pomdp", "robot", "human")}


def stack_environment(ports: Mapping[str, int], log_dir: Path) -> Dict[str, str]:
    """The environment a cell's processes (roslaunch, and the worker's own node) share: the
    cell's own master, logs under the cell's log folder."""
    return {"ROS_MASTER_URI": f"http://127.0.0.1:{ports['master']}",
            "ROS_LOG_DIR": str(Path(log_dir) / "ros")}


def start_stack(spec: CellSpec, ports: Mapping[str, int], log_dir: Path) -> subprocess.Popen:
    """Start the cell's ``hrc.launch`` (with a roscore on ``ports['master']``) in a session of
    its own, output into ``<log_dir>/<cell>.log``. Stop it with :func:`stop_launched`."""
    log_dir = Path(log_dir)
    log_dir.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    env.update(stack_environment(ports, log_dir))
    cmd = ["roslaunch", "-p", str(ports["master"]), "ros_hrc", "hrc.launch"]
    cmd += launch_arguments(spec, ports)
    with open(log_dir / f"{cell_name(spec)}.log", "wb") as log:
        return subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=log,
                                stderr=subprocess.STDOUT, start_new_session=True, env=env)


def stop_launched(proc: subprocess.Popen, grace: float = 60.0) -> None:
    """Stop a roslaunch (or rosbag) started with ``start_new_session=True`` as Ctrl-C would:
    SIGINT to its whole process group, SIGKILL if it is still there after ``grace`` s."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGINT)
        except ProcessLookupError:
            pass
        try:
            proc.wait(grace)
        except subprocess.TimeoutExpired:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait()


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
    return [sys.executable, "-m", WORKER_MODULE, spec.to_json()]
