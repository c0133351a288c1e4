"""What the two solver processes (``despot_mdp``, the human; ``despot_pomdp``, the robot) share
about their start: the options every solver takes and the start-up (no ROS, no sockets).

The options (:func:`solver_parser`): the task, the process's model (``--model``), the link's
host and port (``--port``), the seed, and the launch's link token (``--link-session``,
``--token-file``); each process adds its own. All but the token's are settings, so their
defaults, checks and help are the settings table's (:mod:`ros_hrc.settings`).

The start-up (:func:`start_solver`): whole lines on stdout and stderr (the processes share
roslaunch's terminal), the options read with the launch's resolved settings as defaults
(:func:`ros_hrc.command_line.parse_launch_options`), what the process is built from (its
``build``), and the link token. What cannot start is one line, ``NAME: what is wrong``, and
exit status 2; under a launch the launch is stopped too, since roslaunch would respawn the
process about once a second to fail the same way.
"""
from __future__ import annotations

import argparse
import sys
from typing import Callable, Generic, NamedTuple, Optional, Sequence, TypeVar

from ros_hrc import settings
from ros_hrc.command_line import parse_launch_options, print_whole_lines
from ros_hrc.errors import HrcError
from ros_hrc.link.token import add_token_arguments, launch_token, stop_launch

__all__ = ["CANNOT_START", "Started", "solver_parser", "start_solver"]

#: The exit status of a solver that cannot start on its options (a bad model, no token).
CANNOT_START = 2

Built = TypeVar("Built")


class Started(NamedTuple, Generic[Built]):
    """A solver that could start: its options, what ``build`` made of them, its link token."""

    args: argparse.Namespace
    built: Built
    token: str


def solver_parser(name: str, description: str, model_setting: str,
                  port_setting: str) -> argparse.ArgumentParser:
    """The parser of solver ``name`` with the options every solver takes: ``--task``,
    ``--model`` (the setting ``model_setting``), ``--host``, ``--port`` (``port_setting``),
    ``--seed`` and the link token's; the process adds its own after them."""
    p = argparse.ArgumentParser(prog=name, description=description)
    settings.add_argument(p, "task")
    settings.add_argument(p, model_setting, "--model")
    settings.add_argument(p, "host")
    settings.add_argument(p, port_setting, "--port")
    settings.add_argument(p, "seed")
    add_token_arguments(p)
    return p


def start_solver(name: str, parser: argparse.ArgumentParser, argv: Optional[Sequence[str]],
                 build: Callable[[argparse.Namespace], Built]) -> Optional[Started[Built]]:
    """Start solver ``name`` (module docstring): its options parsed with ``parser``, ``build``
    run on them, its link token read. None when it cannot start (``build`` raised HrcError,
    OSError or ValueError, or the token cannot be read): the one line is printed then, and the
    process exits with :data:`CANNOT_START`."""
    print_whole_lines()
    args = parse_launch_options(parser, argv)
    try:
        built = build(args)
        token = launch_token(args)
    except (HrcError, OSError, ValueError) as exc:
        print(f"{name}: {exc}", file=sys.stderr, flush=True)
        if args.link_session and stop_launch(args.link_session):
            # Respawned, it would fail the same way about once a second: stop the launch.
            print(f"{name}: cannot start on this launch's settings: stopping the launch",
                  file=sys.stderr, flush=True)
        return None
    return Started(args, built, token)
