"""What defines a world: :class:`WorldConfig`, made of each part's config, and where the
agents' models are; :func:`task_world_config`: a world with a task's own facts."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping, Optional, Tuple

from .. import settings
from .camera import CameraConfig
from .conveyor import ConveyorConfig
from .human import HumanConfig
from .object import ObjectConfig
from .robot import RobotConfig
from .window import WindowConfig


def default_model_dir() -> Path:
    """``models/urdf`` of the source tree this module sits in."""
    return Path(__file__).resolve().parents[3] / "models" / "urdf"


@dataclass(frozen=True)
class WorldConfig:
    """Everything that defines a world; the defaults are the scene of docs/world.md."""

    gui: bool = settings.default("gui")
    seed: int = settings.default("seed")
    time_step: float = 1.0 / 240.0   # physics step, s
    substeps: int = 4                # physics steps per control step (motions, clock, requests)
    # The physics server holds one dynamic body (the object on the belt): 10 iterations carry
    # it exactly as 20 or PyBullet's 50 do (docs/performance.md), at half the cost of 20.
    solver_iterations: int = 10
    belt_speed: float = settings.default("belt_speed")  # m/s, downstream (+x)
    #: Simulated seconds from the task's start (a world reset, or /human/reset, which puts the
    #: object back) during which the belt stands still; then it runs (0: it runs from the
    #: start, the seed's world). FABRIC's task timer starts the belt 45 s into a task.
    belt_start: float = 0.0
    #: Once running, the belt runs at the speed that carries the object from its start to the
    #: belt's end in this many seconds, instead of belt_speed (0: belt_speed). FABRIC runs it
    #: 7 s, "until the task reaches a failure".
    belt_run: float = 0.0
    #: The belt's end drops the object into a tray (FABRIC's unprocessed tray): an object
    #: that reached it is gone, and nobody can take it any more (False: an end stop holds it
    #: where the robot can still reach it, the seed's world).
    end_tray: bool = False
    #: Actions (``agent/action``) answered as soon as their motion starts: the motion goes on
    #: while the caller does something else (a cancel or a reset stops it; another action of
    #: that agent waits for it), and no longer keeps the clock running under pause_when_idle.
    #: FABRIC's robot grasp runs on a thread of its own: ("robot/grasp",). Empty: every call
    #: returns when its motion is over, the seed's world.
    async_actions: Tuple[str, ...] = ()
    conveyor: ConveyorConfig = field(default_factory=ConveyorConfig)
    work_object: ObjectConfig = field(default_factory=ObjectConfig)
    human: HumanConfig = field(default_factory=HumanConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    #: Load the agents in colour layers (see .visuals): None = only in the window, which
    #: otherwise draws each link in one colour.
    split_visuals: Optional[bool] = None
    window: WindowConfig = field(default_factory=WindowConfig)


#: The task facts :func:`task_world_config` knows, and what each sets.
TASK_WORLD_FACTS = {
    "belt_start": "WorldConfig.belt_start",
    "belt_run": "WorldConfig.belt_run",
    "end_tray": "WorldConfig.end_tray",
    "async_actions": "WorldConfig.async_actions",
    "object_start_x": "ObjectConfig.start (x; y stays on the belt's centre line)",
    "robot_plan_time": "RobotConfig.plan_time",
    "robot_delivery_time": "RobotConfig.delivery_time",
}


def task_world_config(facts: Mapping[str, Any], **given: Any) -> WorldConfig:
    """The world of a task whose world has facts of its own (``facts``: names of
    :data:`TASK_WORLD_FACTS` -> values; empty: the default world, the seed's), with the other
    fields of :class:`WorldConfig` as ``given``. An unknown fact is a ValueError naming it."""
    unknown = sorted(set(facts) - set(TASK_WORLD_FACTS))
    if unknown:
        raise ValueError(f"unknown world facts {', '.join(unknown)}; known: "
                         f"{', '.join(TASK_WORLD_FACTS)}")
    config = WorldConfig(**given)
    top = {name: facts[name] for name in ("belt_start", "belt_run", "end_tray") if name in facts}
    if "async_actions" in facts:
        top["async_actions"] = tuple(facts["async_actions"])
    work_object, robot = config.work_object, config.robot
    if "object_start_x" in facts:
        work_object = replace(work_object, start=(float(facts["object_start_x"]),
                                                  config.conveyor.centre_y))
    robot_facts = {field_name: float(facts[name]) for name, field_name in
                   (("robot_plan_time", "plan_time"), ("robot_delivery_time", "delivery_time"))
                   if name in facts}
    if robot_facts:
        robot = replace(robot, **robot_facts)
    return replace(config, work_object=work_object, robot=robot, **top)
