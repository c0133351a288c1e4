"""One cell of an experiment grid on a whole stack of its own: what a worker runs, and how it
starts and stops that stack. No ROS here.

A cell is (human model, robot policy, seed). Its worker process (``python -m
ros_hrc.nodes.experiment_cell SPEC_FILE``, see :func:`worker_command`: the spec travels in a
JSON file, never on the command line, whose words the kernel limits to 128 KiB; rospy allows
one node per process) starts ``hrc.launch`` headless, the world's clock as fast as the machine goes, with a
roscore and websocket ports of its own (:func:`pick_ports`: three distinct ports, each free
when picked, so several cells run side by side), watches it (:class:`StackWatch`: a stack
that exits or cannot bind its port fails the cell at once, with the last lines of its log),
drives its episodes, and writes one line per episode on its standard output,
``EPISODE {json}`` (:func:`encode_episode`), as soon as the episode ends. The MDP and the robot
run exactly as in ``roslaunch ros_hrc hrc.launch``: nothing is simulated around them.

Imports point down: the worker (``ros_hrc.nodes.experiment_cell``) imports this module; nothing
in ``ros_hrc.experiment`` imports ``ros_hrc.nodes``.
"""
from __future__ import annotations

import bisect
import dataclasses
import functools
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import (Any, Dict, Iterable, Iterator, List, Mapping, Optional, Sequence, Set, Tuple,
                    Union)

from ros_hrc.errors import HrcError
from ros_hrc.experiment.episode import robot_policy
from ros_hrc.experiment.rows import EpisodeRow, StepRow
from ros_hrc.experiment.sequence_rows import SequenceRow, TaskRow
from ros_hrc.link.transport import DEFAULT_HOST, free_port
from ros_hrc import settings
from ros_hrc.streams import EpisodeSchedule
from ros_hrc.process_tree import processes_naming
from ros_hrc.pomdp.output import write_text_atomically

#: The module a worker process runs (``python -m``).
WORKER_MODULE = "ros_hrc.nodes.experiment_cell"


#: DESPOT's trials per decision in a cell, with no time budget (``time_per_step:=0``), unless
#: the spec gives ``max_trials``: a cell's decisions then depend on its seed alone, not on the
#: machine or its load. About the trials the live 0.1 s budget achieves on this machine where
#: it binds, and its decisions agree with the 0.1 s planner's as often as the 0.1 s planner's
#: agree with themselves (bench/bench_trials.py; docs/performance.md, "Work-bounded planner").
EXPERIMENT_TRIALS = 500

#: Episode numbers are uint32 where they travel (``ros_hrc/Status.episode``, the coordinator's
#: count from 1): a cell records at most this many.
MAX_EPISODES = 2**32 - 1


@dataclass(frozen=True)
class EpisodeRanges:
    """Episode numbers as sorted, disjoint half-open ranges ``[start, stop)``: what a cell
    still has to record, without a list of every number (``--episodes 10**9`` is two
    integers, not a billion)."""
    spans: Tuple[Tuple[int, int], ...] = ()

    @classmethod
    def of(cls, numbers: Union["EpisodeRanges", Iterable[int]]) -> "EpisodeRanges":
        """The ranges of a set of numbers (a list, a ``range``, or ranges already)."""
        if isinstance(numbers, EpisodeRanges):
            return numbers
        if isinstance(numbers, range) and numbers.step == 1:
            return cls(((numbers.start, numbers.stop),) if len(numbers) else ())
        spans: List[List[int]] = []
        for n in sorted(set(numbers)):
            if spans and spans[-1][1] == n:
                spans[-1][1] = n + 1
            else:
                spans.append([n, n + 1])
        return cls(tuple((a, b) for a, b in spans))

    @classmethod
    def missing(cls, count: int, done: Iterable[int]) -> "EpisodeRanges":
        """Episodes ``0 .. count-1`` but those in ``done``; takes memory in proportion to
        ``done``, not to ``count``."""
        spans, start = [], 0
        for n in sorted(d for d in set(done) if 0 <= d < count):
            if n > start:
                spans.append((start, n))
            start = n + 1
        if start < count:
            spans.append((start, count))
        return cls(tuple(spans))

    @classmethod
    def from_json(cls, data: Any) -> "EpisodeRanges":
        """From ``{"spans": [[start, stop], ...]}`` (or a plain list of numbers)."""
        if isinstance(data, dict):
            spans = tuple((int(a), int(b)) for a, b in data["spans"])
            if any(not 0 <= a < b for a, b in spans) or \
                    any(b > c for (_, b), (c, _) in zip(spans, spans[1:])):
                raise ValueError(f"episode ranges must be sorted and disjoint: {spans}")
            return cls(spans)
        return cls.of(int(n) for n in data)

    def __len__(self) -> int:
        return sum(b - a for a, b in self.spans)

    def __iter__(self) -> Iterator[int]:
        for a, b in self.spans:
            yield from range(a, b)

    def __bool__(self) -> bool:
        return bool(self.spans)


def contains(ranges: EpisodeRanges, episode: int) -> bool:
    """Whether ``episode`` is one of ``ranges``' numbers (without listing them)."""
    i = bisect.bisect_right(ranges.spans, (episode, float("inf"))) - 1
    return i >= 0 and ranges.spans[i][0] <= episode < ranges.spans[i][1]


def without(ranges: EpisodeRanges, taken: Set[int]) -> EpisodeRanges:
    """``ranges`` but the numbers in ``taken``: memory in proportion to ``taken``."""
    spans: List[Tuple[int, int]] = []
    for start, stop in ranges.spans:
        rest = EpisodeRanges.missing(stop - start, (n - start for n in taken))
        spans.extend((start + a, start + b) for a, b in rest.spans)
    return EpisodeRanges(tuple(spans))


@dataclass
class CellSpec:
    """What one worker runs. Defaults of the launch settings come from ros_hrc.settings.
    Model files are absolute paths (the entry point resolves what the user typed, once:
    roslaunch starts the processes in another directory)."""
    human_model: str                    # as the grid names it (the results' column)
    robot_policy: str
    seed: int
    episodes: Union[EpisodeRanges, Sequence[int]]   # still to record (resume skips others)
    step_limit: int = 20
    log_dir: str = "."
    robot_model: str = settings.default("robot_model")
    human_choice: str = settings.default("human_choice")
    max_trials: int = settings.default("max_trials")
    reactive_budget: int = settings.default("reactive_budget")
    scenarios: int = settings.default("scenarios")
    depth: int = settings.default("depth")
    lambda_: float = settings.default("lambda")
    extra_args: List[str] = field(default_factory=list)   # more hrc.launch arguments
    episode_timeout: float = 600.0      # wall seconds without a step before giving up
    record_bag: bool = False            # rosbag of /hrc/status next to the logs
    human_model_file: str = ""          # the human model's absolute file ("": human_model)
    # Tasks per sequence (``tasks:=``); 0: no sequences, the cell records episodes. With
    # sequences, ``human_model`` is the schedule's label, ``robot_policy`` the selector and
    # ``episodes`` the sequence numbers still to record (ros_hrc.experiment.sequences).
    sequence: int = 0

    def __post_init__(self) -> None:
        self.episodes = EpisodeRanges.of(self.episodes)

    @property
    def task(self) -> str:
        """The cell's task: its ``task:=`` launch argument (the last wins, as in roslaunch;
        the default task without one)."""
        for word in reversed(self.extra_args):
            if word.startswith("task:="):
                return word[len("task:="):]
        return settings.default("task")

    def to_json(self) -> str:
        return json.dumps(asdict(self))

    @classmethod
    def from_json(cls, text: str) -> "CellSpec":
        data = json.loads(text)
        data["episodes"] = EpisodeRanges.from_json(data["episodes"])
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
    (viz:=false): no one watches a cell. The robot's DESPOT is bounded by work, not time:
    ``spec.max_trials`` (or :data:`EXPERIMENT_TRIALS`) trials per decision and no time budget
    (a cell has no time option), so a cell gives the same rows on any machine and
    under any load. The coordinator plays exactly the spec's episodes, by their numbers
    (``episodes:=``), each on its own streams (:mod:`ros_hrc.streams`).
    With sequences (``spec.sequence``), the robot's selector and library come in
    ``spec.extra_args`` and the stack plays the tasks of the spec's sequences
    (:func:`sequence_task_episodes`).
    ``spec.extra_args`` (``name:=value``) come last and win."""
    if spec.sequence:
        planner = settings.default("planner")     # the selector's policies plan instead
        planner_options = ""
        episodes = sequence_task_episodes(spec)
    else:
        try:
            policy = robot_policy(spec.robot_policy)
        except KeyError as exc:
            raise ValueError(str(exc)) from None
        planner = policy.planner
        planner_options = settings.planner_options_text(policy.options)
        episodes = EpisodeRanges.of(spec.episodes)
    values = {
        "human_model": spec.human_model_file or spec.human_model, "robot_model": spec.robot_model,
        "planner": planner, "seed": spec.seed,
        "mode": "auto", "gui": False, "viz": False, "use_sim_time": False, "real_time_factor": 0,
        "step_delay": 0, "max_steps": spec.step_limit, "on_episode_end": "reset",
        "end_on_goal": False, "read_stdin": False,
        "episodes": EpisodeSchedule(episodes.spans).text() if episodes else "live",
        # The cell subscribes once the master is up; an episode played before that (the
        # short ones last a tenth of a second) would be missed and the cell would fail.
        "wait_for_listener": True,
        "human_choice": spec.human_choice, "time_per_step": 0,
        "max_trials": spec.max_trials or EXPERIMENT_TRIALS,
        "reactive_budget": spec.reactive_budget,
        "scenarios": spec.scenarios, "depth": spec.depth, "lambda": spec.lambda_,
        "pomdp_port": ports["pomdp"], "human_port": ports["human"],
    }
    if planner_options:        # (an empty launch argument would not be the default)
        values["planner_options"] = planner_options
    out = {name: _launch_text(value) for name, value in values.items()}
    for word in spec.extra_args:
        name, sep, value = word.partition(":=")
        if not sep or not name:
            raise ValueError(f"extra launch argument {word!r}: expected name:=value")
        out[name] = value
    return out


def sequence_task_episodes(spec: CellSpec) -> EpisodeRanges:
    """The loop's episodes of a sequence cell's tasks: sequence s's task t is episode
    ``s * L + t - 1`` (:func:`ros_hrc.experiment.sequence_rows.task_episode`)."""
    length = spec.sequence
    return EpisodeRanges(tuple((a * length, b * length)
                               for a, b in EpisodeRanges.of(spec.episodes).spans))


def launch_arguments(spec: CellSpec, ports: Mapping[str, int]) -> List[str]:
    """``hrc.launch`` arguments for a cell, as ``name:=value`` words."""
    return [f"{name}:={value}" for name, value in launch_settings(spec, ports).items()]


def check_launch_settings(spec: CellSpec) -> Dict[str, Any]:
    """The cell's launch arguments resolved by ros_hrc.settings (on stand-in ports);
    raises SettingError (one line) for a bad one, before any stack starts."""
    stand_in = {"pomdp": settings.default("pomdp_port"), "human": settings.default("human_port")}
    return settings.resolve(launch_settings(spec, stand_in))


def stack_key(cell: CellSpec) -> Optional[Tuple[Tuple[str, Any], ...]]:
    """What a cell needs of a stack that a running one cannot take in place (the task, the
    world's settings, the windows: every setting outside :data:`ros_hrc.settings.IN_PLACE`,
    resolved): cells of one key can follow each other on one warm stack. None for a cell
    whose settings do not resolve: any stack takes it, and its worker refuses it with the
    reason (``CELL_REFUSED``) without touching the stack."""
    return _stack_key(dataclasses.replace(cell, episodes=()).to_json())


@functools.lru_cache(maxsize=4096)
def _stack_key(spec_json: str) -> Optional[Tuple[Tuple[str, Any], ...]]:
    try:
        config = check_launch_settings(CellSpec.from_json(spec_json))
    except (HrcError, ValueError):
        return None
    return tuple((name, config[name]) for name in settings.SETTINGS
                 if name not in settings.IN_PLACE)


class StackKeeper:
    """What a lane knows of the one stack it keeps across cells (a local worker's,
    :class:`ros_hrc.experiment.pool.StackWorker`; a cluster actor's,
    :class:`ros_hrc.experiment.cluster.NodeLane`): whether one runs
    (:meth:`stack_running`), its :func:`stack_key` (its first cell's, once that cell is
    over: :meth:`played`), and ``fresh`` (``--fresh-stacks``: a stack per cell)."""

    def __init__(self, fresh: bool = False) -> None:
        self.fresh = fresh
        self.key: Optional[Tuple[Tuple[str, Any], ...]] = None

    def stack_running(self) -> bool:
        raise NotImplementedError

    def takes(self, cell: CellSpec) -> bool:
        """Whether ``cell`` can play next without a new stack (no stack yet: any cell)."""
        if not self.stack_running():
            return True
        key = stack_key(cell)
        # None on either side: a cell refused before it reached a stack (it starts none).
        return not self.fresh and (key is None or self.key is None or key == self.key)

    def warm_for(self, cell: CellSpec) -> bool:
        """Whether a stack runs and can take ``cell`` in place (what the queue prefers)."""
        return self.stack_running() and self.takes(cell)

    def played(self, cell: CellSpec) -> None:
        """``cell`` is over on the running stack: the stack's key is its first cell's."""
        if self.key is None:
            self.key = stack_key(cell)


#: What a cell's stack listens on: its roscore and its two websocket links.
PORT_NAMES = ("master", "pomdp", "human")
#: Tries per port before a cell gives up finding one.
PORT_ATTEMPTS = 50


def port_is_free(port: int, host: str = DEFAULT_HOST) -> bool:
    """Whether a server could bind ``host:port`` now."""
    with socket.socket() as s:
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


def pick_ports() -> Dict[str, int]:
    """Ports for a cell's master and its two websocket links: all three distinct (the
    kernel may hand the same free port out twice in a row) and each free when picked.
    Another process may still take one before the stack binds it: :class:`StackWatch` then
    fails the attempt at once, and the cell runs again on fresh ports. Raises CellFailed
    when no free port turns up."""
    ports: Dict[str, int] = {}
    for name in PORT_NAMES:
        for _ in range(PORT_ATTEMPTS):
            port = free_port()
            if port not in ports.values() and port_is_free(port):
                ports[name] = port
                break
        else:
            raise CellFailed(f"no free port for the {name} after {PORT_ATTEMPTS} tries")
    return ports


def stack_environment(spec: CellSpec, ports: Mapping[str, int],
                      log_dir: Path) -> Dict[str, str]:
    """The environment a cell's processes (roslaunch, and the worker's own node) share: the
    cell's own master, ROS's logs in a folder of the cell's own (:func:`ros_log_dir`)."""
    return {"ROS_MASTER_URI": f"http://127.0.0.1:{ports['master']}",
            "ROS_LOG_DIR": str(ros_log_dir(spec, log_dir))}


def ros_log_dir(spec: CellSpec, log_dir: Path) -> Path:
    """Where a cell's ROS processes log (``<log_dir>/ros/<cell>``): each of them names it in
    its ``__log:=`` argument, which tells a cell's processes from another's."""
    return Path(log_dir) / "ros" / cell_name(spec)


def stack_log(spec: CellSpec, log_dir: Path) -> Path:
    """Where a cell's ``hrc.launch`` writes its output."""
    return Path(log_dir) / f"{cell_name(spec)}.log"


def start_stack(spec: CellSpec, ports: Mapping[str, int], log_dir: Path) -> subprocess.Popen:
    """Start the cell's ``hrc.launch`` (with a roscore on ``ports['master']``) in a session of
    its own, output into :func:`stack_log`. Stop it with :func:`stop_stack`."""
    log_dir = Path(log_dir)
    log_dir.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    env.update(stack_environment(spec, ports, log_dir))
    cmd = ["roslaunch", "-p", str(ports["master"]), "ros_hrc", "hrc.launch"]
    cmd += launch_arguments(spec, ports)
    with open(stack_log(spec, log_dir), "wb") as log:
        return subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=log,
                                stderr=subprocess.STDOUT, start_new_session=True, env=env)


#: Lines of a stack's log that mean it cannot run: a link's server could not bind its port
#: (ros_hrc.link.transport's LinkError; the node would respawn into the same error forever).
FATAL_LOG_MARKERS = ("cannot listen on", "Address already in use")
#: How much of a log's end :func:`log_tail` reads.
TAIL_BYTES = 16384
_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


def log_tail(path: Path, lines: int = 5) -> List[str]:
    """The last ``lines`` non-blank lines of a log (colour codes removed); [] if unreadable."""
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            f.seek(max(0, f.tell() - TAIL_BYTES))
            text = f.read().decode("utf-8", "replace")
    except OSError:
        return []
    kept = [_ANSI.sub("", line).strip() for line in text.splitlines()]
    return [line for line in kept if line][-lines:]


class StackWatch:
    """Watches a cell's ``hrc.launch`` while the worker waits on it: :meth:`check` raises
    CellFailed at once, with the reason, when roslaunch has exited (with the last lines of
    its log) or its log shows a port that cannot be bound."""

    def __init__(self, proc: subprocess.Popen, log_path: Path, name: str) -> None:
        self.proc = proc
        self.log_path = Path(log_path)
        self.name = name
        self._offset = 0
        self._partial = b""

    def _tail_text(self) -> str:
        tail = log_tail(self.log_path)
        return f"; last lines of {self.log_path}: " + " | ".join(tail) if tail else \
            f"; {self.log_path} is empty"

    def check(self) -> None:
        """Raise CellFailed if the stack cannot go on; otherwise return at once."""
        code = self.proc.poll()
        if code is not None:
            raise CellFailed(f"hrc.launch exited ({code}){self._tail_text()}")
        line = self._fatal_line()
        if line is not None:
            raise CellFailed(f"{line} (see {self.log_path})")

    def _fatal_line(self) -> Optional[str]:
        """The first new log line with a :data:`FATAL_LOG_MARKERS` marker, if any."""
        try:
            with open(self.log_path, "rb") as f:
                f.seek(self._offset)
                data = f.read(1 << 20)
        except OSError:
            return None
        self._offset += len(data)
        data = self._partial + data
        complete, _, self._partial = data.rpartition(b"\n")
        for raw in complete.split(b"\n"):
            line = _ANSI.sub("", raw.decode("utf-8", "replace")).strip()
            if any(marker in line for marker in FATAL_LOG_MARKERS):
                return line
        return None


def stop_launched(proc: subprocess.Popen, grace: float = 60.0) -> None:
    """Stop a roslaunch (or rosbag) started with ``start_new_session=True`` as Ctrl-C would:
    SIGINT to its whole process group, SIGKILL if it is still there after ``grace`` s. A
    roslaunch its world's guard froze (SIGSTOP) is woken to take the SIGINT."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGINT)
            os.killpg(proc.pid, signal.SIGCONT)
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


#: Seconds the processes left of a stack get to end on SIGTERM before SIGKILL.
LEFTOVER_GRACE = 10.0


def stop_stack(proc: subprocess.Popen, spec: CellSpec, log_dir: Path,
               grace: float = 60.0) -> List[int]:
    """Stop a cell's ``hrc.launch`` (:func:`stop_launched`), then what is left of it: roslaunch
    runs each node in a session of its own, so a roslaunch that died without stopping them
    (SIGKILL, the OOM killer) leaves its master and nodes running, and stepping. Those
    (found by their ``__log:=`` in :func:`ros_log_dir`) get SIGTERM, then SIGKILL after
    :data:`LEFTOVER_GRACE` s. Returns the pids of the leftovers."""
    stop_launched(proc, grace)
    marker = f"__log:={ros_log_dir(spec, log_dir)}/"
    leftovers = left = processes_naming(marker)
    for signum in (signal.SIGTERM, signal.SIGKILL):
        for pid in left:
            try:
                os.kill(pid, signum)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + LEFTOVER_GRACE
        while left and time.monotonic() < deadline:
            time.sleep(0.1)
            left = processes_naming(marker)
    return leftovers


#: Prefix of a worker's stdout line carrying a finished episode.
EPISODE_LINE = "EPISODE "


def encode_episode(row: EpisodeRow, steps: list) -> str:
    return EPISODE_LINE + json.dumps({"episode": row.as_dict(),
                                      "steps": [s.as_dict() for s in steps]})


#: Prefix of a sequence cell's stdout line carrying a whole sequence (its tasks).
SEQUENCE_LINE = "SEQUENCE "


def encode_sequence(row: SequenceRow, tasks: Sequence[TaskRow]) -> str:
    return SEQUENCE_LINE + json.dumps({"sequence": row.as_dict(),
                                       "tasks": [t.as_dict() for t in tasks]})


#: Prefix of a worker's line saying that a cell is over: every one of its episodes (or
#: sequences) was written; its stack goes on to the next cell.
CELL_OVER_LINE = "CELL_OVER "
#: Prefix of a worker's line saying that a cell's settings were refused before they reached
#: the stack (a bad model): the cell fails with the reason; the stack is as it was.
CELL_REFUSED_LINE = "CELL_REFUSED "


def encode_cell_over(spec: CellSpec, delivered: int) -> str:
    return CELL_OVER_LINE + json.dumps({"cell": cell_name(spec), "delivered": delivered})


def encode_cell_refused(spec: CellSpec, reason: str) -> str:
    return CELL_REFUSED_LINE + json.dumps({"cell": cell_name(spec), "reason": reason})


def decode_cell_end(line: str) -> Optional[Tuple[bool, Dict[str, Any]]]:
    """(True, what it says) for a cell-over line, (False, ...) for a refusal, None for any
    other line."""
    for prefix, over in ((CELL_OVER_LINE, True), (CELL_REFUSED_LINE, False)):
        if line.startswith(prefix):
            return over, json.loads(line[len(prefix):])
    return None


#: The prefixes of the lines that carry a cell's results (:func:`decode_episode` reads them)
#: and its end.
RESULT_LINES = (EPISODE_LINE, SEQUENCE_LINE, CELL_OVER_LINE, CELL_REFUSED_LINE)


def decode_episode(line: str):
    """(EpisodeRow, [StepRow]) from a worker's episode line, (SequenceRow, [TaskRow]) from a
    sequence cell's line, or None for any other line."""
    if line.startswith(SEQUENCE_LINE):
        data = json.loads(line[len(SEQUENCE_LINE):])
        return (SequenceRow.from_dict(data["sequence"]),
                [TaskRow.from_dict(t) for t in data["tasks"]])
    if not line.startswith(EPISODE_LINE):
        return None
    data = json.loads(line[len(EPISODE_LINE):])
    return (EpisodeRow.from_dict(data["episode"]),
            [StepRow.from_dict(s) for s in data["steps"]])


def write_spec(spec: CellSpec, log_dir: Path) -> Path:
    """Write the cell's spec to ``<log_dir>/<cell>.spec.json`` (whole or not at all); its path."""
    path = Path(log_dir) / f"{cell_name(spec)}.spec.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomically(path, spec.to_json() + "\n")
    return path


def read_spec(path: Union[str, Path]) -> CellSpec:
    """The spec :func:`write_spec` wrote."""
    return CellSpec.from_json(Path(path).read_text(encoding="utf-8"))


def worker_command(spec_file: Union[str, Path, None] = None) -> List[str]:
    """The command that runs the cell whose spec is in ``spec_file`` (:func:`write_spec`) in
    a process of its own, on a stack of its own: a file, because a spec can be larger than a
    command line may be. Without ``spec_file``: a worker that owns one stack and plays the
    cells whose spec files it reads on its standard input, one per line, each handed to the
    stack the one before played on (a warm stack)."""
    return [sys.executable, "-m", WORKER_MODULE,
            "--serve" if spec_file is None else str(spec_file)]
