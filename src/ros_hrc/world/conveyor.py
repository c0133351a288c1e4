"""The conveyor belt: a static frame and a moving surface that carries whatever rests on it.

How the belt carries the object: the belt surface is a fixed-base body whose velocity is set
to the belt speed before every physics step, and whose pose is put back where it belongs.
Bullet treats it as a kinematic body: the contact solver sees a surface moving at the belt
speed, so friction drags the object along exactly as a real belt does (an object held above
the belt, or one blocked by the end stop, slips instead of moving).

The belt's end: an end stop (a bar across the belt) catches the object at the downstream end.
The object waits there, with the belt slipping under it, until someone takes it or a reset
puts it back at the start. It never falls off.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence, Tuple

import numpy as np

from .client import PhysicsClient
from .visuals import MATT_SPECULAR

#: Collision group of static scenery (floor, belt, frame): Bullet's default "static" bit.
#: Scenery collides with the object only (mask 1); PyBullet lets two bodies collide when
#: either one's group is in the other's mask, so both sides are set explicitly.
STATIC_GROUP = 2
STATIC_MASK = 1
#: An unheld object whose downstream face is this close to the end stop has reached the
#: belt's end.
_AT_END_STOP_M = 0.02


@dataclass(frozen=True)
class ConveyorConfig:
    """Geometry of the belt. x runs along the belt, downstream is +x."""

    start_x: float = -1.25        # upstream end of the belt surface, m
    end_x: float = 0.75           # downstream end, m
    centre_y: float = 0.0
    width: float = 0.40
    surface_height: float = 0.90  # top of the belt above the floor, m
    end_stop_height: float = 0.05  # how far the end stop rises above the surface, m

    @property
    def length(self) -> float:
        """Length of the belt surface, m."""
        return self.end_x - self.start_x


#: The belt's thickness, m (its top is ConveyorConfig.surface_height).
BELT_THICKNESS = 0.04
_BELT_COLOUR = (0.15, 0.15, 0.17, 1.0)
_FRAME_COLOUR = (0.62, 0.64, 0.66, 1.0)
_STOP_COLOUR = (0.95, 0.75, 0.10, 1.0)
# Every part is made matt (MATT_SPECULAR) as it is built, not later with the other bodies:
# a body without a collision shape cannot be changed after it is made.


class Conveyor:
    """The belt in one physics client; ``speed`` in m/s (downstream positive)."""

    def __init__(self, client: PhysicsClient, config: ConveyorConfig, speed: float) -> None:
        self.client = client
        self.config = config
        self.speed = speed
        c = config
        mid_x = (c.start_x + c.end_x) / 2
        self._surface_pose = ([mid_x, c.centre_y, c.surface_height - BELT_THICKNESS / 2],
                              [0.0, 0.0, 0.0, 1.0])
        self.belt_id = self._box([c.length / 2, c.width / 2, BELT_THICKNESS / 2],
                                 self._surface_pose[0], _BELT_COLOUR)
        # Friction of the surface: rubber-like, so the belt's pull wins over the object's inertia.
        client.changeDynamics(self.belt_id, -1, lateralFriction=0.9)
        self.frame_ids = self._build_frame()

    def _box(self, half: Sequence[float], position: Sequence[float],
             colour: Tuple[float, float, float, float], collide: bool = True) -> int:
        shape = self.client.createCollisionShape(self.client.GEOM_BOX, halfExtents=list(half)) \
            if collide else -1
        visual = self.client.createVisualShape(self.client.GEOM_BOX, halfExtents=list(half),
                                               rgbaColor=list(colour), specularColor=list(MATT_SPECULAR))
        body = self.client.createMultiBody(baseMass=0, baseCollisionShapeIndex=shape,
                                           baseVisualShapeIndex=visual, basePosition=list(position))
        self.client.setCollisionFilterGroupMask(body, -1, STATIC_GROUP, STATIC_MASK)
        return body

    def _build_frame(self) -> list:
        c = self.config
        below = c.surface_height - BELT_THICKNESS
        ids = []
        # Side rails a little above the surface keep the eye on the belt; they never touch a
        # centred object.
        for side in (-1, 1):
            y = c.centre_y + side * (c.width / 2 + 0.02)
            ids.append(self._box([c.length / 2 + 0.05, 0.02, 0.05],
                                 [(c.start_x + c.end_x) / 2, y, c.surface_height - 0.035], _FRAME_COLOUR))
            for x in (c.start_x + 0.1, c.end_x - 0.1):
                ids.append(self._box([0.03, 0.03, below / 2], [x, y, below / 2], _FRAME_COLOUR,
                                     collide=False))
        # Rollers at both ends (look only).
        for x in (c.start_x, c.end_x):
            shape = self.client.createVisualShape(self.client.GEOM_CYLINDER, radius=BELT_THICKNESS / 2 + 0.01,
                                                  length=c.width, rgbaColor=list(_FRAME_COLOUR),
                                                  specularColor=list(MATT_SPECULAR))
            ids.append(self.client.createMultiBody(
                baseMass=0, baseVisualShapeIndex=shape,
                basePosition=[x, c.centre_y, c.surface_height - BELT_THICKNESS / 2],
                baseOrientation=[0.7071068, 0.0, 0.0, 0.7071068]))
        # The end stop: a bar across the belt just before its downstream end.
        ids.append(self._box([0.015, c.width / 2 + 0.02, (c.end_stop_height + 0.01) / 2],
                             [c.end_x - 0.015, c.centre_y, c.surface_height + (c.end_stop_height - 0.01) / 2],
                             _STOP_COLOUR))
        return ids

    @property
    def surface_pose(self) -> tuple:
        """Position and quaternion of the belt's surface box (its centre), as built."""
        return self._surface_pose

    @property
    def stop_x(self) -> float:
        """x of the end stop's upstream face: where an object waits at the belt's end."""
        return self.config.end_x - 0.03

    def before_step(self) -> None:
        """Give the surface its velocity for the next step and keep it in place (kinematic belt)."""
        position, orientation = self._surface_pose
        self.client.resetBasePositionAndOrientation(self.belt_id, position, orientation)
        self.client.resetBaseVelocity(self.belt_id, [self.speed, 0.0, 0.0], [0.0, 0.0, 0.0])

    def carry(self, position: Sequence[float], half: float, seconds: float) -> np.ndarray:
        """Where the belt takes a box of half-size ``half`` resting at ``position`` in
        ``seconds``: downstream at the belt's speed, and the end stop holds it."""
        x = position[0] + self.speed * max(0.0, seconds)
        x = min(x, max(position[0], self.stop_x - half))   # the stop holds it
        x = max(x, min(position[0], self.config.start_x + half))
        return np.array([x, position[1], position[2]])

    def at_end(self, position: Sequence[float], half: float) -> bool:
        """True when a box of half-size ``half`` at ``position`` has reached the belt's end:
        its downstream face at the end stop (where it rests, its centre ``half`` upstream)."""
        return position[0] + half >= self.stop_x - _AT_END_STOP_M

    def end_x(self, half: float) -> float:
        """x of the centre of a box of half-size ``half`` as it reaches the belt's end
        (:meth:`at_end` from there on)."""
        return self.stop_x - _AT_END_STOP_M - half

    def is_on_belt(self, position: Sequence[float], tolerance: float = 0.08) -> bool:
        """True when ``position`` lies over the belt surface, within ``tolerance`` above it."""
        c = self.config
        x, y, z = position
        return (c.start_x <= x <= c.end_x and abs(y - c.centre_y) <= c.width / 2
                and c.surface_height - 0.01 <= z <= c.surface_height + tolerance)
