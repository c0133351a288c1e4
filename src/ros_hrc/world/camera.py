"""The cameras on the scene: the fixed snapshot camera, and the window's initial view seen
through PyBullet's window lens; their matrices and the images they take (software renderer,
so it works headless)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence, Tuple

import numpy as np

from .client import PhysicsClient
from .window import WindowConfig

#: PyBullet's window draws with a fixed vertical field of view (its projection matrix has
#: 1/tan(fov/2) = 1), whatever the window's size.
GUI_FOV_DEG = 90.0

#: View and projection matrices, PyBullet's (column-major).
Matrices = Tuple[Sequence[float], Sequence[float]]


@dataclass(frozen=True)
class CameraConfig:
    """The fixed camera of snapshots (:meth:`~.scene.World.render`, ``/hrc/camera/image``).

    It looks as the window does (:class:`~.window.WindowConfig`), from further back through its
    narrower lens: the belt, both agents and both working arms are in view, and the human
    stays in it all the way through a walk-away.
    """

    eye: Tuple[float, float, float] = (-3.31, 1.30, 3.12)
    target: Tuple[float, float, float] = (-0.5, -0.6, 1.0)
    fov_deg: float = 50.0
    width: int = 800
    height: int = 600


def camera_matrices(client: PhysicsClient, camera: CameraConfig, width: int, height: int) -> Matrices:
    """The snapshot camera's matrices for an image of ``width`` x ``height`` pixels."""
    view = client.computeViewMatrix(list(camera.eye), list(camera.target), [0, 0, 1])
    return view, client.computeProjectionMatrixFOV(camera.fov_deg, width / height, 0.05, 20.0)


def window_matrices(client: PhysicsClient, window: WindowConfig, width: int, height: int) -> Matrices:
    """The matrices of the window's initial view (its camera and 90 deg lens)."""
    distance, yaw, pitch, target = window.view()
    view = client.computeViewMatrixFromYawPitchRoll(list(target), distance, yaw, pitch, 0.0, 2)
    return view, client.computeProjectionMatrixFOV(GUI_FOV_DEG, width / height, 0.01, 100.0)


def take_image(client: PhysicsClient, matrices: Matrices, width: int, height: int) -> Sequence[int]:
    """The RGBA pixels of the scene through ``matrices`` (as PyBullet gives them; see
    :func:`rgb`), lit as the window is, with shadows."""
    view, projection = matrices
    image = client.getCameraImage(width, height, view, projection, shadow=1,
                                  lightDirection=[-1.0, -2.0, 4.0], renderer=client.ER_TINY_RENDERER)
    return image[2]


def rgb(pixels: Sequence[int], width: int, height: int) -> np.ndarray:
    """PyBullet's RGBA pixels as an RGB image ``(height, width, 3)`` of uint8."""
    return np.reshape(np.asarray(pixels, dtype=np.uint8), (height, width, 4))[:, :, :3]
