"""hrc_check: the launch's pre-flight. Every argument, both models, the policy file and the
ports are checked before anything starts; the resolved configuration is printed as YAML.

    hrc_check human_model:=tired human_port:=9091 ...     # the launch arguments, name:=value

On success it prints the configuration (every setting, defaults filled in, a mapping name ->
value) on stdout and exits 0. Every path in it (a model file, ``policy_file``,
``snapshot_dir``) is absolute: resolved here, in the directory roslaunch was started from,
because the processes of the launch run in ``$ROS_HOME``. On the first problem it prints one line on stderr,
``hrc.launch: <what is wrong>`` naming the argument or the file, and exits 2; never a traceback.
``hrc.launch`` runs it as a ``<param command=...>`` so that roslaunch refuses to start anything
when it fails (through ``--status-pipe``, below)::

    <param name="/hrc/config" type="yaml"
           command="$(find ros_hrc)/scripts/hrc_check human_model:=$(arg human_model) ..."/>

A model whose names are generic (``s0..``, ``a0..``, ``o0..``, as POMDPX ``<NumValues>`` gives
them) in the task's sizes is read by position (:mod:`ros_hrc.models`); the mapping is one
line per such model on stderr, ``hrc.launch: <file>: names by position: states s0=S0 ...``,
before the YAML. Not on stdout: roslaunch reads stdout as the value of ``/hrc/config`` and
never shows it, while it passes the command's stderr through to the terminal, so the line is
seen when the launch starts; a YAML comment would be parsed away unseen.

The planner (``planner:=``: ours, an installed package's or ``module:Class``;
docs/extending.md) is imported and checked to be a planner as the robot process will find it,
and a selector of a sequence likewise (below): an unknown name is one line with the known
names and the nearest, a module that does not import or a class of another kind one line
naming it and why.

A sequence (``tasks:=N``, docs/sequences.md) is checked whole before anything starts: its
schedule (every type the task's, a schedule file readable and well formed: the file and the
line), and with a selector other than ``fixed`` the policy library (each policy's robot model
the task's) and the selector model (of this task and this library; one a selector needs:
refused without, naming ``make train-selector``), as the robot process will load them
(:mod:`ros_hrc.processes.selection`).

``gui:=true`` and ``rviz:=true`` need a display: without DISPLAY, or when no X server answers
there, the launch is refused (the window or RViz would die and the stack run on unseen).

``--no-port-check`` skips binding the ports (to check a configuration for later). The
POMDP's port is only checked with ``start_pomdp:=true``: started by hand, the POMDP process
may already serve it.

``--world`` checks only the settings given (world.launch's pre-flight: no models, no ports),
prints those, and starts its error lines with ``world.launch``. ``--arguments-only`` checks no
setting and prints ``{}`` (experiment.launch's pre-flight: only the check below).

Run by roslaunch (its parent), it first compares the ``name:=value`` words the user gave
roslaunch with the arguments the launch file declares
(:mod:`ros_hrc.commands.launch_arguments`): roslaunch ignores an undeclared one in silence, so
a typo is refused here, naming the nearest declared argument::

    hrc.launch: human_modle:=tired: no such argument (did you mean human_model?)

``--status-pipe=PATH`` (each launch file gives one, named after its session): the refusal is
only the line. The program then always exits 0 and prints a mapping (``{}`` on a refusal), and
hands its exit status to the launch through the FIFO ``PATH``, which the launch file reads
right after this ``<param>`` and exits with (``$(eval ... exit(status))``). Without it, a
failing ``<param command>`` made roslaunch follow the line with ~2 KB of red ``RLException``
dumping the whole tag. The FIFO is removed as soon as roslaunch opened it: a refused launch
leaves no file behind.

``--link-session=NAME`` (hrc.launch gives ``$(anon hrc_link)``): once every check passed, make
the launch's link token (:mod:`ros_hrc.link.token`), remove the tokens of launches that ended,
write the resolved configuration beside the token (the solver processes, given the same
``--link-session``, take their options from it) and add the token file's path to the
configuration as ``token_file``. When a solver is left to be run by hand (``start_mdp:=false``
/ ``start_pomdp:=false``), one line on stderr gives the whole command to run it with::

    hrc.launch: run despot_mdp by hand: rosrun ros_hrc despot_mdp --host 127.0.0.1 --port 9090 \
        --model humanModel --token-file ~/.ros/ros_hrc/links/hrc_link_....token
"""
from __future__ import annotations

import errno
import functools
import io
import os
import shlex
import signal
import socket
import sys
from pathlib import Path
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

from ros_hrc.errors import HrcError
from ros_hrc import settings

NAME = "hrc_check"
#: What each error line starts with: the user ran the launch file, not this program.
PREFIX = "hrc.launch"

USAGE = (f"usage: {NAME} [--no-port-check] [--world | --arguments-only] [--link-session=NAME] "
         "[--status-pipe=PATH] name:=value ...  "
         f"(the arguments of hrc.launch: {', '.join(settings.SETTINGS)})")
_SESSION_OPTION = "--link-session="
_STATUS_PIPE_OPTION = "--status-pipe="


class CheckError(HrcError):
    """One line saying what is wrong with the launch's configuration."""


def parse_words(words: Sequence[str]) -> Dict[str, str]:
    """``name:=value`` words as a dict; a word of another shape or a name given twice is refused."""
    values: Dict[str, str] = {}
    for word in words:
        name, sep, value = word.partition(":=")
        if not sep or not name:
            raise CheckError(f"{word!r}: expected name:=value (e.g. human_model:=tired)")
        if name in values and values[name] != value:
            raise CheckError(f"{name}: given twice ({values[name]!r} and {value!r})")
        values[name] = value
    return values


def check_models(config: Mapping[str, object], notes: Optional[List[str]] = None,
                 given: Optional[Mapping[str, str]] = None) -> None:
    """Load both models and check them against the tables of the chosen task (``task``; a
    model of another task is refused, naming the task it fits), and the policy file against
    the robot model for planner:=policy. The start-up line of each model named by position
    is appended to ``notes``. An error names the argument as typed (``given``, the words'
    values) and the file it looked for."""
    typed = functools.partial(typed_value, config, given or {})

    from ros_hrc.models import (ModelNotFound, load_human_model, load_robot_model,
                                     positional_mapping_line)

    loaded = {}
    for name, load in (("human_model", load_human_model), ("robot_model", load_robot_model)):
        try:
            # As typed: this runs where it was typed, so it names the same file as the
            # resolved path, and a refusal shows both.
            loaded[name] = load(typed(name), config.get("task"))
        except ModelNotFound as exc:
            raise CheckError(f"{name}:={typed(name)}: {exc}") from None
        line = positional_mapping_line(loaded[name])
        if line is not None and notes is not None:
            notes.append(line)
    if config["planner"] == "policy":
        from ros_hrc.pomdp.policy import load as load_policy

        try:
            load_policy(str(config["policy_file"]), loaded["robot_model"])
        except (HrcError, OSError, ValueError) as exc:
            text = " ".join(str(exc).split())
            raise CheckError(f"policy_file:={typed('policy_file')}: {text}") from None


def check_planner(config: Mapping[str, object]) -> None:
    """The planner ``planner:=`` names, imported and checked to be a planner, and its own
    options (``planner_options:=``) checked against it, as the robot process will find them (:func:`ros_hrc.pomdp.planner.planner_class`): a name no package
    declares, a module that does not import or a class of another kind is refused now, one
    line, before anything starts."""
    from ros_hrc.pomdp.planner import planner_class
    from ros_hrc.registry import RegistryError

    try:
        kind = planner_class(str(config["planner"]))
    except RegistryError as exc:
        raise CheckError(f"planner:={config['planner']}: {exc.reason}") from None
    try:
        kind.checked_options(settings.planner_option_values(str(config["planner_options"])))
    except ValueError as exc:
        raise CheckError(f"planner_options:={config['planner_options']}: {exc}") from None


def typed_value(config: Mapping[str, object], given: Mapping[str, str], name: str) -> str:
    """Setting ``name`` as the user typed it (``given``: the words' values), or its resolved
    value when it was not typed or typed as ``auto``."""
    text = str(given.get(name) or "").strip()
    return str(config[name]).strip() if text in ("", settings.AUTO_WORD) else text


def check_sequence(config: Mapping[str, object],
                   given: Optional[Mapping[str, str]] = None) -> None:
    """A sequence's library and selector model, loaded as the robot process will load them
    (nothing for ``selector:=fixed``: the launch's one robot, checked with the models). As
    typed (this runs where they were typed, so the same files), so a refusal names the
    argument as the user wrote it and the file it looked for."""
    from ros_hrc import tasks
    from ros_hrc.processes.selection import load_selection, uses_library

    given = given or {}
    if uses_library(str(config["selector"])):
        load_selection(str(config["selector"]), typed_value(config, given, "library"),
                       typed_value(config, given, "selector_model"),
                       tasks.get(str(config["task"])))


def ports_to_bind(config: Mapping[str, object]) -> List[str]:
    """The port settings whose servers the launch starts: human_port (hrc_human) always,
    pomdp_port only with start_pomdp (without it, the POMDP process started by hand may
    already serve it)."""
    return [name for name in settings.PORTS
            if name != "pomdp_port" or config.get("start_pomdp", True)]


def check_ports(config: Mapping[str, object]) -> None:
    """Each port the launch will serve can be bound on ``host`` now (as the servers will:
    with SO_REUSEADDR, so a port in TIME_WAIT is free)."""
    host = str(config["host"])
    literal = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    for name in ports_to_bind(config):
        port = int(config[name])  # type: ignore[arg-type]
        try:
            infos = socket.getaddrinfo(literal, port, type=socket.SOCK_STREAM,
                                       flags=socket.AI_PASSIVE)
        except socket.gaierror as exc:
            raise CheckError(f"host:={host}: cannot resolve it ({exc.strerror})") from None
        family, kind, proto, _, address = infos[0]
        with socket.socket(family, kind, proto) as sock:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                sock.bind(address)
            except OSError as exc:
                if exc.errno == errno.EADDRINUSE:
                    raise CheckError(f"{name}:={port}: port {port} is already in use on {host} "
                                     "(another launch running? choose another port)") from None
                if exc.errno in (errno.EACCES, errno.EPERM):
                    raise CheckError(f"{name}:={port}: not allowed to bind port {port} on "
                                     f"{host} ({exc.strerror})") from None
                raise CheckError(f"host:={host}: cannot bind port {port} there "
                                 f"({exc.strerror or exc})") from None


def display_problem(display: Optional[str], timeout: float = 2.0) -> Optional[str]:
    """Why no window can open on X display ``display`` (DISPLAY's value), or None when an X
    server accepts connections there (local ``:N``: its socket; ``host:N``: TCP 6000+N)."""
    if not display:
        return "DISPLAY is not set"
    host, sep, rest = display.rpartition(":")
    number = rest.split(".", 1)[0]
    if not sep or not number.isdigit():
        return f"DISPLAY={display} is not a display name (such as :0)"
    if host in ("", "unix"):
        path = f"/tmp/.X11-unix/X{int(number)}"
        # Linux X servers listen on an abstract socket of the same name too.
        addresses = ["\0" + path, path] if sys.platform.startswith("linux") else [path]
        for address in addresses:
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
                sock.settimeout(timeout)
                try:
                    sock.connect(address)
                    return None
                except OSError:
                    continue
        return f"no X server answers on DISPLAY={display}"
    try:
        with socket.create_connection((host, 6000 + int(number)), timeout=timeout):
            return None
    except OSError as exc:
        return f"no X server answers on DISPLAY={display} ({exc.strerror or exc})"


def check_display(config: Mapping[str, object],
                  environ: Optional[Mapping[str, str]] = None) -> None:
    """gui:=true (PyBullet's window) and rviz:=true need a display that answers."""
    wanted = [name for name in ("gui", "rviz") if config.get(name)]
    if not wanted:
        return
    env = os.environ if environ is None else environ
    problem = display_problem(env.get("DISPLAY", ""))
    if problem:
        raise CheckError(f"{wanted[0]}:=true: needs a display, but {problem} (run it on a "
                         f"desktop or under Xvfb, or leave {wanted[0]}:=false)")


def check(words: Sequence[str], port_check: bool = True,
          notes: Optional[List[str]] = None) -> Dict[str, object]:
    """The resolved configuration of the launch arguments ``words``; raises HrcError (a
    SettingError, ModelError, ModelFormatError or CheckError) with one line on the first
    problem. Each model named by position adds its mapping line to ``notes``."""
    given = parse_words(words)
    config = settings.resolve(given)
    check_planner(config)
    check_models(config, notes, given)
    check_sequence(config, given)
    check_display(config)
    if port_check:
        check_ports(config)
    return config


#: The solver processes a launch may leave to be run by hand: (its start_* setting, its port).
BY_HAND = {"despot_mdp": ("start_mdp", "human_port"), "despot_pomdp": ("start_pomdp", "pomdp_port")}


def hand_run_command(process: str, config: Mapping[str, object], token_file: str) -> str:
    """The whole command that runs ``process`` by hand into this launch: its host, port,
    model and token file, and each other option of its own whose setting is not the default
    (taken from the process's own parser, so the command is what it accepts)."""
    if process == "despot_mdp":
        from ros_hrc.processes.despot_mdp import build_parser
    else:
        from ros_hrc.processes.despot_pomdp import build_parser
    always = {"host", BY_HAND[process][1], "human_model", "robot_model"}
    # What each automatic setting resolves to on this task: the process, given the task,
    # resolves it the same (e.g. learning_bonus), so the command need not say it.
    automatic = settings.resolve({"task": str(config.get("task", ""))}, environ={})
    words = ["rosrun", "ros_hrc", process]
    for action in build_parser()._actions:
        name = getattr(action, "setting", None)
        if name is None or name not in config:
            continue
        value = config[name]
        default = settings.default(name)
        if name not in always and (value == default or
                                   (default is None and value == automatic.get(name))):
            continue
        flag = max(action.option_strings, key=len)
        words += [flag, shlex.quote(settings._shown(value))]
    words += ["--token-file", shlex.quote(str(token_file))]
    return " ".join(words)


def make_link_token(session: str):
    """Make the launch's token file (after the tokens of ended launches are removed); its
    path. The launcher is this program's parent, roslaunch."""
    from ros_hrc.link.token import mint_token, prune_tokens

    prune_tokens()
    return mint_token(session, launcher_pid=os.getppid())


def one_line(text: object) -> str:
    return " ".join(str(text).split())


def unknown_launch_arguments(launcher: int) -> Optional[Tuple[str, str]]:
    """(the launch file's name, the refusal line) when a ``name:=value`` word given to
    ``launcher`` (this program's roslaunch) is declared by none of its launch files: roslaunch
    would ignore it in silence. None when each is, or ``launcher`` is no roslaunch (run by
    hand)."""
    from ros_hrc.commands.launch_arguments import (check_launch_command_line,
                                                   roslaunch_command_line)

    found = roslaunch_command_line(launcher)
    return None if found is None else check_launch_command_line(*found)


def make_status_pipe(path: Path) -> None:
    """Make the FIFO ``path`` (mode 0600; its directory made if needed, 0700) through which
    the launch reads the pre-flight's exit status."""
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.mkfifo(path, 0o600)


def hand_status_to_launch(path: Path, status: int, timeout: float = 60.0) -> None:
    """Give ``status`` to the launch through the FIFO ``path`` (:func:`make_status_pipe`):
    a child process waits for roslaunch to open it, removes it and writes the status. The
    FIFO is gone once roslaunch has read it, or after ``timeout`` s if it never does (Ctrl-C
    first): a refused launch leaves no file, and this program returns at once (roslaunch
    waits for its output before reading the FIFO)."""
    sys.stdout.flush()
    sys.stderr.flush()
    if os.fork() != 0:
        return
    try:   # the child: it must not hold roslaunch's pipes of this program's output
        quiet = os.open(os.devnull, os.O_RDWR)
        for fd in (0, 1, 2):
            os.dup2(quiet, fd)

        def give_up(_signum, _frame):
            raise TimeoutError

        signal.signal(signal.SIGALRM, give_up)
        signal.alarm(max(1, int(timeout)))
        writer = os.open(path, os.O_WRONLY)   # blocks until roslaunch opens it to read
        signal.alarm(0)
        path.unlink()
        os.write(writer, f"{status}\n".encode())
        os.close(writer)
    except BaseException:   # timed out, interrupted: only the FIFO is left to remove
        try:
            path.unlink()
        except OSError:
            pass
    finally:
        os._exit(0)


def run(words: List[str]) -> int:
    """The pre-flight on ``words`` (this program's arguments): the configuration on stdout,
    notes and the refusal line on stderr; the exit status (0, or 2 on a refusal)."""
    port_check = "--no-port-check" not in words
    world_only = "--world" in words
    arguments_only = "--arguments-only" in words
    words = [w for w in words if w not in ("--no-port-check", "--world", "--arguments-only")]
    prefix = "world.launch" if world_only else PREFIX
    try:
        if any(w in ("-h", "--help") for w in words):
            lines = [__doc__.split("\n\n")[0], "", USAGE,
                     "(docs/settings.md lists them too, with the values each takes)"]
            for s in settings.SETTINGS.values():
                shown = "automatic" if s.default is None else repr(s.default)
                lines.append(f"  {s.name:<17} {s.doc} (default: {shown})")
            sys.stdout.write("\n".join(lines) + "\n")
            sys.stdout.flush()
            return 0
        sessions = [w[len(_SESSION_OPTION):] for w in words if w.startswith(_SESSION_OPTION)]
        words = [w for w in words if not w.startswith(_SESSION_OPTION)]
        options = [w for w in words if w.startswith("-")]
        if options:
            raise CheckError(f"{options[0]}: unknown option; {USAGE}")
        unknown = unknown_launch_arguments(os.getppid())
        if unknown is not None:
            prefix = unknown[0]     # the file the user gave roslaunch, whose arguments these are
            raise CheckError(unknown[1])
        notes: List[str] = []
        if arguments_only:
            config: Dict[str, object] = {}
        elif world_only:
            given = parse_words(words)
            resolved = settings.resolve(given)
            config = {name: resolved[name] for name in given}
            check_display(config)
        else:
            config = check(words, port_check, notes)
        if sessions:
            from ros_hrc.link.token import write_session_settings

            token_file = str(make_link_token(sessions[-1]))
            write_session_settings(sessions[-1], config)
            config["token_file"] = token_file
            for process, (flag, _port) in BY_HAND.items():
                if not config[flag]:
                    notes.append(f"run {process} by hand: "
                                 f"{hand_run_command(process, config, token_file)}")
        for line in notes:   # only once every check passed: a refusal stays one line
            print(f"{prefix}: {line}", file=sys.stderr, flush=True)
        import yaml

        sys.stdout.write(yaml.safe_dump(dict(config), sort_keys=False, default_flow_style=False))
        sys.stdout.flush()
        return 0
    except HrcError as exc:
        print(f"{prefix}: {one_line(exc)}", file=sys.stderr, flush=True)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:   # stdout closed early (| head): nothing more to say
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 2
    except Exception as exc:  # no traceback for any input: one line, whatever went wrong
        print(f"{prefix}: {NAME} failed: {type(exc).__name__}: {one_line(exc)}",
              file=sys.stderr, flush=True)
        return 2


def main(argv: Optional[Sequence[str]] = None) -> int:
    from ros_hrc.command_line import own_arguments

    words: List[str] = own_arguments(argv)
    pipes = [w[len(_STATUS_PIPE_OPTION):] for w in words if w.startswith(_STATUS_PIPE_OPTION)]
    words = [w for w in words if not w.startswith(_STATUS_PIPE_OPTION)]
    if not pipes:
        return run(words)
    # Run by a launch: roslaunch reads the status from the FIFO, after this program's output
    # (a mapping, ``{}`` on a refusal, so that the <param> itself never fails: a failing
    # <param command> makes roslaunch dump the whole tag in red after the refusal line).
    pipe = Path(pipes[-1])
    try:
        make_status_pipe(pipe)
    except OSError as exc:
        print(f"{PREFIX}: {NAME} failed: {pipe}: {exc.strerror or exc}", file=sys.stderr,
              flush=True)
        return 2
    real_stdout = sys.stdout
    sys.stdout = io.StringIO()
    try:
        status = run(words)
    finally:
        output, sys.stdout = sys.stdout.getvalue(), real_stdout
    sys.stdout.write(output if status == 0 else "{}\n")
    hand_status_to_launch(pipe, status)
    return 0


if __name__ == "__main__":
    sys.exit(main())
