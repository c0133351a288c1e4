"""The object to grasp: a small box that rides the belt and can be held by the human or the robot.

Holding is a fixed constraint between the holder's hand (or gripper) link and the object, made
at the pose they have when the grasp closes: the object moves with the hand from then on and
does not jump into it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np

from ..errors import SimulationError
from .client import PhysicsClient

#: Collision group of the object (Bullet's default dynamic bit).
OBJECT_GROUP = 1
#: The object touches only dynamic (1) and static (2) bodies: not the human (4) or robot (8),
#: whose motions are scripted and would otherwise knock it about.
OBJECT_MASK = 1 | 2

NOBODY = "none"


@dataclass(frozen=True)
class ObjectConfig:
    """The object's size, mass and where a reset puts it."""

    size: float = 0.06                                  # edge of the cube, m
    mass: float = 0.2                                   # kg
    start: Tuple[float, float] = (-0.70, 0.0)           # x, y on the belt after a reset, m
    colour: Tuple[float, float, float, float] = (0.85, 0.10, 0.10, 1.0)


class WorkObject:
    """The object, its holder (``"none"``, ``"human"`` or ``"robot"``) and its hold constraint."""

    def __init__(self, client: PhysicsClient, config: ObjectConfig, surface_height: float) -> None:
        self.client = client
        self.config = config
        half = config.size / 2
        self._start = [config.start[0], config.start[1], surface_height + half + 0.001]
        shape = client.createCollisionShape(client.GEOM_BOX, halfExtents=[half] * 3)
        visual = client.createVisualShape(client.GEOM_BOX, halfExtents=[half] * 3,
                                          rgbaColor=list(config.colour))
        self.body_id = client.createMultiBody(baseMass=config.mass, baseCollisionShapeIndex=shape,
                                              baseVisualShapeIndex=visual, basePosition=self._start)
        # A resting box would fall asleep and stop feeling the belt: keep it awake.
        client.changeDynamics(self.body_id, -1, lateralFriction=0.8, rollingFriction=0.001,
                              activationState=client.ACTIVATION_STATE_DISABLE_SLEEPING)
        client.setCollisionFilterGroupMask(self.body_id, -1, OBJECT_GROUP, OBJECT_MASK)
        self.holder = NOBODY
        self._constraint: Optional[int] = None

    @property
    def start_position(self) -> np.ndarray:
        """Where a reset puts the object (centre, world frame)."""
        return np.array(self._start)

    def position(self) -> np.ndarray:
        """Centre of the object in the world frame."""
        return np.array(self.client.getBasePositionAndOrientation(self.body_id)[0])

    def pose(self) -> Tuple[Tuple[float, ...], Tuple[float, ...]]:
        """Position and quaternion (x, y, z, w) of the object."""
        return self.client.getBasePositionAndOrientation(self.body_id)

    def attach(self, holder: str, body_id: int, link_index: int,
               link_pose: Tuple[Sequence[float], Sequence[float]]) -> None:
        """Hold the object rigidly in ``holder``'s link (whose centre-of-mass pose is ``link_pose``)."""
        if self.holder != NOBODY:
            raise SimulationError(f"the object is already held by the {self.holder}")
        link_position, link_orientation = link_pose
        position, orientation = self.pose()
        inverse = self.client.invertTransform(link_position, link_orientation)
        relative = self.client.multiplyTransforms(inverse[0], inverse[1], position, orientation)
        self._constraint = self.client.createConstraint(
            body_id, link_index, self.body_id, -1, self.client.JOINT_FIXED, [0, 0, 0],
            relative[0], [0, 0, 0], relative[1], [0, 0, 0, 1])
        self.client.changeConstraint(self._constraint, maxForce=200)
        self.holder = holder

    def release(self) -> None:
        """Let go (the object falls from where it is). No-op when nobody holds it."""
        if self._constraint is not None:
            self.client.removeConstraint(self._constraint)
        self._constraint = None
        self.holder = NOBODY

    def reset(self) -> None:
        """Release and put the object back at its start on the belt, at rest."""
        self.release()
        self.client.resetBasePositionAndOrientation(self.body_id, self._start, [0, 0, 0, 1])
        self.client.resetBaseVelocity(self.body_id, [0, 0, 0], [0, 0, 0])
