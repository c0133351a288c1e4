"""The world's bodies, built in its two PyBullet servers (:class:`~.scene.World` steps them).

Two PyBullet servers, because only the object needs dynamics:

* the **physics** server simulates what contact matters for: the floor, the belt (which
  carries the object by friction), its rails and end stop, and the object. It steps at
  ``time_step`` (240 Hz), ``substeps`` physics steps per control step.
* the **scene** server (``World.client``; the window with ``gui``) holds every body as it is
  seen: the same scenery, a copy of the object, the human and the robot. It is never stepped:
  the agents' joints are set along their scripted motions (they touch nothing: holding is
  done by the world, not by contact), and the object's copy is put where the physics put the
  object. Rays (line of sight), images and the agents' geometry are read here.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable, NamedTuple, Optional

import numpy as np

from .client import PhysicsClient
from .config import WorldConfig
from .conveyor import STATIC_GROUP, STATIC_MASK, Conveyor
from .human import Human
from .object import WorkObject
from .robot import Robot
from .window import Window


class Stage(NamedTuple):
    """The bodies of a world."""

    floor_id: int          # the floor in the scene server
    scenery: Conveyor      # the belt as seen (and as it blocks a line of sight), never moving
    conveyor: Conveyor     # the belt that carries the object, in the physics server
    object: WorkObject
    human: Human
    robot: Robot


def build_stage(client: PhysicsClient, physics: PhysicsClient, config: WorldConfig, model_dir: Path,
                control_period: float, rng: np.random.Generator,
                predict: Callable[[float], np.ndarray], window: Optional[Window] = None) -> Stage:
    """Set up the ``physics`` server and build every body: in the scene server ``client``
    and, for the floor, the belt and the object, in ``physics``. ``predict``: where the object
    will be in so many seconds, for the robot; ``window``: shows the floor while the rest loads."""
    # One stepSimulation() is a control step of `substeps` physics steps of `time_step`.
    physics.setTimeStep(control_period)
    # Pyramid friction instead of the friction cone: a third cheaper, and on a belt that
    # pulls along x the object's path is the same to 0.1 mm (docs/performance.md).
    physics.setPhysicsEngineParameter(numSolverIterations=config.solver_iterations,
                                      numSubSteps=config.substeps, enableConeFriction=0)
    physics.setGravity(0, 0, -9.81)
    floor_id = _floor(client)
    if window is not None:
        window.hold(floor_id)
    _floor(physics)
    scenery = Conveyor(client, config.conveyor, 0.0)
    conveyor = Conveyor(physics, config.conveyor, config.belt_speed)
    work_object = WorkObject(client, physics, config.work_object, config.conveyor.surface_height)
    human = Human(client, str(model_dir / "human.urdf"), config.human, control_period,
                  work_object, rng, config.split_visuals)
    robot = Robot(client, str(model_dir / "pr2_like.urdf"), config.robot, control_period,
                  work_object, config.split_visuals, predict)
    return Stage(floor_id, scenery, conveyor, work_object, human, robot)


def _floor(client: PhysicsClient) -> int:
    plane = client.createCollisionShape(client.GEOM_PLANE)
    # Wide: from the window's camera the floor, not the sky, fills the background.
    look = client.createVisualShape(client.GEOM_BOX, halfExtents=[15, 15, 0.005],
                                    rgbaColor=[0.80, 0.80, 0.78, 1], visualFramePosition=[0, 0, -0.005])
    floor = client.createMultiBody(0, plane, look)
    client.setCollisionFilterGroupMask(floor, -1, STATIC_GROUP, STATIC_MASK)
    return floor
