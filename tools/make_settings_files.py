#!/usr/bin/env python3
"""Write what is made from the settings table (``ros_hrc.settings``, the only place a default is
written): the ``<arg>`` lines of ``launch/hrc.launch`` and of ``launch/world.launch`` (the
world alone: :data:`ros_hrc.settings.WORLD_SETTINGS`), and the reference ``docs/settings.md``.

    python tools/make_settings_files.py           # rewrite them from the table
    python tools/make_settings_files.py --check   # exit 1, naming each file that differs

In the launch files only the lines between :data:`BEGIN` and :data:`END` are written; the rest
of each file (the pre-flight, the nodes) is left as it is. Each argument's default is the table's as
a launch file writes it (:attr:`ros_hrc.settings.Setting.launch_default`), its doc the table's,
with the values a number takes. The output is deterministic: a unit test
(test/unit/loop/test_settings.py) fails when a committed file is not what this writes.

ROS-free: only ros_hrc.settings.
"""
from __future__ import annotations

import argparse
import sys
import textwrap
from pathlib import Path
from typing import Dict, Iterable, List, Optional, Sequence

REPO = Path(__file__).resolve().parents[1]
for _path in (REPO / "src", REPO / "tools"):  # a checkout without an installed package; the
    if str(_path) not in sys.path:             # tests load this file by its path
        sys.path.insert(0, str(_path))

from generated_files import MarkersMissing, between_markers, write_or_check  # noqa: E402
from ros_hrc import settings  # noqa: E402
from ros_hrc.settings import Setting  # noqa: E402

LAUNCH = Path("launch") / "hrc.launch"
WORLD_LAUNCH = Path("launch") / "world.launch"
REFERENCE = Path("docs") / "settings.md"
THIS = "tools/make_settings_files.py"
#: The lines of hrc.launch between these two are written here.
BEGIN = (f"<!-- Written by {THIS} from the settings table (src/ros_hrc/settings.py): "
         "edit the table, then run it. -->")
END = "<!-- (end of the lines written from the settings table) -->"
INDENT = "  "


def hrc_launch_settings() -> List[Setting]:
    """The settings that are arguments of hrc.launch, in the table's order."""
    return [s for s in settings.SETTINGS.values() if s.in_hrc_launch]


def by_group(members: Iterable[Setting]) -> Dict[str, List[Setting]]:
    """``members`` under their headings, in the order each heading first comes."""
    groups: Dict[str, List[Setting]] = {}
    for member in members:
        groups.setdefault(member.group, []).append(member)
    return groups


def world_launch_settings() -> List[Setting]:
    """The settings that are arguments of world.launch, in the table's order."""
    return [settings.SETTINGS[name] for name in settings.WORLD_SETTINGS]


def launch_doc(setting: Setting, world: bool = False) -> str:
    """An argument's doc in a launch file (``roslaunch --ros-args`` shows it): the table's
    (world.launch's own where it has one), and for a number the values it takes."""
    doc = setting.world_doc if world and setting.world_doc else setting.doc
    if setting.kind in ("int", "float"):
        return f"{doc}; {setting.accepted()}"
    return doc


def attribute(text: str) -> str:
    """``text`` as the value of a double-quoted XML attribute (``>`` may stay as it is)."""
    return text.replace("&", "&amp;").replace("<", "&lt;").replace('"', "&quot;")


def arg_line(setting: Setting, world: bool = False) -> str:
    """One ``<arg name default doc/>`` line."""
    default = setting.world_default if world and setting.world_default is not None \
        else setting.launch_default
    return (f'{INDENT}<arg name="{setting.name}" default="{attribute(default)}" '
            f'doc="{attribute(launch_doc(setting, world))}"/>')


def launch_block(world: bool = False) -> List[str]:
    """A launch file's argument lines (between the markers), a comment over each group:
    hrc.launch's, or with ``world`` world.launch's."""
    lines: List[str] = []
    chosen = world_launch_settings() if world else hrc_launch_settings()
    for heading, group in by_group(chosen).items():
        lines += ["", f"{INDENT}<!-- {heading} -->"]
        lines += [arg_line(member, world) for member in group]
    return lines


def with_launch_block(text: str, world: bool = False) -> str:
    """``text`` (hrc.launch, or world.launch with ``world``) with the lines between the
    markers written anew."""
    return between_markers(text, BEGIN, END, launch_block(world=world),
                           WORLD_LAUNCH if world else LAUNCH)


def _prose(text: str) -> str:
    return textwrap.fill(text, width=96, break_on_hyphens=False, break_long_words=False)


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def reference() -> str:
    """docs/settings.md: every setting, group by group: its default, what it takes, its doc."""
    lines = [
        "# Settings: every launch argument and its default",
        "",
        f"<!-- Written by {THIS} from the settings table (src/ros_hrc/settings.py): edit the "
        "table, then run it; a unit test fails when this file differs. -->",
        "",
        _prose("The arguments of `hrc.launch` (`roslaunch ros_hrc hrc.launch name:=value ...`; "
               "`--ros-args` lists them with these docs); `world.launch`, the world alone, "
               "takes the world's among them. The same settings are the options of the "
               "programs that take them (`--name-with-dashes`: `despot_mdp`, `despot_pomdp`, "
               "`hrc_experiment`) and the parameters of the nodes. Each default is written "
               "once, in `ros_hrc.settings`; an argument given empty takes it too. Before "
               "anything starts, the launch's pre-flight (`hrc_check`; `rosrun ros_hrc "
               "hrc_check -h` lists the settings as well) refuses a value it does not accept, "
               "in one line naming the argument."),
        "",
        _prose("`auto` is a setting decided from the others (its doc says how); a model's "
               "`auto` is the task's model. A path is taken relative to the directory "
               "roslaunch runs in."),
    ]
    for heading, members in by_group(settings.SETTINGS.values()).items():
        lines += ["", f"## {heading[0].upper()}{heading[1:]}", "",
                  "| argument | default | accepts | what it does |", "|---|---|---|---|"]
        for s in members:
            doc = s.doc if s.in_hrc_launch else f"{s.doc} (world.launch's only)"
            lines.append(f"| `{s.name}` | `{_cell(s.launch_default)}` | "
                         f"{_cell(s.accepted())} | {_cell(doc)} |")
    return "\n".join(lines) + "\n"


def written_files(root: Path = REPO) -> Dict[Path, str]:
    """Each file under ``root`` this writes -> its text as written from the table now."""
    launch, world = root / LAUNCH, root / WORLD_LAUNCH
    return {launch: with_launch_block(launch.read_text(encoding="utf-8")),
            world: with_launch_block(world.read_text(encoding="utf-8"), world=True),
            root / REFERENCE: reference()}


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="make_settings_files", description=__doc__.split(
        "\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 naming each file that differs")
    parser.add_argument("--root", type=Path, default=REPO, help="the repository (default: "
                        "this script's)")
    args = parser.parse_args(argv)
    try:
        files = written_files(args.root)
    except (OSError, MarkersMissing) as exc:
        print(f"make_settings_files: {exc}", file=sys.stderr)
        return 2
    return write_or_check(files, args.check, "make_settings_files",
                          lambda path: f"{path} differs from the settings table "
                                       f"(python {THIS} rewrites it)")

if __name__ == "__main__":
    sys.exit(main())
