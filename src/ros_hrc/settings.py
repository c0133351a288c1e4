"""One source of defaults and checks for every launch argument (no ROS, no sockets).

``hrc.launch`` (through ``hrc_check``), the command-line programs, the nodes and
``hrc_experiment`` read their defaults from :data:`SETTINGS` and check values with
:func:`parse`, so a value means the same thing, and is refused the same way, whichever entry
point it comes through. The table is the only place a default is written: hrc.launch's and
world.launch's ``<arg>`` lines and the reference ``docs/settings.md`` are written from it
(``python tools/make_settings_files.py``; a unit test fails when either differs), and a module
whose parameter is a setting takes its default with :func:`default`.

A refused value raises :class:`SettingError`, whose text is one line naming the argument, the
value and what is wrong::

    pomdp_port:=70000: must be an integer from 1 to 65535
    human_port:=abc: must be an integer from 1 to 65535, got 'abc'

    parse(name, value)              -> the typed value ("" or None: the default)
    default(name)                   -> the default
    resolve({name: value, ...})     -> every setting, checked together (ports distinct, ...)
    add_argument(parser, name, ...) -> an argparse option with the table's type, default, help
    use_as_defaults(parser, config) -> resolved settings as the defaults of those options

Paths: a model path, ``policy_file`` and ``snapshot_dir`` are made absolute against the
directory of the command that parses them (:func:`ros_hrc.model_files.user_path`), so the entry
point that the user ran resolves them once and only absolute paths travel on to processes that
run elsewhere. Scenario names (``tired``) stay names.

Numbers: an integer setting is at most :data:`INT32_MAX`, the largest integer the ROS parameter
server (XML-RPC) carries, since every setting is on it (``/hrc/config``) and several are node
parameters; each other bound is what the setting's consumer takes.
"""
from __future__ import annotations

import ipaddress
import json
import math
import os
import re
import tomllib
from dataclasses import dataclass, replace
from typing import Any, Dict, FrozenSet, List, Mapping, Optional, Tuple

from ros_hrc import registry, tasks
from ros_hrc.tasks import fabric_reactive
from ros_hrc.tasks.schedule import MAX_TASKS, ScheduleError, parse_schedule
from ros_hrc.errors import HrcError, did_you_mean
from ros_hrc.pomdp import despot_parameters
from ros_hrc.streams import LIVE, MAX_SEED, EpisodeSchedule
from ros_hrc.model_files import MODELS_DIR, model_names, names_a_file, ros_home, user_path

__all__ = ["Setting", "SettingError", "SETTINGS", "PORTS", "parse", "default", "resolve",
           "add_argument", "use_as_defaults", "TRUE_WORDS", "FALSE_WORDS", "AUTO_WORD",
           "NO_FILE_WORD", "INT32_MAX", "WORLD_SETTINGS"]

TRUE_WORDS = ("true", "1", "yes", "on")
FALSE_WORDS = ("false", "0", "no", "off")
#: What an automatic setting (default None) is given to leave the choice to :func:`resolve`
#: (the launch files' default, so that ``roslaunch --ros-args`` lists it as optional).
AUTO_WORD = "auto"
#: A file setting's "no file" (the launch files' default for ``policy_file``; a file of that
#: name is given as ``./none``).
NO_FILE_WORD = "none"
#: The largest integer any setting may take: the ROS parameter server's ints are XML-RPC's
#: 32-bit ones, and roslaunch fails with a traceback on a larger one.
INT32_MAX = 2**31 - 1

#: The snapshots' folder in $ROS_HOME when ``snapshot_dir`` is empty.
SNAPSHOT_FOLDER = "hrc_snapshots"

#: Setting kinds: how a value is read.
KINDS = ("str", "model", "int", "float", "bool", "choice", "host", "file", "dir", "episodes",
         "registered")


class SettingError(HrcError):
    """A setting's value is refused. ``str()`` is one line: ``name:=value: what is wrong``."""

    def __init__(self, name: str, value: Any, requirement: str, unparsable: bool = False) -> None:
        self.name = name
        self.value = value
        self.requirement = requirement     # e.g. "must be an integer >= 0"
        self.unparsable = unparsable       # the text was not even of the right type
        shown = _shown(value)
        what = f"{requirement}, got {shown!r}" if unparsable else requirement
        self.what = what
        super().__init__(f"{name}:={shown}: {what}")


def _shown(value: Any) -> str:
    """A value as the user would have typed it, on one line."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return " ".join(str(value).split()) if "\n" in str(value) else str(value)


def _number(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else f"{x:g}"


@dataclass(frozen=True)
class Setting:
    """One launch argument: its kind, default, doc and the values it accepts.

    ``default`` None on a bool means "automatic": :func:`resolve` derives it (the doc says how).
    """

    name: str
    kind: str
    default: Any
    doc: str
    minimum: Optional[float] = None
    maximum: Optional[float] = None
    choices: Optional[Tuple[str, ...]] = None
    exclusive_minimum: bool = False    # value > minimum rather than >=
    unit: str = ""
    smallest_nonzero: Optional[float] = None   # 0, or at least this (a float's off switch)
    #: The heading it is listed under (hrc.launch's comments, docs/settings.md).
    group: str = ""
    #: hrc.launch's default when it is a roslaunch expression (``$(optenv ...)``,
    #: ``$(eval ...)``) rather than a word :meth:`parse` reads as ``default``.
    launch_expression: Optional[str] = None
    #: An argument of hrc.launch (False: of world.launch alone).
    in_hrc_launch: bool = True
    #: world.launch's doc, where the table's speaks of what the world alone does not run
    #: (None: the table's).
    world_doc: Optional[str] = None
    #: world.launch's default, where the world alone takes another than hrc.launch (None: the
    #: table's). pause_when_idle: the world alone runs freely; hrc.launch's auto decides by
    #: real_time_factor and mode.
    world_default: Optional[str] = None
    #: A ``registered`` setting's entry-point group (:mod:`ros_hrc.registry`): its values
    #: are the names found there at run time, or ``module:Class``.
    registry: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"setting {self.name}: unknown kind {self.kind!r}")
        if self.kind == "choice" and not self.choices:
            raise ValueError(f"setting {self.name}: a choice needs choices")
        if (self.kind == "registered") != bool(self.registry):
            raise ValueError(f"setting {self.name}: a registered setting, and only one, "
                             "names its registry")

    @property
    def flag(self) -> str:
        """The command-line option of the same name: ``--time-per-step``."""
        return "--" + self.name.replace("_", "-")

    @property
    def launch_default(self) -> str:
        """The default as a launch file writes it: the table's expression, or the word
        :meth:`parse` reads as the default (``auto`` for an automatic setting, and for a model:
        :func:`resolve` gives the task's; ``none`` for no file; ``true``/``false``)."""
        if self.launch_expression is not None:
            return self.launch_expression
        if self.default is None or self.kind == "model" or (self.kind == "str"
                                                             and self.default == ""):
            return AUTO_WORD     # (an empty default would be a required argument to roslaunch)
        if self.kind == "file" and self.default == "":
            return NO_FILE_WORD
        return _shown(self.default)

    def accepted(self) -> str:
        """The values it takes, e.g. ``an integer from 1 to 65535`` (what :meth:`requirement`
        says a value must be), with the words for "the default" where they differ from it."""
        if self.kind == "model":
            text = "a scenario name or a model file"
        else:
            text = self.requirement()[len("must be "):]
        if self.default is None or self.kind == "model":
            text += f", or {AUTO_WORD}"
        elif self.kind == "file":
            text += f", or {NO_FILE_WORD}"
        return text

    def requirement(self) -> str:
        """What a value must be, as the second half of an error line."""
        unit = f" ({self.unit})" if self.unit else ""
        if self.kind in ("int", "float"):
            noun = "an integer" if self.kind == "int" else "a number"
            lo, hi = self.minimum, self.maximum
            if self.smallest_nonzero is not None:
                noun, lo = f"0 or {noun}", self.smallest_nonzero
            if lo is not None and hi is not None and not self.exclusive_minimum:
                return f"must be {noun} from {_number(lo)} to {_number(hi)}{unit}"
            parts = []
            if lo is not None:
                parts.append(f"{'>' if self.exclusive_minimum else '>='} {_number(lo)}")
            if hi is not None:
                parts.append(f"<= {_number(hi)}")
            return f"must be {noun}{' ' + ' and '.join(parts) if parts else ''}{unit}"
        if self.kind == "bool":
            return "must be true or false (also 1/0, yes/no, on/off)"
        if self.kind == "choice":
            return f"must be one of {', '.join(self.choices or ())}"
        if self.kind == "registered":
            # Ours: what any machine has (docs written from it stay true); an installed
            # package's are listed by the refusal itself (registry.check_name).
            what = registry.WHAT[self.registry]
            return (f"must be a {what} of ours ({', '.join(registry.BUILT_IN[self.registry])}),"
                    f" an installed package's (docs/extending.md) or module:Class")
        if self.kind == "host":
            return "must be an IPv4 or IPv6 address or a host name"
        if self.kind == "model":
            return "must name a model (a scenario name or a model file)"
        if self.kind == "file":
            return "must be a readable file"
        if self.kind == "dir":
            return "must be a directory (made if missing)"
        if self.kind == "episodes":
            return "must be live or episode numbers and ranges, e.g. 2,5-7"
        return "must be a string"

    def parse(self, value: Any) -> Any:
        """The typed value of ``value``; ``""`` or None give the default. Raises SettingError."""
        if value is None or (isinstance(value, str) and value.strip() == ""):
            return self.default
        parse = getattr(self, "_parse_" + self.kind)
        return parse(value)

    # -- one parser per kind --------------------------------------------------------------------
    def _refuse(self, value: Any, unparsable: bool = False) -> SettingError:
        return SettingError(self.name, value, self.requirement(), unparsable)

    def _in_range(self, value: Any, number: float) -> None:
        if self.smallest_nonzero is not None and 0 < number < self.smallest_nonzero:
            raise self._refuse(value)
        if self.minimum is not None:
            if number < self.minimum or (self.exclusive_minimum and number == self.minimum):
                raise self._refuse(value)
        if self.maximum is not None and number > self.maximum:
            raise self._refuse(value)

    def _parse_int(self, value: Any) -> Optional[int]:
        if isinstance(value, str) and value.strip().lower() == AUTO_WORD and self.default is None:
            return None      # automatic: resolve() derives it
        if isinstance(value, bool) or not isinstance(value, (int, str)):
            raise self._refuse(value, unparsable=True)
        if isinstance(value, str):
            text = value.strip()
            if not re.fullmatch(r"[+-]?[0-9]+", text):
                raise self._refuse(value, unparsable=True)
            number = int(text)
        else:
            number = int(value)
        self._in_range(value, number)
        return number

    def _parse_float(self, value: Any) -> Optional[float]:
        if isinstance(value, str) and value.strip().lower() == AUTO_WORD and self.default is None:
            return None      # automatic: resolve() derives it
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise self._refuse(value, unparsable=True)
        try:
            number = float(value.strip() if isinstance(value, str) else value)
        except ValueError:
            raise self._refuse(value, unparsable=True) from None
        if not math.isfinite(number):
            raise self._refuse(value, unparsable=True)
        self._in_range(value, number)
        return number

    def _parse_bool(self, value: Any) -> Optional[bool]:
        if isinstance(value, bool):
            return value
        if isinstance(value, int) and value in (0, 1):
            return bool(value)
        if isinstance(value, str):
            word = value.strip().lower()
            if word == AUTO_WORD and self.default is None:
                return None
            if word in TRUE_WORDS:
                return True
            if word in FALSE_WORDS:
                return False
        raise self._refuse(value, unparsable=True)

    def _parse_choice(self, value: Any) -> str:
        text = str(value).strip()
        if text not in (self.choices or ()):
            raise self._refuse(value)
        return text

    def _parse_registered(self, value: Any) -> str:
        """A name the registry knows now, or ``module:Class`` (imported by whoever builds it:
        :func:`ros_hrc.registry.load`)."""
        if not isinstance(value, str):
            raise self._refuse(value, unparsable=True)
        try:
            return registry.check_name(self.registry, value)
        except registry.RegistryError as exc:
            raise SettingError(self.name, value, str(exc)) from None

    def _parse_episodes(self, value: Any) -> str:
        try:
            schedule = EpisodeSchedule.parse(str(value))
        except ValueError:
            raise self._refuse(value, unparsable=True) from None
        return schedule.text() if schedule is not None else LIVE

    def _parse_str(self, value: Any) -> str:
        if not isinstance(value, str):
            raise self._refuse(value, unparsable=True)
        if value.strip() == AUTO_WORD and self.default == "":
            return self.default      # the launch file's word for "none given"
        return value.strip()

    def _parse_model(self, value: Any) -> str:
        """A scenario name as it is; a path made absolute (:func:`user_path`); ``auto``: the
        default task's model (:func:`resolve` gives the chosen task's)."""
        if not isinstance(value, str) or any(c in value for c in "\n\r\0"):
            raise self._refuse(value)
        text = value.strip()
        if text == AUTO_WORD:
            return self.default
        return str(user_path(text)) if names_a_file(text) else text

    def _parse_host(self, value: Any) -> str:
        text = str(value).strip()
        if not _valid_host(text):
            raise self._refuse(value)
        return text

    def _parse_file(self, value: Any) -> str:
        """An absolute path (:func:`user_path`) to a readable file; ``none``: no file."""
        if not isinstance(value, str) or any(c in value for c in "\n\r\0"):
            raise self._refuse(value)
        if value.strip() == NO_FILE_WORD:
            return self.default
        path = str(user_path(value.strip()))
        if not os.path.isfile(path) or not os.access(path, os.R_OK):
            raise SettingError(self.name, value, f"no readable file there (looked for {path})")
        return path

    def _parse_dir(self, value: Any) -> str:
        """An absolute path (:func:`user_path`) that is a directory or not there yet."""
        if not isinstance(value, str) or any(c in value for c in "\n\r\0"):
            raise self._refuse(value)
        path = str(user_path(value.strip()))
        if os.path.exists(path) and not os.path.isdir(path):
            raise SettingError(self.name, value, f"{path} is not a directory")
        return path


_HOST_LABEL = re.compile(r"(?!-)[A-Za-z0-9-]{1,63}(?<!-)\Z")


def _valid_host(text: str) -> bool:
    """An IPv4 or IPv6 literal (``[::1]`` too), or a host name (RFC 1123, not all-numeric)."""
    literal = text[1:-1] if text.startswith("[") and text.endswith("]") else text
    try:
        ipaddress.ip_address(literal)
        return True
    except ValueError:
        pass
    name = text[:-1] if text.endswith(".") else text
    if not name or len(name) > 253:
        return False
    labels = name.split(".")
    if not all(_HOST_LABEL.match(label) for label in labels):
        return False
    return not labels[-1].isdigit()    # 999.1.1.1 is a bad address, not a name


def _s(name: str, kind: str, default: Any, doc: str, **more: Any) -> Setting:
    return Setting(name, kind, default, doc, **more)


def _despot(name: str) -> Setting:
    """The setting of DESPOT's parameter ``name``: its definition's kind, default, doc and
    limits (ros_hrc.pomdp.despot_parameters)."""
    fields = despot_parameters.setting_fields(name)
    return _s(name, fields.pop("kind"), fields.pop("default"), fields.pop("doc"), **fields)


def _port(name: str, default: int, doc: str) -> Setting:
    return _s(name, "int", default, doc, minimum=1, maximum=65535)


def _group(heading: str, *members: Setting) -> Tuple[Setting, ...]:
    """``members`` listed under ``heading`` (hrc.launch's comments, docs/settings.md)."""
    return tuple(replace(member, group=heading) for member in members)


def _model_doc(kind: str, noun: str, suffixes: str) -> str:
    """The doc of a model setting: the names each task's model folder ships (read from the
    folders, so ``--ros-args`` and docs/settings.md list what is there) and its default."""
    shipped = []
    for name in tasks.TASK_NAMES:
        folder = tasks.get(name).model_dirs[kind]
        shown = folder.relative_to(MODELS_DIR.parent).as_posix()
        shipped.append(f"{name}, in {shown}/: {', '.join(model_names(folder))}")
    defaults = ", ".join(f"{name}: {tasks.get(name).default_model(kind)}"
                         for name in tasks.TASK_NAMES)
    return (f"{noun} by name, one of the task's ({'; '.join(shipped)}), or a {suffixes} "
            f"path; auto (or empty): the task's default ({defaults})")


#: The only place a default is written: hrc.launch's and world.launch's ``<arg>`` lines and
#: docs/settings.md are made from it (tools/make_settings_files.py; a unit test fails when they differ), and the
#: programs, nodes and modules that need a default ask :func:`default`.
_TABLE: Tuple[Setting, ...] = (
    *_group(
        "what runs",
        _s("human_model", "model", "humanModel", _model_doc("human", "human scenario",
                                                             ".pomdpx")),
        _s("robot_model", "model", "robot", _model_doc("robot", "robot POMDP",
                                                       ".pomdp/.pomdpx")),
        _s("task", "choice", tasks.DEFAULT_TASK, "the collaboration task (docs/tasks.md): seed "
           "(the manual's) or fabric (the seed authors' successor: a human who reacts to the "
           "robot)", choices=tasks.TASK_NAMES),
        _s("mode", "choice", "auto", "auto: the MDP picks the human's next state; manual: you "
           "type it (or call /hrc/set_human_state)", choices=("auto", "manual"),
           world_doc="the loop's mode, as hrc.launch passes it: manual makes "
                     "pause_when_idle:=auto freeze the world while someone types a state"),
        _s("gui", "bool", False, "open PyBullet's window (true) or run headless (false)"),
        _s("seed", "int", 0, "random seed of the world and both solvers: same seed, same run",
           minimum=0, maximum=MAX_SEED,
           world_doc="random seed of the world: same seed and same calls, same run"),
        _s("use_sim_time", "bool", False,
           "the world publishes /clock and every node runs on simulated time"),
        # (a factor below 0.001 would have the world sleep longer than a clock can count)
        _s("real_time_factor", "float", 1.0,
           "simulated seconds per wall second; 0 = as fast as possible", minimum=0, maximum=1000,
           smallest_nonzero=0.001),
        _s("pause_when_idle", "bool", None, "freeze simulated time between actions; auto (or "
           "empty): true when real_time_factor is 0 (the run then depends only on the seed) or "
           "in manual mode (the world waits while you type a state)", world_default="false",
           world_doc="freeze simulated time while no action runs, so a run depends only on the "
           "calls made (auto: when real_time_factor is 0 or mode is manual, as hrc.launch "
           "passes it; the world alone runs freely)"),
        _s("belt_speed", "float", 0.02, "conveyor belt speed", minimum=0, maximum=0.5,
           unit="m/s"),
        _s("away_time", "float", None, "how long a walk away lasts when the human is "
           "already away: he stays away and the belt runs on; auto: the task's (seed 0, no "
           "time, its study's world; fabric 0.8, as long as an idle, so that a human waiting "
           "in recovery lets the object reach the belt's end)", minimum=0, maximum=60,
           unit="s"),
    ),
    *_group(
        "watching it: RViz and the camera",
        _s("viz", "bool", True, "publish what RViz shows: each agent's description and joint "
           "states, /tf (robot_state_publisher per agent) and the step's markers"),
        _s("rviz", "bool", False,
           "start RViz with launch/hrc.rviz (needs a display; implies viz)"),
        _s("snapshot_dir", "dir", "", "where /hrc/world/snapshot writes its PNGs (empty: "
           f"$ROS_HOME/{SNAPSHOT_FOLDER}); names are unique per run",
           launch_expression=f"$(optenv ROS_HOME ~/.ros)/{SNAPSHOT_FOLDER}"),
        _s("camera_rate", "float", 0.0, "rate of /hrc/camera/image, the snapshot renderer's "
           "view (0: off)", minimum=0, maximum=30, unit="Hz"),
        _s("publish_rate", "float", 10.0, "rate of /hrc/world_state while anyone subscribes "
           "(wall clock)", minimum=0, maximum=1000, exclusive_minimum=True, unit="Hz",
           in_hrc_launch=False),
    ),
    *_group(
        "links (DESIGN §2): the websocket servers and their clients",
        _s("host", "host", "127.0.0.1",
           "address the websocket servers bind and the clients connect to"),
        _port("pomdp_port", 7070, "POMDP process's server, for the observations of hrc_human "
              "(the coordinator)"),
        _port("human_port", 9090, "hrc_human's server, for the steps of the MDP process"),
        _s("link_read_timeout", "float", 5.0, "how long a websocket server keeps a client "
           "whose outbox has not moved (it reads nothing it is sent) before it disconnects it; "
           "a client that reads, however slowly, stays (docs/protocol.md)", minimum=0,
           maximum=3600, exclusive_minimum=True, unit="s"),
    ),
    *_group(
        "the human (MDP) and the episodes",
        _s("start_mdp", "bool", True,
           "start the MDP process; false to run 'rosrun ros_hrc despot_mdp' by hand"),
        # roslaunch needs a word for it (the xterm, the MDP's stdin), before hrc_check runs.
        _s("mdp_xterm", "bool", None, "give the MDP process its own xterm (by default: in "
           "manual mode when a display exists)",
           launch_expression="$(eval 'true' if arg('mode') == 'manual' and "
                             "optenv('DISPLAY', '') else 'false')"),
        _s("human_choice", "choice", "optimal", "how the human picks actions: optimal, softmax "
           "or random", choices=("optimal", "softmax", "random")),
        _s("temperature", "float", 1.0, "softmax temperature of human_choice:=softmax",
           minimum=0, exclusive_minimum=True),
        _s("manual_share", "float", 0.8, "belief share of a manually entered state", minimum=0,
           maximum=1, exclusive_minimum=True),
        _s("step_delay", "float", 1.0, "pause between steps in auto mode", minimum=0,
           maximum=3600, unit="s"),
        _s("max_steps", "int", 0, "end an episode after this many steps (0: no limit)",
           minimum=0, maximum=INT32_MAX),
        _s("on_episode_end", "choice", "wait", "wait (for Enter or /hrc/reset), reset (start a "
           "new episode) or continue", choices=("wait", "reset", "continue")),
        _s("end_on_goal", "bool", True, "also end an episode when the human MDP reaches its "
           "goal state success, as the seed does; it always ends when someone holds the object "
           "or the object left the belt"),
        _s("episodes", "episodes", LIVE, "live: episodes 1, 2, 3 ..., each reset the next; or "
           "the episode numbers to play, in order, e.g. 0-99 or 2,5-7 (experiments: each names "
           "its random streams, so (seed, episode) is the same episode whatever ran before it; "
           "an episode cut short is played again; after the last the loop waits)"),
        _s("wait_for_listener", "bool", False, "take no step before someone subscribes to "
           "/hrc/status (an experiment cell, which must see every step of every episode it "
           "records)"),
    ),
    *_group(
        "the robot (POMDP)",
        _s("start_pomdp", "bool", True, "start the POMDP process"),
        _s("planner", "registered", "despot", "despot; policy with policy_file; reactive "
           "(baseline: the task's reactive robot, rules on the current observation: seed's see "
           "reactive_budget, fabric's reactive MDP see reactive_wait); none (baseline: the "
           "robot never acts); explore (a uniformly random action each step, seeded: hrc_fit's "
           "exploring robot); or a planner of an installed package (its entry point in "
           "ros_hrc.planners) or module:Class (docs/extending.md)",
           registry=registry.PLANNERS),
        _s("planner_options", "str", "", "the planner's own options (its class's options: "
           "docs/extending.md), NAME=VALUE pairs, comma-separated, each VALUE as TOML writes "
           "it (0.2, 3, true, \"text\"); auto (or empty): its defaults"),
        _s("policy_file", "file", "",
           "offline policy for planner:=policy (hrc_pomdp solve -o FILE); only with that "
           "planner (none: no file)"),
        # DESPOT's: defined once, with their limits, in ros_hrc.pomdp.despot_parameters.
        *(_despot(name) for name in despot_parameters.SETTING_NAMES),
        _s("reactive_budget", "int", 8, "planner:=reactive of task seed helps after this many "
           "steps since the reset without the human getting the object (0: never for that "
           "reason)", minimum=0, maximum=INT32_MAX),
        # The task's own figure: its reactive robot's rules are data of the task.
        _s("reactive_wait", "float", fabric_reactive.DEFAULT_WAIT, "planner:=reactive of task "
           "fabric declares that the human needs help (and grasps) once this many simulated "
           "seconds have passed since the episode's reset without success: the authors' "
           f"{_number(fabric_reactive.DEFAULT_WAIT)} s (0: never for that reason)",
           minimum=0, maximum=1e6, unit="s"),
    ),
    *_group(
        "sequences: tasks, the policy library and its selector (docs/sequences.md)",
        _s("tasks", "int", None, "play a sequence of this many tasks with one robot whose "
           "selector keeps what it learnt (the world reset between tasks, each ending by "
           "success, failure or timeout; /hrc/task_status per task); auto (or empty): no "
           "sequence, episodes as on_episode_end says", minimum=1, maximum=MAX_TASKS),
        _s("schedule", "str", "", "which human plays which task of the sequence: auto (or "
           "empty): human_model every task; TYPE*K,TYPE2*K2,... (K tasks each, in order, repeated; "
           "TYPE>TYPE2*K drifts from TYPE to TYPE2 over the block); fabric (FABRIC's 10 humans "
           "x 30 tasks); or a .toml file of [[block]] tables (human, tasks, drift_to)"),
        _s("selector", "str", "fixed", "how the robot chooses its policy before each task: "
           "fixed (robot_model and planner, as without a sequence), fixed:POLICY (one policy "
           "of the library), random, bpr (BPR-EI), bpr-pi (BPR-PI), bpr-fabric (FABRIC's "
           "BPR), bandit or oracle (told the true type); docs/selectors.md; or the robot "
           "that learns its human (robot_model its prior): pomdp_learning (root sampling), "
           "pomdp_learning_mean (the posterior mean); docs/learning.md; or a selector of an "
           "installed package (its entry point in ros_hrc.selectors) or module:Class "
           "(docs/extending.md)"),
        _s("library", "str", AUTO_WORD, "the policy library the selector chooses from: a "
           "manifest (library.toml) or a folder holding one; auto: the task's "
           "(models/fabric/library.toml, models/robot/library.toml)"),
        _s("selector_model", "str", AUTO_WORD, "the selector's model (make train-selector "
           "writes it): a JSON file; auto: the task's (models/fabric/selector_model.json, "
           "models/robot/selector_model.json) if it exists; the BPR selectors and the oracle "
           "need one"),
        _s("task_timeout", "float", None, "a task of a sequence still running after this "
           "many simulated seconds since its start ends with outcome timeout; auto: the "
           "task's (80 s, FABRIC's forced reset)", minimum=0, maximum=1e6,
           exclusive_minimum=True, unit="s"),
        # ros_hrc.agents.selectors.DEFAULT_FORGETTING (a test checks they agree)
        _s("bpr_forgetting", "float", 0.05, "the BPR selectors' (bpr, bpr-pi) floor: after "
           "each task this share of the belief over the human types is spread evenly over "
           "them, so that a switched human is found again (0: the paper's plain Bayes rule; "
           "docs/selectors.md, Forgetting); a robot model of human types carries its type "
           "belief to the next task with the same floor", minimum=0, maximum=0.99),
        _s("learning_strength", "float", 20.0, "the learning robot's (selector:=pomdp_learning, "
           "pomdp_learning_mean) prior strength kappa: pseudo-counts per row of its prior, the "
           "launch's robot_model (docs/learning.md; chosen on the fit set)", minimum=0,
           maximum=1e9, exclusive_minimum=True),
        _s("learning_forgetting", "float", 0.1, "the learning robot's forgetting rate: when "
           "a task's counts are added, those so far are first multiplied by 1 - this (0: keep "
           "everything; 1: only the last task), so that a new human is learnt again "
           "(docs/learning.md; chosen on the fit set)", minimum=0, maximum=1),
        _s("learning_draws", "int", 8, "the models pomdp_learning draws from its posterior "
           "before each task and plans over (root sampling: its belief weighs them as the task "
           "goes on); pomdp_learning_mean plans on the posterior mean alone", minimum=1,
           maximum=64),
        _s("learning_bonus", "float", None, "the learning robot's exploration bonus beta: "
           "on a decision's first step, beta / (1 + n + m) is added to the reward of the "
           "task's idle action in a state it was taken in n times (by the counts learnt) and "
           "looked at m times this task, so that early in a sequence the robot watches what "
           "its human does alone (0: none; docs/learning.md); auto: the task's (seed 10, "
           "fabric 10: each chosen on streams it is not judged on)",
           minimum=0, maximum=1e6),
    ),
    *_group(
        "the terminal",
        _s("read_stdin", "bool", True, "Enter on the roslaunch terminal resets everything"),
        _s("verbose", "bool", False, "also print the solver processes' own lines (despot_pomdp's "
           "belief and decision, despot_mdp's == RESULTS ==) in the roslaunch terminal; by "
           "default they go to their log files ($ROS_HOME/log/latest/despot_*-stdout.log) and "
           "the terminal shows hrc_human's step block alone, but for the MDP in manual mode "
           "without an xterm of its own (its prompt is answered there)"),
    ),
)

#: Every launch argument (hrc.launch's, and world.launch's publish_rate), by name, in the
#: table's order: hrc.launch's.
SETTINGS: Dict[str, Setting] = {s.name: s for s in _TABLE}

#: The arguments of world.launch (the world alone: no loop, no solvers), in the table's order;
#: its <arg> lines are written from the table (tools/make_settings_files.py) and its pre-flight
#: (``hrc_check --world``) is given each of them.
WORLD_SETTINGS: Tuple[str, ...] = tuple(name for name in SETTINGS if name in (
    "task", "mode", "gui", "seed", "use_sim_time", "real_time_factor", "pause_when_idle",
    "belt_speed", "away_time", "viz", "rviz", "snapshot_dir", "camera_rate", "publish_rate"))

#: ``selector:=`` takes ``fixed`` (also as ``fixed:POLICY``), a selector of the registry
#: (:mod:`ros_hrc.registry`, ``ros_hrc.selectors``: the robot process builds it with
#: ros_hrc.agents.selectors.make_selector), or the learning robot's
#: (ros_hrc.agents.learning): one robot whose model of the human is learnt, root-sampled or
#: its posterior mean; it plans with DESPOT (planner:=despot).
LEARNING_SELECTORS: Tuple[str, ...] = ("pomdp_learning", "pomdp_learning_mean")
#: The learning robot's own settings (its prior strength, forgetting rate, draws and
#: exploration bonus).
LEARNING_SETTINGS: Tuple[str, ...] = ("learning_strength", "learning_forgetting",
                                      "learning_draws", "learning_bonus")


def selector_words() -> Tuple[str, ...]:
    """The names ``selector:=`` takes now: fixed, the registry's selectors (ours and the
    installed packages'), the learning robot's."""
    return ("fixed",) + registry.names(registry.SELECTORS) + LEARNING_SELECTORS

#: The settings a running stack can take in place (``/hrc/configure``, a warm stack's next
#: cell: docs/experiments.md, "Warm stacks"): what its solver processes and its loop are built
#: from at start (models, planner, selector, seed, the episodes to play). Any other setting
#: (the task, the world's, the ports, the windows, the terminal) needs a new launch: a
#: reconfiguration that changes one is refused.
IN_PLACE: FrozenSet[str] = frozenset((
    "human_model", "robot_model", "seed", "human_choice", "temperature", "manual_share",
    "step_delay", "max_steps", "on_episode_end", "end_on_goal", "episodes",
    "wait_for_listener", "planner", "planner_options", "policy_file", "time_per_step", "scenarios", "depth",
    "lambda", "max_trials", "reactive_budget", "reactive_wait", "tasks", "schedule",
    "selector", "library", "selector_model", "task_timeout", "bpr_forgetting",
    *LEARNING_SETTINGS))


def needs_new_launch(running: Mapping[str, Any], wanted: Mapping[str, Any]) -> List[str]:
    """The settings, resolved, that differ between a running launch's ``running`` and
    ``wanted`` and cannot be taken in place (:data:`IN_PLACE`), in table order."""
    return [name for name in SETTINGS if name not in IN_PLACE
            and running.get(name) != wanted.get(name)]


#: The websocket ports, which must differ.
PORTS: Tuple[str, ...] = ("pomdp_port", "human_port")


def _no_such_argument(name: str) -> str:
    hint = did_you_mean(name, SETTINGS)
    return f"no such argument; {hint + ' ' if hint else ''}known: {', '.join(SETTINGS)}"


def _setting(name: str, value: Any = "") -> Setting:
    try:
        return SETTINGS[name]
    except KeyError:
        raise SettingError(name, value, _no_such_argument(name)) from None


def parse(name: str, value: Any) -> Any:
    """``value`` (a launch argument's text, or a Python value) as the setting's type; ``""``
    or None give the default. Raises SettingError (one line) for a bad value or name."""
    return _setting(name, value).parse(value)


def default(name: str) -> Any:
    """The setting's default (None for an automatic one: :func:`resolve` derives it)."""
    return _setting(name).default


def resolve(values: Mapping[str, Any], environ: Optional[Mapping[str, str]] = None
            ) -> Dict[str, Any]:
    """Every setting, in table order: the given ones parsed, the others their defaults, then
    the checks that involve several (distinct ports, policy_file with planner:=policy) and the
    automatic ones (pause_when_idle: when real_time_factor is 0 or in manual mode; mdp_xterm:
    in manual mode with a display, ``environ`` for DISPLAY, os.environ by default; an empty
    snapshot_dir: ``$ROS_HOME/hrc_snapshots``, ``environ``'s ROS_HOME). A model
    not given (or given empty or ``auto``) is the task's default (:mod:`ros_hrc.tasks`).

    Raises SettingError on the first problem; unknown names are refused, all of them named.
    """
    unknown = [n for n in values if n not in SETTINGS]
    if unknown:
        if len(unknown) == 1:
            raise SettingError(unknown[0], values[unknown[0]], _no_such_argument(unknown[0]))
        raise SettingError(", ".join(unknown), "",
                           f"no such arguments; known: {', '.join(SETTINGS)}")
    out = {name: setting.parse(values.get(name)) for name, setting in SETTINGS.items()}
    task = tasks.get(out["task"])
    for name, kind in (("human_model", "human"), ("robot_model", "robot")):
        given = values.get(name)
        if given is None or (isinstance(given, str) and given.strip() in ("", AUTO_WORD)):
            out[name] = task.default_model(kind)
    if out["planner"] == "reactive" and not task.reactive_robot:
        with_one = [name for name in tasks.TASK_NAMES if tasks.get(name).reactive_robot]
        raise SettingError("planner", values.get("planner"),
                           f"task {task.name} has no reactive robot (tasks with one: "
                           f"{', '.join(with_one)}; use despot, policy, none or explore)")
    seen: Dict[int, str] = {}
    for name in PORTS:
        port = out[name]
        if port in seen:
            raise SettingError(name, values.get(name, port),
                               f"the same port as {seen[port]}; the ports must differ")
        seen[port] = name
    if out["planner"] == "policy" and not out["policy_file"]:
        raise SettingError("policy_file", values.get("policy_file", ""),
                           "planner:=policy needs a policy file (hrc_pomdp solve -o FILE)")
    if out["planner"] != "policy" and out["policy_file"]:
        raise SettingError("policy_file", values.get("policy_file"),
                           f"only used with planner:=policy, not planner:={out['planner']}")
    if out["time_per_step"] == 0 and out["max_trials"] == 0:
        raise SettingError("time_per_step", values.get("time_per_step", 0),
                           "0 (no time budget) needs max_trials > 0 to bound the decision")
    planner_option_values(out["planner_options"])
    if out["away_time"] is None:
        out["away_time"] = task.away_time
    if not out["snapshot_dir"]:
        # What the world would use: said where the configuration is printed (hrc_check).
        out["snapshot_dir"] = str(ros_home(environ) / SNAPSHOT_FOLDER)
    _resolve_sequence(out, values, task)
    if out["rviz"]:
        out["viz"] = True    # RViz shows what viz publishes
    if out["pause_when_idle"] is None:
        # Manual mode: the world must not run on (the belt carrying the object away) while
        # someone types the human's next state.
        out["pause_when_idle"] = out["real_time_factor"] == 0 or out["mode"] == "manual"
    if out["mdp_xterm"] is None:
        env = os.environ if environ is None else environ
        out["mdp_xterm"] = out["mode"] == "manual" and bool(env.get("DISPLAY", ""))
    return out


def planner_option_values(text: str) -> Dict[str, Any]:
    """``planner_options``'s pairs (``explore=0.2,name="x"``) as a mapping, each value as TOML
    reads it; SettingError (one line) for text that is not NAME=VALUE pairs."""
    if not str(text).strip():
        return {}
    try:
        return dict(tomllib.loads(f"options = {{{text}}}")["options"])
    except tomllib.TOMLDecodeError as exc:
        raise SettingError("planner_options", text, "must be NAME=VALUE pairs, comma-separated, "
                           f"each VALUE as TOML writes it ({' '.join(str(exc).split())})") \
            from None


def planner_options_text(options: Mapping[str, Any]) -> str:
    """``options`` as ``planner_options:=`` writes them (:func:`planner_option_values` reads
    them back): ``explore=0.2,name="x"``."""
    def shown(value: Any) -> str:
        if isinstance(value, bool):
            return "true" if value else "false"
        if isinstance(value, str):
            return json.dumps(value)
        return repr(value)
    return ",".join(f"{name}={shown(value)}" for name, value in options.items())


def learning_planner_problem(selector: str, planner: str) -> str:
    """Why ``selector`` cannot run with ``planner`` ("" when it can): the learning robot
    plans with DESPOT on its posterior."""
    if selector in LEARNING_SELECTORS and planner != "despot":
        return f"plans with DESPOT on what it learns: it needs planner:=despot, not {planner}"
    return ""


def _resolve_sequence(out: Dict[str, Any], values: Mapping[str, Any], task: tasks.Task) -> None:
    """The sequence's settings (docs/sequences.md), checked together: a selector or a schedule
    only with ``tasks``, a selector of :func:`selector_words` (or module:Class), a schedule whose types are the
    task's (a schedule file's path made absolute), ``task_timeout`` auto: the task's;
    ``tasks`` not given is 0 once resolved (no sequence)."""
    selector = out["selector"]
    kind, sep, policy = selector.partition(":")
    if kind == "fixed" and sep and not policy.strip():
        raise SettingError("selector", values.get("selector"),
                           "fixed:POLICY needs a policy of the library after the colon")
    if kind != "fixed" and selector not in LEARNING_SELECTORS and \
            not registry.is_object_path(selector) and selector not in selector_words():
        known = selector_words()
        hint = did_you_mean(selector, known)
        hint = f"; {hint}" if hint else ""
        raise SettingError("selector", values.get("selector"),
                           f"unknown selector{hint} (known: {', '.join(known)}, fixed:POLICY "
                           "(a policy of the library), or module:Class)")
    problem = learning_planner_problem(selector, out["planner"])
    if problem:
        raise SettingError("selector", values.get("selector"), problem)
    if out["tasks"] is None:
        for name, word in (("selector", "fixed"), ("schedule", "")):
            if out[name] != word:
                raise SettingError(name, values.get(name),
                                   "only with a sequence: a selector chooses between the tasks "
                                   "of a sequence and a schedule says who plays them; give "
                                   "tasks:=N")
    schedule = out["schedule"]
    if schedule and (schedule.endswith(".toml") or "/" in schedule):
        schedule = out["schedule"] = str(user_path(schedule))
    try:
        parse_schedule(schedule, model_names(task.model_dirs["human"]), out["human_model"],
                       task.name)
    except ScheduleError as exc:
        raise SettingError("schedule", values.get("schedule"), str(exc)) from None
    for name in ("library", "selector_model"):
        text = out[name] or AUTO_WORD
        out[name] = text if text == AUTO_WORD else str(user_path(text))
    if out["task_timeout"] is None:
        out["task_timeout"] = task.task_timeout
    if out["learning_bonus"] is None:
        out["learning_bonus"] = task.learning_bonus
    if out["tasks"] is None:
        out["tasks"] = 0     # resolved: no sequence (the parameter server carries no None)


def add_argument(parser, name: str, *flags: str, **kwargs: Any):
    """Add the setting ``name`` to an argparse parser: the flag (``--`` + name with ``-``
    for ``_`` unless ``flags`` are given), a type that parses with :func:`parse` (a bad value
    is argparse's one-line error; an empty one means the default), the table's default and
    its doc as help. ``kwargs`` override any of them."""
    setting = _setting(name)

    def type_(text: str) -> Any:
        try:
            return setting.parse(text)
        except SettingError as exc:
            import argparse
            raise argparse.ArgumentTypeError(f"{exc.requirement}, got {text!r}") from None

    type_.__name__ = setting.kind   # argparse names it in some messages
    shown = "automatic" if setting.default is None else (
        "''" if setting.default == "" else _shown(setting.default))
    unit = f" {setting.unit}" if setting.unit and setting.kind == "float" else ""
    options: Dict[str, Any] = {
        "type": type_, "default": setting.default,
        "help": f"{setting.doc} (default: {shown}{unit})".replace("%", "%%"),
    }
    options["metavar"] = ("{" + ",".join(setting.choices or ()) + "}" if setting.kind == "choice"
                          else setting.name.upper())
    if flags and all(f.startswith("-") for f in flags):
        options["dest"] = name        # -p for planner still sets args.planner
    options.update(kwargs)
    action = parser.add_argument(*(flags or (setting.flag,)), **options)
    action.setting = name             # what use_as_defaults matches on
    return action


def use_as_defaults(parser, config: Mapping[str, Any]) -> None:
    """Make the values of ``config`` (setting name -> resolved value, e.g. a launch session's
    settings) the defaults of the parser's options made by :func:`add_argument`; an option
    given on the command line still wins."""
    parser.set_defaults(**{action.dest: config[action.setting] for action in parser._actions
                           if getattr(action, "setting", None) in config})
