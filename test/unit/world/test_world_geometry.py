"""Pure helpers of the world: inverse kinematics, timing profile, rotations."""
import math

import numpy as np
import pytest

from ros_hrc.world.geometry import angle_between, min_jerk, quat_to_matrix, two_link_ik, yaw_quaternion


def _forward(elevation, flex, upper, lower):
    return (upper * math.cos(elevation) + lower * math.cos(elevation + flex),
            upper * math.sin(elevation) + lower * math.sin(elevation + flex))


@pytest.mark.parametrize("elbow_up", [False, True])
@pytest.mark.parametrize("target", [(0.5, -0.2), (0.3, 0.3), (0.6, 0.0), (0.1, -0.55)])
def test_two_link_ik_reaches_the_target_on_the_chosen_elbow_side(target, elbow_up):
    elevation, flex = two_link_ik(*target, 0.4, 0.32, elbow_up=elbow_up)
    assert np.allclose(_forward(elevation, flex, 0.4, 0.32), target, atol=1e-9)
    assert (flex <= 0) if elbow_up else (flex >= 0)


def test_two_link_ik_refuses_targets_out_of_reach_or_too_close():
    assert two_link_ik(0.8, 0.0, 0.4, 0.32) is None
    assert two_link_ik(0.05, 0.0, 0.4, 0.32) is None


def test_min_jerk_starts_and_stops_at_rest():
    assert min_jerk(0.0) == 0.0 and min_jerk(1.0) == 1.0 and min_jerk(0.5) == pytest.approx(0.5)
    assert min_jerk(-1.0) == 0.0 and min_jerk(2.0) == 1.0
    eps = 1e-4
    assert min_jerk(eps) / eps < 1e-6  # zero velocity at the start


def test_yaw_quaternion_turns_x_towards_y():
    rotation = quat_to_matrix(yaw_quaternion(math.pi / 2))
    assert np.allclose(rotation @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    assert angle_between([1, 0, 0], [0, 0, 2]) == pytest.approx(math.pi / 2)
