"""The agents' descriptions (hrc_description) as robot_state_publisher takes them: a root link
without an inertia (KDL warned about one at every start), every other link as in the URDF,
and the URDF files the world loads left as they are."""
from pathlib import Path
import xml.etree.ElementTree as ElementTree

import pytest

from ros_hrc.commands.description import AGENT_URDF, prefixed_description
from ros_hrc.model_files import MODELS_DIR


def root_link(tree):
    children = {joint.find("child").get("link") for joint in tree.iter("joint")}
    roots = [link for link in tree.iter("link") if link.get("name") not in children]
    assert len(roots) == 1
    return roots[0]


@pytest.mark.parametrize("agent", sorted(AGENT_URDF))
def test_the_root_link_has_no_inertia_and_the_other_links_keep_theirs(agent):
    path = MODELS_DIR / "urdf" / AGENT_URDF[agent]
    text = path.read_text(encoding="utf-8")
    urdf = ElementTree.fromstring(text)
    described = ElementTree.fromstring(prefixed_description(text, agent))
    assert root_link(urdf).find("inertial") is not None     # the world's body needs it
    assert root_link(described).get("name") == f"{agent}/{root_link(urdf).get('name')}"
    assert root_link(described).find("inertial") is None
    inertias = {link.get("name"): ElementTree.tostring(link.find("inertial"))
                for link in urdf.iter("link")
                if link.find("inertial") is not None and link is not root_link(urdf)}
    assert inertias
    for link in described.iter("link"):
        name = link.get("name").split("/", 1)[1]
        if name in inertias:
            assert ElementTree.tostring(link.find("inertial")) == inertias[name]
    assert path.read_text(encoding="utf-8") == text
