"""RViz's texts in sight: from the default view of ``launch/hrc.rviz``, no body of the world
hides any text of hrc_viz's markers, whatever the agents do, each text is inside the view,
and no two texts lie on each other.

No ROS master and no RViz: the world runs headless through every action of both agents, its
bodies' boxes sampled as they move; the markers are hrc_viz's own (``status_markers``, with
its default parameters), the view is read from ``hrc.rviz`` and placed as RViz's orbit view
places its camera. A text's extent is taken from RViz's font as measured on a screenshot
(a character 0.43 of the text's height wide, a line 1.15 of it high), with room to spare.
"""
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from ros_hrc.loop.display import status_lines
from ros_hrc.nodes.viz_node import OBJECT_FLOOR_FRAME, VizNodeConfig, status_markers
from ros_hrc.world import HUMAN_ACTIONS, ROBOT_ACTIONS, World, WorldConfig

RVIZ_FILE = Path(__file__).resolve().parents[2] / "launch" / "hrc.rviz"
#: RViz's 3-D view in hrc.rviz's window (1280 x 800) beside the Displays panel, px: the
#: narrower of the two ways it opens.
VIEW_SIZE = (900, 710)
#: A character's width and a line's height, per unit of a text's height (measured: 0.43, 1.15).
CHAR_WIDTH, LINE_HEIGHT = 0.5, 1.2
STATES = ("S0", "S1", "S2", "S3", "S4", "S5", "S6")


class View:
    """RViz's orbit view from ``hrc.rviz``: its eye, axes and lens."""

    def __init__(self, rviz_file: Path) -> None:
        current = yaml.safe_load(rviz_file.read_text())["Visualization Manager"]["Views"]["Current"]
        focal = np.array([current["Focal Point"][axis] for axis in "XYZ"], dtype=float)
        yaw, pitch, distance = current["Yaw"], current["Pitch"], current["Distance"]
        self.eye = focal + distance * np.array([math.cos(yaw) * math.cos(pitch),
                                                math.sin(yaw) * math.cos(pitch), math.sin(pitch)])
        self.forward = (focal - self.eye) / np.linalg.norm(focal - self.eye)
        self.right = np.cross(self.forward, [0.0, 0.0, 1.0])
        self.right /= np.linalg.norm(self.right)
        self.up = np.cross(self.right, self.forward)
        self.fov = current["Field of View"]   # vertical, radians

    def pixel(self, point: np.ndarray) -> np.ndarray:
        """Where ``point`` shows in the view, px from its top-left corner."""
        width, height = VIEW_SIZE
        offset = point - self.eye
        depth = offset @ self.forward
        scale = height / 2 / math.tan(self.fov / 2) / depth
        return np.array([width / 2 + scale * (offset @ self.right), height / 2 - scale * (offset @ self.up)])


def hides(start: np.ndarray, end: np.ndarray, low: np.ndarray, high: np.ndarray) -> bool:
    """True if the segment from ``start`` to ``end`` passes through the box ``low``..``high``."""
    direction = end - start
    enter, leave = 0.0, 1.0
    for axis in range(3):
        if abs(direction[axis]) < 1e-12:
            if not low[axis] <= start[axis] <= high[axis]:
                return False
            continue
        a = (low[axis] - start[axis]) / direction[axis]
        b = (high[axis] - start[axis]) / direction[axis]
        enter, leave = max(enter, min(a, b)), min(leave, max(a, b))
        if enter > leave:
            return False
    return True


def body_boxes(world: World) -> list:
    """(body, low, high) for every link of both agents and the belt, as they are now."""
    client = world.client
    boxes = []
    for name, body in (("human", world.human.body_id), ("robot", world.robot.body_id),
                       ("belt", world.scenery.belt_id)):
        for link in range(-1, client.getNumJoints(body)):
            low, high = client.getAABB(body, link)
            boxes.append((name, np.array(low), np.array(high)))
    return boxes


def a_step(**over):
    values = dict(step=3, episode=1, human_action="walkAway", human_state="recovery",
                  observation_bits=0, robot_observation="O0", robot_action="rGrasp_obj",
                  robot_state="S3", belief_states=STATES, belief=[0.9, 0, 0, 0.1, 0, 0, 0],
                  object_holder="human", episode_over=True, end_reason="success")
    values.update(over)
    return SimpleNamespace(**values)


#: The longest caption a step shows: its report with a long outcome of the robot's action.
LONG_CAPTION = "\n".join(status_lines(a_step())[:3] + [
    "  -> cannot grasp: the object is out of reach, 1.00 m from the right shoulder (the arm "
    "reaches 0.90 m)"] + status_lines(a_step())[3:])


def texts(markers) -> list:
    """(name, marker) of every text, a name per kind (the belief's labels are one kind)."""
    return [(m.ns, m) for m in markers.markers if m.type == m.TEXT_VIEW_FACING]


def extent(view: View, marker, centre: np.ndarray) -> list:
    """The centre, corners and edge midpoints of a text's block as RViz draws it (centred)."""
    lines = marker.text.split("\n")
    half_width = CHAR_WIDTH * marker.scale.z * max(len(line) for line in lines) / 2
    half_height = LINE_HEIGHT * marker.scale.z * len(lines) / 2
    return [centre + i * half_width * view.right + j * half_height * view.up
            for i in (-1, 0, 1) for j in (-1, 0, 1)]


def where(marker, object_position: np.ndarray) -> np.ndarray:
    position = np.array([marker.pose.position.x, marker.pose.position.y, marker.pose.position.z])
    if marker.header.frame_id == OBJECT_FLOOR_FRAME:
        return np.array([object_position[0], object_position[1], 0.0]) + position
    assert marker.header.frame_id == VizNodeConfig().frame, marker.header.frame_id
    return position


@pytest.fixture(scope="module")
def samples():
    """The world's bodies and the object's place every 0.1 s of simulated time, through every
    action of each agent in turn, each from the start."""
    out = []
    with World(WorldConfig(seed=1)) as world:
        for agent, actions in (("human", HUMAN_ACTIONS), ("robot", ROBOT_ACTIONS)):
            for action in actions:
                ticket = world.submit(agent, action)
                while not ticket.done():
                    world.advance(0.1)
                    out.append((f"{agent}/{action}", body_boxes(world),
                                np.array(world.object.pose()[0])))
                world.reset()
    return out


def step_markers():
    """hrc_viz's markers for a step with a long caption, with the node's default layout."""
    config = VizNodeConfig()
    return status_markers(a_step(), config.frame, config.bars_origin, config.bar_spacing,
                          config.bar_height, config.text_position, caption=LONG_CAPTION,
                          columns=config.caption_columns, holder_height=config.holder_height)


def test_no_body_hides_a_text_from_rviz_s_default_view(samples):
    view, markers = View(RVIZ_FILE), step_markers()
    hidden = set()
    for action, boxes, object_position in samples:
        for name, marker in texts(markers):
            for point in extent(view, marker, where(marker, object_position)):
                for body, low, high in boxes:
                    if hides(view.eye, point, low, high):
                        hidden.add((name, marker.id, body, action))
    assert not hidden, sorted(hidden)


def test_every_text_is_in_the_view_and_on_no_other(samples):
    view, markers = View(RVIZ_FILE), step_markers()
    caption = next(m for name, m in texts(markers) if name == "step")
    assert len(caption.text.split("\n")) > len(LONG_CAPTION.split("\n"))   # it was wrapped
    width, height = VIEW_SIZE
    for _, _, object_position in samples:
        boxes = {}
        for name, marker in texts(markers):
            corners = np.array([view.pixel(p) for p in extent(view, marker, where(marker, object_position))])
            low, high = corners.min(axis=0), corners.max(axis=0)
            assert low[0] >= 0 and low[1] >= 0 and high[0] <= width and high[1] <= height, \
                (name, marker.text, low, high)
            key = "belief" if name.startswith("belief") else name
            old = boxes.get(key)
            boxes[key] = (np.minimum(old[0], low), np.maximum(old[1], high)) if old else (low, high)
        for a in boxes:
            for b in boxes:
                if a < b:
                    (low_a, high_a), (low_b, high_b) = boxes[a], boxes[b]
                    apart = (high_a < low_b).any() or (high_b < low_a).any()
                    assert apart, f"{a} {boxes[a]} lies on {b} {boxes[b]}"
