"""The object to grasp: a small box that rides the belt and can be held by the human or the robot.

The object lives in both of the world's PyBullet servers (see :mod:`.scene`): a dynamic body in
the physics server, where the belt carries it by friction, and a copy in the scene server,
where the agents are, so that rays (line of sight) and images see it. The physics body is the
truth; :meth:`WorkObject.after_step` copies its pose to the scene after every control step.

Holding: when a grasp closes, the object's pose relative to the holder's hand (or gripper)
link is kept, and after every control step the object is put back at that pose relative to
the hand: it moves with the hand from then on and does not jump into it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, Sequence, Tuple

import numpy as np

from ..errors import SimulationError
from .client import PhysicsClient

#: Collision group of the object (Bullet's default dynamic bit).
OBJECT_GROUP = 1
#: The object touches only dynamic (1) and static (2) bodies: not the human (4) or robot (8),
#: whose motions are scripted and would otherwise knock it about.
OBJECT_MASK = 1 | 2

NOBODY = "none"

#: A position and a quaternion (x, y, z, w), as PyBullet gives them.
Pose = Tuple[Sequence[float], Sequence[float]]


@dataclass(frozen=True)
class ObjectConfig:
    """The object's size, mass and where a reset puts it."""

    size: float = 0.06                                  # edge of the cube, m
    mass: float = 0.2                                   # kg
    start: Tuple[float, float] = (-0.70, 0.0)           # x, y on the belt after a reset, m
    #: Green: a colour of its own, far from every body's (the robot's gripper is red, the
    #: belt's stop yellow, the human's shirt blue), so the object shows in any hand.
    colour: Tuple[float, float, float, float] = (0.10, 0.78, 0.25, 1.0)


class WorkObject:
    """The object, its holder (``"none"``, ``"human"`` or ``"robot"``) and how it is held.

    ``client`` is the scene server (``body_id`` is the object's copy there, the one rays hit);
    ``physics`` the server that simulates it (``physics_id``).
    """

    def __init__(self, client: PhysicsClient, physics: PhysicsClient, config: ObjectConfig,
                 surface_height: float) -> None:
        self.client = client
        self.physics = physics
        self.config = config
        half = config.size / 2
        self._start = [config.start[0], config.start[1], surface_height + half + 0.001]
        # A rigid body, not a one-link multibody: a fifth cheaper per step, same path on the belt.
        self.physics_id = self._create(physics, config.mass, rigid_body=True)
        # A resting box would fall asleep and stop feeling the belt: keep it awake.
        physics.changeDynamics(self.physics_id, -1, lateralFriction=0.8, rollingFriction=0.001,
                               activationState=physics.ACTIVATION_STATE_DISABLE_SLEEPING)
        self.body_id = self._create(client, 0.0)   # never simulated: only placed
        self.holder = NOBODY
        #: Why nobody can take the object any more ("" while it can be taken): the world sets
        #: it when the object fell into the tray at the belt's end (``WorldConfig.end_tray``).
        self.gone = ""
        # While held: the hand's pose, and the object's pose in the hand's frame.
        self._hand: Optional[Callable[[], Pose]] = None
        self._in_hand: Optional[Pose] = None

    def _create(self, client: PhysicsClient, mass: float, rigid_body: bool = False) -> int:
        half = self.config.size / 2
        shape = client.createCollisionShape(client.GEOM_BOX, halfExtents=[half] * 3)
        visual = client.createVisualShape(client.GEOM_BOX, halfExtents=[half] * 3,
                                          rgbaColor=list(self.config.colour))
        body = client.createMultiBody(baseMass=mass, baseCollisionShapeIndex=shape,
                                      baseVisualShapeIndex=visual, basePosition=self._start,
                                      useMaximalCoordinates=rigid_body)
        client.setCollisionFilterGroupMask(body, -1, OBJECT_GROUP, OBJECT_MASK)
        return body

    @property
    def start_position(self) -> np.ndarray:
        """Where a reset puts the object (centre, world frame)."""
        return np.array(self._start)

    def position(self) -> np.ndarray:
        """Centre of the object in the world frame."""
        return np.array(self.physics.getBasePositionAndOrientation(self.physics_id)[0])

    def pose(self) -> Pose:
        """Position and quaternion (x, y, z, w) of the object."""
        return self.physics.getBasePositionAndOrientation(self.physics_id)

    def attach(self, holder: str, hand: Callable[[], Pose]) -> None:
        """Hold the object rigidly, where it is now, in the hand whose pose ``hand()`` gives
        (a link of a body in the scene server)."""
        if self.holder != NOBODY:
            raise SimulationError(f"the object is already held by the {self.holder}")
        self._hand = hand
        hand_position, hand_orientation = hand()
        position, orientation = self.pose()
        inverse = self.client.invertTransform(hand_position, hand_orientation)
        self._in_hand = self.client.multiplyTransforms(inverse[0], inverse[1], position, orientation)
        self.holder = holder

    def release(self) -> None:
        """Let go (the object falls from where it is). No-op when nobody holds it."""
        self._hand = self._in_hand = None
        self.holder = NOBODY

    def after_step(self) -> None:
        """After a control step: a held object goes where the hand took it; the scene's copy
        goes where the physics put the object."""
        if self._hand is not None:
            hand_position, hand_orientation = self._hand()
            self._put(*self.client.multiplyTransforms(hand_position, hand_orientation,
                                                      self._in_hand[0], self._in_hand[1]))
            return
        position, orientation = self.pose()
        self.client.resetBasePositionAndOrientation(self.body_id, position, orientation)

    def reset(self) -> None:
        """Release and put the object back at its start on the belt, at rest."""
        self.release()
        self.gone = ""
        self._put(self._start, [0, 0, 0, 1])

    def _put(self, position: Sequence[float], orientation: Sequence[float]) -> None:
        """Put the object there at rest, and its copy in the scene with it."""
        self.physics.resetBasePositionAndOrientation(self.physics_id, position, orientation)
        self.physics.resetBaseVelocity(self.physics_id, [0, 0, 0], [0, 0, 0])
        self.client.resetBasePositionAndOrientation(self.body_id, position, orientation)
