"""The arguments a user gave roslaunch against the ones its launch file declares (no ROS).

roslaunch ignores a ``name:=value`` word its launch file does not declare: a typo
(``human_modle:=tired``) starts the defaults without a word. The launch's pre-flight
(``hrc_check``, run by roslaunch as a ``<param command=...>``) reads the command line of the
roslaunch that runs it, finds the launch file(s) it was given and refuses a word that none of
them declares, in one line naming the nearest declared argument::

    human_modle:=tired: no such argument (did you mean human_model?)

Only the top-level files count: an included file (world_nodes.launch under hrc.launch) gets its
arguments from its includer, never from the command line. A user's argument is an ``<arg>``
with no ``value=`` (a ``value=`` argument is derived inside the file, roslaunch does not take
it from the command line) outside an ``<include>`` (whose ``<arg>`` children pass values on).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable, List, Optional, Sequence, Tuple

from defusedxml import ElementTree as SafeElementTree

from ros_hrc.errors import did_you_mean
from ros_hrc.model_files import MODELS_DIR

#: This package's name and directory, where ``roslaunch ros_hrc FILE`` finds FILE.
PACKAGE = "ros_hrc"
PACKAGE_DIR = MODELS_DIR.parent

#: roslaunch's options that take a value in the next word (``roslaunch -h``): that word is
#: neither a launch file nor a package.
_OPTIONS_WITH_VALUE = frozenset((
    "--args", "--find-node", "-c", "--child", "-u", "--server_uri", "--run_id", "-p",
    "--port", "--pid", "-w", "--numworkers", "-t", "--timeout", "--master-logger-level",
    "--sigint-timeout", "--sigterm-timeout"))


def split_command_line(words: Sequence[str]) -> Tuple[List[str], List[str]]:
    """roslaunch's arguments (``argv[1:]``) as (its positional words: a package and a file,
    or files; the user's ``name:=value`` words). roslaunch's own remappings (``__name:=``,
    ``__log:=``) are not the user's launch arguments and are left out."""
    positional: List[str] = []
    assignments: List[str] = []
    skip_next = False
    for word in words:
        if skip_next:
            skip_next = False
        elif ":=" in word:
            if not word.startswith("__"):
                assignments.append(word)
        elif word.startswith("-") and word != "-":
            skip_next = word in _OPTIONS_WITH_VALUE
        else:
            positional.append(word)
    return positional, assignments


def launch_files(positional: Sequence[str], cwd: Path) -> List[Path]:
    """The launch files roslaunch was given, as it finds them (``roslaunch PACKAGE FILE`` or
    ``roslaunch FILE ...``, relative to ``cwd``, roslaunch's directory); [] when they are not
    this package's or cannot be found here (nothing is then checked)."""
    if len(positional) >= 2 and positional[0] == PACKAGE:
        name = positional[1]
        found = [path for path in (PACKAGE_DIR / "launch" / name, PACKAGE_DIR / name)
                 if path.is_file()]
        return found[:1]
    if not positional or positional[0] == "-":
        return []
    paths = [cwd / word for word in positional]
    return paths if all(path.is_file() for path in paths) else []


def declared_arguments(launch_file: Path) -> List[str]:
    """The arguments a user may give ``launch_file`` on the command line: its ``<arg>``
    tags without ``value=``, outside any ``<include>``, in the file's order."""
    root = SafeElementTree.parse(str(launch_file)).getroot()
    names: List[str] = []

    def visit(element) -> None:
        for child in element:
            if child.tag == "include":
                continue
            if child.tag == "arg" and child.get("value") is None and child.get("name"):
                names.append(child.get("name"))
            visit(child)

    visit(root)
    return names


def unknown_argument_line(assignments: Iterable[str], declared: Sequence[str],
                          where_listed: str) -> Optional[str]:
    """One line naming each of ``assignments`` (``name:=value`` words) whose name is not in
    ``declared``, each with the nearest declared name (difflib) or, without a close one,
    ``where_listed``; None when every name is declared."""
    parts = []
    for word in assignments:
        name = word.partition(":=")[0]
        if name in declared:
            continue
        hint = did_you_mean(name, declared) or f"the arguments: {where_listed}"
        parts.append(f"{word}: no such argument ({hint})")
    return "; ".join(parts) if parts else None


def where_arguments_are_listed(launch_file: Path) -> str:
    """Where a user reads the arguments of ``launch_file``."""
    if launch_file.name == "hrc.launch":
        return "rosrun ros_hrc hrc_check -h, or docs/settings.md"
    return f"roslaunch {PACKAGE} {launch_file.name} --ros-args"


def check_launch_command_line(command_line: Sequence[str], cwd: Path
                              ) -> Optional[Tuple[str, str]]:
    """(the launch file's name, the refusal line) for the roslaunch run as ``command_line``
    (its whole argv) in ``cwd`` when a ``name:=value`` word is declared by none of its launch
    files; None when each is, or when its files are not this package's (nothing known to
    compare with)."""
    positional, assignments = split_command_line(command_line[1:])
    files = launch_files(positional, cwd)
    if not files or not assignments:
        return None
    declared = [name for path in files for name in declared_arguments(path)]
    line = unknown_argument_line(assignments, declared, where_arguments_are_listed(files[0]))
    return None if line is None else (files[0].name, line)


def roslaunch_command_line(pid: int) -> Optional[Tuple[List[str], Path]]:
    """(the arguments after ``roslaunch``, its directory) of process ``pid`` when it runs
    roslaunch; None otherwise (``rosrun ros_hrc hrc_check`` by hand, a test)."""
    import psutil

    from ros_hrc.process_tree import command_line, is_roslaunch

    if not is_roslaunch(pid):
        return None
    words = command_line(pid)
    start = next(i for i, word in enumerate(words) if os.path.basename(word) == "roslaunch")
    try:
        cwd = Path(psutil.Process(pid).cwd())
    except psutil.Error:
        return None
    return words[start:], cwd
