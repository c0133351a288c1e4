"""Small geometry helpers shared by the bodies: rotations, timing profiles, two-link IK.

Pure numpy: no physics server needed, so they are tested on their own.
"""
from __future__ import annotations

import math
from typing import Optional, Sequence, Tuple

import numpy as np

Vector = np.ndarray


def quat_to_matrix(quaternion: Sequence[float]) -> np.ndarray:
    """3x3 rotation matrix of a unit quaternion given as x, y, z, w (PyBullet's order)."""
    x, y, z, w = quaternion
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def yaw_quaternion(yaw: float) -> Tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of a rotation by ``yaw`` radians about the world z axis."""
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def rot_y(angle: float) -> np.ndarray:
    """Rotation matrix about y (positive tips +x down towards -z, +z towards +x)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def angle_between(u: Sequence[float], v: Sequence[float]) -> float:
    """Angle in radians between two non-zero vectors."""
    u, v = np.asarray(u, float), np.asarray(v, float)
    cosine = float(np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v)))
    return math.acos(max(-1.0, min(1.0, cosine)))


def min_jerk(fraction: float) -> float:
    """Minimum-jerk progress 0..1 for time fraction 0..1: smooth start and stop, like a person's reach."""
    s = max(0.0, min(1.0, fraction))
    return s * s * s * (10 - 15 * s + 6 * s * s)


def wrap_angle(angle: float) -> float:
    """Angle folded into [-pi, pi)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def two_link_ik(forward: float, up: float, upper: float, lower: float,
                elbow_up: bool = False) -> Optional[Tuple[float, float]]:
    """Planar two-link inverse kinematics.

    The chain starts at the origin of a vertical plane (``forward``, ``up``). Returns
    ``(elevation, flex)``: the first link's angle above the forward axis, and the second link's
    angle relative to the first (positive: bends upwards). By default the elbow lies below the
    shoulder-target line (flex >= 0); ``elbow_up`` gives the other solution (flex <= 0).
    None when the target is farther than ``upper + lower`` or closer than ``|upper - lower|``.
    """
    distance = math.hypot(forward, up)
    if distance > upper + lower or distance < abs(upper - lower) or distance < 1e-9:
        return None
    cos_flex = (distance * distance - upper * upper - lower * lower) / (2 * upper * lower)
    flex = math.acos(max(-1.0, min(1.0, cos_flex)))
    # Bending up (positive flex) puts the elbow under the line, so the first link dips below it.
    tilt = math.atan2(lower * math.sin(flex), upper + lower * math.cos(flex))
    if elbow_up:
        return math.atan2(up, forward) + tilt, -flex
    return math.atan2(up, forward) - tilt, flex


def clamp_to_sphere(point: Vector, centre: Vector, radius: float) -> Vector:
    """``point`` moved towards ``centre`` until it lies within ``radius`` of it."""
    offset = np.asarray(point, float) - np.asarray(centre, float)
    distance = float(np.linalg.norm(offset))
    if distance <= radius or distance < 1e-12:
        return np.asarray(point, float)
    return np.asarray(centre, float) + offset * (radius / distance)
