"""What defines a world: :class:`WorldConfig`, made of each part's config, and where the
agents' models are."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

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
    conveyor: ConveyorConfig = field(default_factory=ConveyorConfig)
    work_object: ObjectConfig = field(default_factory=ObjectConfig)
    human: HumanConfig = field(default_factory=HumanConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    #: Load the agents in colour layers (see .visuals): None = only in the window, which
    #: otherwise draws each link in one colour.
    split_visuals: Optional[bool] = None
    window: WindowConfig = field(default_factory=WindowConfig)
