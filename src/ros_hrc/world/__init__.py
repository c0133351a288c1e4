"""The PyBullet world (no ROS): conveyor, object, human and PR2-like robot.

Entry point: :class:`~ros_hrc.world.scene.World` (its stepping loop and API), configured by
:class:`~ros_hrc.world.config.WorldConfig`. One module per body: ``conveyor``, ``object``,
``human``, ``robot``; ``body`` holds what articulated bodies share, ``stage`` builds them all
in the world's two PyBullet servers, ``client`` binds every PyBullet call to one server.
``tickets``: the actions asked of the world, queued per agent; ``window``: PyBullet's window
(``x11`` names it; ``wrap`` wraps its caption, and RViz's); ``camera``: snapshots.
"""
from .config import WorldConfig
from .outcome import Outcome, Reading
from .scene import HUMAN_ACTIONS, PREDICATES, ROBOT_ACTIONS, World
from .tickets import Ticket
from .window import WindowClosed

__all__ = ["HUMAN_ACTIONS", "PREDICATES", "ROBOT_ACTIONS", "Outcome", "Reading", "Ticket", "World",
           "WorldConfig", "WindowClosed"]
