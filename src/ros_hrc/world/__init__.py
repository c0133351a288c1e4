"""The PyBullet world (no ROS): conveyor, object, human and PR2-like robot.

Entry point: :class:`~ros_hrc.world.scene.World`. One module per body: ``conveyor``,
``object``, ``human``, ``robot``; ``body`` holds what articulated bodies share, ``client``
binds every PyBullet call to one physics server.
"""
from .outcome import Outcome, Reading
from .scene import HUMAN_ACTIONS, PREDICATES, ROBOT_ACTIONS, Ticket, World, WorldConfig
from .window import WindowClosed

__all__ = ["HUMAN_ACTIONS", "PREDICATES", "ROBOT_ACTIONS", "Outcome", "Reading", "Ticket", "World",
           "WorldConfig", "WindowClosed"]
