"""What the overlay reads of PyBullet's camera: a window being closed answers a size of 0 and
matrices of zeros, and the overlay must then place nothing rather than fail the step that
drew it (CI: Escape during a step raised 'Singular matrix' in /human/attempt_grasp)."""
import numpy as np

from ros_hrc.world.window import camera_has_view, screen_points


def perspective(fov_deg=60.0, aspect=4 / 3, near=0.01, far=100.0):
    f = 1.0 / np.tan(np.radians(fov_deg) / 2)
    return np.array([[f / aspect, 0, 0, 0], [0, f, 0, 0],
                     [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)],
                     [0, 0, -1, 0]])


def camera(width, height, view, projection):
    # getDebugVisualizerCamera's first four fields; its matrices are column-major.
    return (width, height, tuple(view.T.ravel()), tuple(projection.T.ravel()))


def test_a_window_with_a_view_has_one_and_its_points_can_be_placed():
    cam = camera(1024, 768, np.eye(4), perspective())
    assert camera_has_view(cam)
    assert len(screen_points(cam, [(10, 10), (10, 40)])) == 2


def test_a_closing_window_has_no_view():
    assert not camera_has_view(camera(0, 0, np.zeros((4, 4)), np.zeros((4, 4))))
    assert not camera_has_view(camera(1024, 768, np.zeros((4, 4)), perspective()))
