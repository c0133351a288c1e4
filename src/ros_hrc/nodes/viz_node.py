"""hrc_viz: the step as RViz markers, from /hrc/status and hrc_world's /hrc/caption.

Publishes ``/hrc/markers`` (``visualization_msgs/MarkerArray``, latched) on every step and
every change of the caption:

* ``belief``: one bar per state of the robot's model, its height the robot's belief in that
  state; the true state (which the robot never sees) in orange, the needs-help states S2..S5
  in blue, the others in grey; each with its name and probability underneath;
* ``step``: the step being played above the scene: ``/hrc/caption`` from hrc_world (the
  action under way, then its outcome, then the step's report; cleared on reset:
  :class:`ros_hrc.loop.display.StepCaption`), or without it the last step's lines
  (:func:`ros_hrc.loop.display.status_lines`), wrapped to ``~caption_columns`` characters
  (:func:`ros_hrc.world.wrap.wrap_lines`); a reset's caption clears the bars and the holder
  too;
* ``holder``: who holds the object, floating straight over it at a fixed height above the
  tallest body, so that no body hides it from RViz's default view (frame ``object_floor``,
  which hrc_world's /tf puts on the floor under the object, turned as the world: the label
  stays over the object at its height whoever carries the object where), with a thin line
  down to the belt's height;
* ``scenery``: the belt (frame ``belt``) and the object (frame ``object``) as boxes, which no
  URDF describes (published once, latched, and with every step).

Parameters (:class:`VizNodeConfig`, read once: :func:`ros_hrc.nodes.common.read_config`):
``~frame`` (``world``), ``~bars_origin`` ([x, y, z] of the first bar's foot, m; the bars run
along +y), ``~bar_spacing`` (m), ``~bar_height`` (m: a belief of 1), ``~text_position``
([x, y, z]: the caption's centre; RViz centres a text on its position), ``~caption_columns``
(characters a caption line is wrapped to), ``~holder_height`` (m: the holder's label above the
floor, under the object), ``~belt_size`` ([length, width, thickness], m; default the world's belt)
and ``~object_size`` (edge, m; default the world's object).

Where the texts and bars go: from RViz's default view (``launch/hrc.rviz``: from in front of
the belt, above it, the human on the left and the robot on the right) they sit in the sky
above the bodies, where no body hides them whatever the agents do (a human who walks away
comes towards that view, on its left; the human's raised arm reaches 2.13 m):
the caption at the top, the belief's bars under it on the left (high enough for a human who
walked away), the holder's label under it over the object. ``test/nodes/test_viz_layout.py`` checks every text's line of sight
against the world's bodies through every action of both agents.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import rospy
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from std_msgs.msg import ColorRGBA, String
from visualization_msgs.msg import Marker, MarkerArray

from ros_hrc.loop.display import belief_bars, holder_text, is_reset_caption, status_lines
from ros_hrc.msg import Status
from ros_hrc.nodes.common import init_node, read_config
from ros_hrc.world.conveyor import BELT_THICKNESS, ConveyorConfig
from ros_hrc.world.object import ObjectConfig
from ros_hrc.world.wrap import wrap_lines

#: The object's colour in the world (PyBullet's window and snapshots).
OBJECT_COLOUR = ObjectConfig().colour

_TRUE = ColorRGBA(0.95, 0.55, 0.10, 1.0)
_HELP = ColorRGBA(0.20, 0.45, 0.85, 0.9)
_OTHER = ColorRGBA(0.60, 0.60, 0.62, 0.9)
_TEXT = ColorRGBA(0.05, 0.05, 0.05, 1.0)
_POINTER = ColorRGBA(0.35, 0.35, 0.38, 0.8)

#: hrc_world's /tf frame on the floor under the object, turned as the world (not as the object).
OBJECT_FLOOR_FRAME = "object_floor"
#: A caption line in RViz is wrapped to this many characters: at the caption's place and
#: RViz's default view, 100 characters take about 700 of the 900 px the view has beside the
#: Displays panel.
CAPTION_COLUMNS = 100
#: The holder's label this high over the floor, m: above the tallest body (the human's
#: raised arm, 2.13 m), below the caption.
HOLDER_LABEL_HEIGHT = 2.15
#: The holder's line runs down to the belt's surface.
_BELT_SURFACE = ConveyorConfig().surface_height
#: The sizes of the texts (a line's height, m).
CAPTION_HEIGHT = 0.075
HOLDER_HEIGHT = 0.05


def _pose(x: float, y: float, z: float) -> Pose:
    return Pose(position=Point(x, y, z), orientation=Quaternion(0, 0, 0, 1))


def _marker(frame: str, ns: str, mid: int, kind: int, stamp) -> Marker:
    m = Marker()
    m.header.frame_id = frame
    m.header.stamp = stamp
    m.ns, m.id, m.type, m.action = ns, mid, kind, Marker.ADD
    m.frame_locked = True
    return m


def _text(frame: str, ns: str, mid: int, stamp, text: str, where: Sequence[float],
          height: float) -> Marker:
    m = _marker(frame, ns, mid, Marker.TEXT_VIEW_FACING, stamp)
    m.pose = _pose(*where)
    m.scale = Vector3(0, 0, height)
    m.color = _TEXT
    m.text = text
    return m


def scenery_markers(belt_size: Sequence[float], object_size: float, stamp=None) -> List[Marker]:
    """The belt and the object as boxes in their own frames (from hrc_world's /tf)."""
    stamp = stamp if stamp is not None else rospy.Time(0)
    belt = _marker("belt", "scenery", 0, Marker.CUBE, stamp)
    belt.pose = _pose(0, 0, 0)
    belt.scale = Vector3(*belt_size)
    belt.color = ColorRGBA(0.15, 0.15, 0.17, 1.0)
    thing = _marker("object", "scenery", 1, Marker.CUBE, stamp)
    thing.pose = _pose(0, 0, 0)
    thing.scale = Vector3(object_size, object_size, object_size)
    thing.color = ColorRGBA(*OBJECT_COLOUR)   # as in the world: a colour of its own
    return [belt, thing]


def caption_marker(text: str, frame: str, text_at: Sequence[float], stamp=None,
                   columns: int = CAPTION_COLUMNS) -> Marker:
    """The step's text (``step``) above the scene, its lines wrapped to ``columns``."""
    stamp = stamp if stamp is not None else rospy.Time(0)
    wrapped = "\n".join(wrap_lines(text.split("\n"), columns))
    return _text(frame, "step", 0, stamp, wrapped, text_at, CAPTION_HEIGHT)


def holder_markers(text: str, height: float, stamp=None) -> List[Marker]:
    """Who holds the object (``holder``): the label ``height`` m over the floor, straight over
    the object, and a thin line from just under it down to the belt's surface."""
    stamp = stamp if stamp is not None else rospy.Time(0)
    label = _text(OBJECT_FLOOR_FRAME, "holder", 0, stamp, text, (0, 0, height), HOLDER_HEIGHT)
    line = _marker(OBJECT_FLOOR_FRAME, "holder", 1, Marker.LINE_LIST, stamp)
    line.pose = _pose(0, 0, 0)
    line.scale = Vector3(0.006, 0, 0)
    line.color = _POINTER
    line.points = [Point(0, 0, _BELT_SURFACE), Point(0, 0, height - HOLDER_HEIGHT)]
    return [label, line]


def status_markers(status, frame: str, origin: Sequence[float], spacing: float,
                   height: float, text_at: Sequence[float], stamp=None,
                   caption: Optional[str] = None, columns: int = CAPTION_COLUMNS,
                   holder_height: float = HOLDER_LABEL_HEIGHT) -> MarkerArray:
    """The markers of one step (module docstring); ``caption``: the step's text (default: the
    step's report, :func:`status_lines`), wrapped to ``columns``; the holder's label
    ``holder_height`` m over the floor."""
    stamp = stamp if stamp is not None else rospy.Time(0)
    markers: List[Marker] = []
    x0, y0, z0 = origin
    for i, bar in enumerate(belief_bars(status)):
        y = y0 + i * spacing    # along the belt's width: across the default view
        h = max(bar.probability, 0.0) * height
        cube = _marker(frame, "belief", i, Marker.CUBE, stamp)
        cube.pose = _pose(x0, y, z0 + max(h, 0.002) / 2)
        cube.scale = Vector3(0.04, spacing * 0.7, max(h, 0.002))
        cube.color = _TRUE if bar.true_state else (_HELP if bar.needs_help else _OTHER)
        markers.append(cube)
        label = f"{bar.state}{'*' if bar.true_state else ''}\n{bar.probability:.2f}"
        markers.append(_text(frame, "belief_labels", i, stamp, label, (x0, y, z0 - 0.09), 0.05))
    markers.append(_text(frame, "belief_title", 0, stamp,
                         "robot's belief (* true state, orange)",
                         (x0, y0 + spacing * 3, z0 + height + 0.09), 0.06))
    text = caption if caption is not None else "\n".join(status_lines(status))
    markers.append(caption_marker(text, frame, text_at, stamp, columns))
    markers.extend(holder_markers(holder_text(getattr(status, "object_holder", "none")),
                                  holder_height, stamp))
    return MarkerArray(markers=markers)


_BELT = ConveyorConfig()


@dataclass(frozen=True)
class VizNodeConfig:
    """The node's parameters (module docstring); the scenery's sizes are the world's."""

    frame: str = "world"
    bars_origin: Tuple[float, ...] = (-1.3, -1.35, 1.75)
    bar_spacing: float = 0.13
    bar_height: float = 0.3
    text_position: Tuple[float, ...] = (-0.55, 0.1, 2.48)
    caption_columns: int = CAPTION_COLUMNS
    holder_height: float = HOLDER_LABEL_HEIGHT
    belt_size: Tuple[float, ...] = (_BELT.length, _BELT.width, BELT_THICKNESS)
    object_size: float = ObjectConfig().size


class VizNode:
    def __init__(self, config: VizNodeConfig) -> None:
        self.frame = config.frame
        self.origin = config.bars_origin
        self.spacing = config.bar_spacing
        self.height = config.bar_height
        self.text_at = config.text_position
        self.columns = config.caption_columns
        self.holder_height = config.holder_height
        self.scenery = scenery_markers(config.belt_size, config.object_size)
        self.caption: Optional[str] = None   # hrc_world's caption of the step being played
        self.step: List[Marker] = []          # the last step's bars and labels
        self.lock = threading.Lock()
        self.pub = rospy.Publisher("/hrc/markers", MarkerArray, queue_size=2, latch=True)
        self.pub.publish(MarkerArray(markers=self.scenery))
        rospy.Subscriber("/hrc/status", Status, self._on_status, queue_size=10)
        rospy.Subscriber("/hrc/caption", String, self._on_caption, queue_size=10)

    def _on_status(self, status: Status) -> None:
        if status.fault:
            return   # a failed step carries no decision to show; the caption says it failed
        with self.lock:
            markers = status_markers(status, self.frame, self.origin, self.spacing, self.height,
                                     self.text_at, rospy.Time.now(), self.caption, self.columns,
                                     self.holder_height)
            self.step = [m for m in markers.markers if m.ns != "step"]
            self._publish(markers.markers)

    def _on_caption(self, caption: String) -> None:
        with self.lock:
            self.caption = caption.data
            text = caption_marker(caption.data, self.frame, self.text_at, rospy.Time.now(),
                                  self.columns)
            if is_reset_caption(caption.data):
                # Nothing of the last episode stays: its bars, its holder, its text.
                self.step = []
                clear = Marker(action=Marker.DELETEALL)
                clear.header.frame_id = self.frame
                return self._publish([clear, text])
            self._publish(list(self.step) + [text])

    def _publish(self, markers: List[Marker]) -> None:
        # Latched: a late RViz gets everything at once, the scenery included.
        self.pub.publish(MarkerArray(markers=markers + self.scenery))


def main() -> None:
    """Entry point of ``scripts/hrc_viz``."""
    init_node("hrc_viz")
    VizNode(read_config(VizNodeConfig))
    rospy.loginfo("hrc_viz: the steps of /hrc/status as markers on /hrc/markers")
    rospy.spin()
