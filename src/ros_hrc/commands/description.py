"""The agents' URDFs as RViz and robot_state_publisher see them (no ROS, no PyBullet).

Both agents' links go into one /tf tree, so each agent's link names get its name as a prefix
(``human/torso``, ``robot/base_footprint``); joint names stay as they are, since each agent's
joint states are published in its own namespace. ``hrc_description AGENT [URDF]`` prints the
result; the launch files set it as ``/<agent>/robot_description``.
"""
from __future__ import annotations

import sys
import xml.etree.ElementTree as ElementTree   # writing only; parsing is defusedxml's
from pathlib import Path
from typing import Optional, Sequence

from defusedxml import ElementTree as SafeElementTree

from ros_hrc.command_line import own_arguments
from ros_hrc.model_files import MODELS_DIR

#: Each agent's URDF in models/urdf.
AGENT_URDF = {"human": "human.urdf", "robot": "pr2_like.urdf"}


def prefixed_description(urdf_text: str, prefix: str) -> str:
    """The URDF with every link named ``<prefix>/<link>``; joints keep their names. The root
    link loses its ``<inertial>``: KDL (robot_state_publisher) cannot use a root link's
    inertia and warned about it at every start. The description only names frames and shapes
    for RViz and /tf; the world's bodies are loaded from the URDF files themselves, where
    PyBullet needs the root's mass, so they do not change."""
    root = SafeElementTree.fromstring(urdf_text)
    children = {joint.find("child").get("link") for joint in root.iter("joint")
                if joint.find("child") is not None}
    for link in root.iter("link"):
        if link.get("name") not in children:
            for inertial in link.findall("inertial"):
                link.remove(inertial)
    for link in root.iter("link"):
        link.set("name", f"{prefix}/{link.get('name')}")
    for joint in root.iter("joint"):
        for end in ("parent", "child"):
            element = joint.find(end)
            if element is not None:
                element.set("link", f"{prefix}/{element.get('link')}")
    return ElementTree.tostring(root, encoding="unicode")


def main(argv: Optional[Sequence[str]] = None) -> int:
    """``hrc_description AGENT [URDF]``: the agent's prefixed URDF on standard output."""
    args = own_arguments(argv)
    if not args or args[0] not in AGENT_URDF or len(args) > 2:
        print(f"usage: hrc_description {{{'|'.join(AGENT_URDF)}}} [URDF]", file=sys.stderr)
        return 2
    agent = args[0]
    path = Path(args[1]) if len(args) == 2 else \
        MODELS_DIR / "urdf" / AGENT_URDF[agent]
    try:
        text = path.read_text(encoding="utf-8")
        sys.stdout.write(prefixed_description(text, agent))
    except (OSError, SafeElementTree.ParseError) as error:
        print(f"hrc_description: {path}: {error}", file=sys.stderr)
        return 2
    return 0
