"""Every visual keeps its colour in PyBullet's window: a link's visuals split by colour into layers.

PyBullet's OpenGL window (the example browser) draws each link as one mesh with one colour:
the visuals of a link are merged, and the merged mesh takes the colour of the link's last
visual (``changeVisualShape(..., shapeIndex=i)`` recolours the whole link there too). The
software renderer of snapshots (TinyRenderer) colours each visual on its own, so only the
window is wrong: a shirt in skin colour, a robot base all dark.

The fix keeps the body the world moves and measures exactly as it is, and adds twins:

* layer 0 is the URDF with, in each link, only the visuals of the link's first colour. Its
  links, joints, inertials and collision shapes are the URDF's, so link and joint indices,
  kinematics and rays are unchanged;
* layer k (k >= 1) is the same kinematic tree with, in each link, only the visuals of the link's
  (k+1)-th colour and no collision shapes (rays and contacts pass through it). The world puts its
  joints wherever it puts layer 0's (:meth:`~.body.ArticulatedBody.command`).

Colours are told apart by their RGBA value (a named material or an inline ``<color>``).
"""
from __future__ import annotations

import copy
import os
from typing import Dict, List, Optional, Tuple
from xml.etree import ElementTree

Colour = Optional[Tuple[float, ...]]
#: Specular colour of the scenery and the agents: nearly matt, since PyBullet's window puts a
#: glaring highlight on large or shiny faces with its default.
MATT_SPECULAR = (0.08, 0.08, 0.08)


def _materials(robot: ElementTree.Element) -> Dict[str, Colour]:
    """The URDF's named materials (top-level ``<material>``) and their RGBA."""
    named: Dict[str, Colour] = {}
    for material in robot.findall("material"):
        named[material.get("name", "")] = _rgba(material)
    return named


def _rgba(material: Optional[ElementTree.Element]) -> Colour:
    colour = material.find("color") if material is not None else None
    if colour is None or colour.get("rgba") is None:
        return None
    return tuple(round(float(x), 4) for x in colour.get("rgba").split())


def visual_colour(visual: ElementTree.Element, named: Dict[str, Colour]) -> Colour:
    """The RGBA a visual is drawn in (None: no colour given)."""
    material = visual.find("material")
    if material is None:
        return None
    inline = _rgba(material)
    return inline if inline is not None else named.get(material.get("name", ""))


def link_colours(urdf_text: str) -> Dict[str, List[Colour]]:
    """Per link, the distinct colours of its visuals in order of first appearance."""
    robot = ElementTree.fromstring(urdf_text)
    named = _materials(robot)
    out: Dict[str, List[Colour]] = {}
    for link in robot.findall("link"):
        colours: List[Colour] = []
        for visual in link.findall("visual"):
            colour = visual_colour(visual, named)
            if colour not in colours:
                colours.append(colour)
        out[link.get("name", "")] = colours
    return out


def visual_layers(urdf_text: str, base_dir: Optional[str] = None) -> List[str]:
    """The URDF split into layers by colour (see the module docstring); one layer, the URDF
    itself, when no link has visuals of two colours.

    ``base_dir``: the URDF's directory; relative mesh file names are made absolute against it,
    since the layers are loaded from elsewhere.
    """
    colours = link_colours(urdf_text)
    count = max((len(c) for c in colours.values()), default=1)
    if count <= 1:
        return [urdf_text]
    source = ElementTree.fromstring(urdf_text)
    named = _materials(source)
    if base_dir:
        for mesh in source.iter("mesh"):
            name = mesh.get("filename", "")
            if name and "://" not in name and not os.path.isabs(name):
                mesh.set("filename", os.path.join(base_dir, name))
    layers = []
    for k in range(count):
        robot = copy.deepcopy(source)
        for link in robot.findall("link"):
            order = colours[link.get("name", "")]
            for visual in link.findall("visual"):
                if order.index(visual_colour(visual, named)) != k:
                    link.remove(visual)
            if k > 0:
                for collision in link.findall("collision"):
                    link.remove(collision)
        if k > 0:
            robot.set("name", f"{robot.get('name', 'body')}__colour{k}")
        layers.append(ElementTree.tostring(robot, encoding="unicode"))
    return layers
