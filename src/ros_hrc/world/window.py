"""PyBullet's window (``gui``): its size and view, its set-up as it opens, the overlay's lines
and its closing.

What PyBullet 3.2.x offers and what it does not:

* **Title.** The example browser that draws the window takes ``--width``, ``--height``,
  ``--background_color_red/green/blue`` (and ``--mp4``, ``--opengl2`` ...) as connect
  ``options`` (:func:`window_options`), but no title: :class:`~.x11.WindowNamer` renames the
  window through Xlib.
* **Opening.** The window draws from the moment it opens, before connect() returns: its first
  frames show PyBullet's default scene and panels. Then, with rendering off, it shows the last
  frame drawn. So :class:`Window` turns the panels off and sets the camera at once (an empty
  scene draws in no time); draws the floor and a "loading" line; turns rendering off while the
  rest loads (ten times faster: no frame per shape, no body appearing one by one); turns it on.
* **Overlay.** PyBullet draws debug text at a 3-D point, at a fixed size in pixels, one line
  per item (a newline in the text goes off somewhere in 3-D). :func:`screen_points` gives the
  points in front of the camera that land at given pixels, so lines can be pinned to a corner
  of the window as it is framed. Each added, replaced or removed item waits for a frame of
  the window (50 to 250 ms each with software rendering, measured under Xvfb), and the window
  draws between them: replaced line by line, a caption showed the next step's first line
  over the last step's report for a second. With rendering off the window shows its last
  frame and these calls take no frame, so :meth:`Window.show_overlay` changes every line
  with rendering off: the window goes from one whole caption to the next.
* **Width.** The font is proportional: caption text (letters, digits, spaces, punctuation)
  measured 6.3 to 6.7 px per character per unit of ``textSize`` under Xvfb;
  :func:`overlay_columns` counts 7 to leave room, and the overlay wraps its lines to that many
  characters (:func:`~.wrap.wrap_lines`) for the window's width as it is now.
* **Closing.** Esc ends the window's threads and disconnects the scene server, but not the
  process: :class:`WindowClosed` is what the world raises then. (The window manager's close
  button cuts the window's X connection instead, and Xlib ends the process, status 1: the
  window does not take part in the window manager's close protocol.)
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from contextlib import contextmanager
from typing import Callable, Iterator, List, Sequence, Tuple

import numpy as np

from ..errors import SimulationError
from .client import PhysicsClient
from .visuals import MATT_SPECULAR
from .wrap import wrap_lines
from .x11 import WindowNamer

LOG = logging.getLogger(__name__)

#: The window's title.
WINDOW_TITLE = "ros_hrc: human-robot collaboration (PyBullet)"
#: Named in the window's overlay.
_PACKAGE = "ros_hrc"
#: The overlay: lines from the window's top-left corner, in pixels; their size and colour.
_OVERLAY_MARGIN = (14.0, 26.0)
_OVERLAY_LINE_PX = 22.0
_OVERLAY_TEXT_SIZE = 1.3
#: The width of one character of the overlay's text per unit of text size, px: measured
#: 6.3 to 6.7 on caption lines (module docstring), with room to spare.
_OVERLAY_CHAR_PX = 7.0
#: The fewest characters a line is wrapped to, however narrow the window.
_OVERLAY_MIN_COLUMNS = 20
_OVERLAY_COLOUR = (0.05, 0.06, 0.12)
#: How often the stepping loop looks whether the user moved the window's view, s.
_LOOK_PERIOD = 0.3

#: PyBullet's camera view: distance, yaw and pitch (degrees), target.
View = Tuple[float, float, float, Tuple[float, float, float]]


def _size_and_view(camera: Sequence) -> Tuple[float, ...]:
    """The window's width and height and its view matrix, from ``getDebugVisualizerCamera``."""
    return (float(camera[0]), float(camera[1])) + tuple(camera[2])


class WindowClosed(SimulationError):
    """The PyBullet window was closed (Esc, or the window manager): the scene server is gone,
    so the world cannot go on. Raised by every later call of the world."""

    def __init__(self, message: str = "the PyBullet window was closed: the scene is gone, "
                                      "the world stops") -> None:
        super().__init__(message)


@dataclass(frozen=True)
class WindowConfig:
    """PyBullet's window (``gui``): its size, the colour of its sky, its initial view.

    The view is PyBullet's camera (distance, yaw, pitch in degrees, target): PyBullet's window
    sees 90 deg vertically, much wider than the snapshots' 50, so it has a view of its own. It
    looks from above the belt's upstream end, behind the robot's shoulder, across the belt
    towards the human: the robot on the left, the human on the right, the belt between them,
    and room on the right for where the human's walk-away ends (1.5 m from the belt), so
    both agents stay in frame whatever they do (test_world_window checks every link).
    """

    width: int = 1024
    height: int = 768
    background: Tuple[float, float, float] = (0.86, 0.88, 0.91)
    distance: float = 1.85
    yaw_deg: float = -124.0
    pitch_deg: float = -35.0
    target: Tuple[float, float, float] = (-0.5, -0.6, 1.0)

    def view(self) -> View:
        """The initial view as PyBullet takes it: distance, yaw, pitch (degrees), target."""
        return self.distance, self.yaw_deg, self.pitch_deg, tuple(float(x) for x in self.target)


def window_options(width: int, height: int, background: Sequence[float]) -> str:
    """Connect ``options`` for PyBullet's window: its size and the sky's colour."""
    red, green, blue = background[:3]
    return (f"--width={int(width)} --height={int(height)} --background_color_red={red:.3f} "
            f"--background_color_green={green:.3f} --background_color_blue={blue:.3f}")


def _camera_matrices(camera: Sequence) -> Tuple[np.ndarray, np.ndarray]:
    """The view and projection matrices of ``getDebugVisualizerCamera``'s answer (PyBullet's
    are column-major)."""
    view = np.array(camera[2], dtype=float).reshape(4, 4).T
    projection = np.array(camera[3], dtype=float).reshape(4, 4).T
    return view, projection


def camera_has_view(camera: Sequence) -> bool:
    """Whether ``getDebugVisualizerCamera``'s answer is of a window that shows a view: a window
    being closed answers a size of 0 and matrices of zeros, from which no point can be placed
    (:func:`screen_points` would invert a singular matrix)."""
    if float(camera[0]) <= 0 or float(camera[1]) <= 0:
        return False
    view, projection = _camera_matrices(camera)
    return bool(abs(np.linalg.det(projection @ view)) > 1e-12)


def screen_points(camera: Sequence, pixels: Sequence[Sequence[float]], depth: float = 0.5) -> List[List[float]]:
    """World points ``depth`` metres in front of the camera that show at ``pixels`` ((x, y)
    from the top-left corner). ``camera``: what ``getDebugVisualizerCamera`` returns."""
    width, height = float(camera[0]), float(camera[1])
    view, projection = _camera_matrices(camera)
    inverse = np.linalg.inv(projection @ view)
    # Clip-space depth of a point `depth` in front of the eye (eye space looks down -z).
    clip = projection @ np.array([0.0, 0.0, -depth, 1.0])
    z_ndc = clip[2] / clip[3]
    out = []
    for x, y in pixels:
        ndc = np.array([2.0 * x / width - 1.0, 1.0 - 2.0 * y / height, z_ndc, 1.0])
        world = inverse @ ndc
        out.append((world[:3] / world[3]).tolist())
    return out


def overlay_columns(window_width: float, text_size: float = _OVERLAY_TEXT_SIZE) -> int:
    """How many characters of the overlay's text fit on one line of a window ``window_width``
    px wide, between the overlay's margins (at least 20: in a narrower window a line runs
    off the edge rather than into a column of single words)."""
    usable = float(window_width) - 2.0 * _OVERLAY_MARGIN[0]
    return max(int(usable // (_OVERLAY_CHAR_PX * text_size)), _OVERLAY_MIN_COLUMNS)


class Window:
    """PyBullet's window on the world's scene server ``client``: set up as it opens (see the
    module docstring), the overlay's lines kept in its top-left corner, and whether it is gone.

    The world calls it with ``gui`` only (:meth:`lines` and :attr:`closed` are read in any
    case), under the world's lock once the world is built.
    """

    def __init__(self, client: PhysicsClient, config: WindowConfig) -> None:
        self.client = client
        self.config = config
        self._overlay: List[Tuple[int, str, Tuple[float, ...]]] = []   # (item id, text, where)
        self._caption: List[str] = []                # the lines asked for, before wrapping
        self._rendering = True                       # the window draws (off while loading)
        self._overlay_view: Tuple[float, ...] = ()   # the window's size and view the overlay was placed for
        self._view_seen: Tuple[float, ...] = ()      # the view at the last look
        self._next_look = 0.0                        # when to look at the view again (monotonic s)
        self.closed = False                          # found gone (see check)
        self._closed_listeners: List[Callable[[], None]] = []

    # --- opening -----------------------------------------------------------------------------------
    def open(self, namer: WindowNamer) -> None:
        """Right after the window opened: its title (``namer``, made before it opened),
        PyBullet's panels off, light and camera."""
        c = self.client
        if not namer.name(WINDOW_TITLE):
            LOG.info("PyBullet's window keeps PyBullet's title (no X11 window found to rename)")
        for flag in (c.COV_ENABLE_GUI, c.COV_ENABLE_RGB_BUFFER_PREVIEW, c.COV_ENABLE_DEPTH_BUFFER_PREVIEW,
                     c.COV_ENABLE_SEGMENTATION_MARK_PREVIEW, c.COV_ENABLE_MOUSE_PICKING):
            c.configureDebugVisualizer(flag, 0)
        # Light from above, behind the camera's left, as in the snapshots; shadows sized to
        # the scene.
        c.configureDebugVisualizer(lightPosition=[-3.0, -2.0, 6.0], shadowMapWorldSize=6,
                                   shadowMapResolution=1024, shadowMapIntensity=0.35)
        distance, yaw, pitch, target = self.config.view()
        c.resetDebugVisualizerCamera(distance, yaw, pitch, list(target))

    def hold(self, floor_id: int) -> None:
        """With the floor in place: a frame with it and a "loading" line, then rendering off."""
        c = self.client
        c.changeVisualShape(floor_id, -1, specularColor=[0.0, 0.0, 0.0])   # no glare on it
        self.show_overlay([f"{_PACKAGE}: loading the scene ..."])
        c.configureDebugVisualizer(c.COV_ENABLE_RENDERING, 0)
        self._rendering = False

    def show(self, floor_id: int) -> None:
        """The scene is complete: matt bodies, the first overlay, rendering on."""
        c = self.client
        for body in (c.getBodyUniqueId(i) for i in range(c.getNumBodies())):
            if body != floor_id:
                for link in range(-1, c.getNumJoints(body)):
                    c.changeVisualShape(body, link, specularColor=list(MATT_SPECULAR))
        self.show_overlay([f"{_PACKAGE}: the scene is ready; waiting for the first step"])
        c.configureDebugVisualizer(c.COV_ENABLE_RENDERING, 1)
        self._rendering = True

    # --- the overlay -------------------------------------------------------------------------------
    def lines(self) -> List[str]:
        """The lines the overlay shows now, as wrapped to the window's width."""
        return [text for _, text, _ in self._overlay]

    def show_overlay(self, lines: Sequence[str]) -> None:
        """Show ``lines`` at the top-left corner of the view as it is, wrapped to the window's
        width (:func:`overlay_columns`), in place of what was shown: all lines at once, never
        a mix of the old and the new (module docstring). Items that did not change are kept.
        """
        c = self.client
        camera = c.getDebugVisualizerCamera()
        self._caption = [str(line) for line in lines]
        if not camera_has_view(camera):
            # The window is going away (Escape or its close button while a step drew): nothing
            # can be placed; the caption is kept for a view that comes back (follow_view).
            self._overlay_view = None
            return
        self._overlay_view = self._view_seen = _size_and_view(camera)
        wrapped = wrap_lines(self._caption, overlay_columns(camera[0]))
        x, y = _OVERLAY_MARGIN
        places = screen_points(camera, [(x, y + i * _OVERLAY_LINE_PX) for i in range(len(wrapped))])
        shown: List[Tuple[int, str, Tuple[float, ...]]] = []
        changes: List[Tuple[int, str, Tuple[float, ...], int]] = []   # (line, text, where, old item)
        for i, (text, place) in enumerate(zip(wrapped, places)):
            where = tuple(round(v, 4) for v in place)
            old = self._overlay[i] if i < len(self._overlay) else None
            if old is not None and old[1] == text and old[2] == where:
                shown.append(old)
            else:
                shown.append(old)   # its place, filled below
                changes.append((i, text, where, old[0] if old is not None else -1))
        gone = [item for item, _, _ in self._overlay[len(wrapped):]]
        if not changes and not gone:
            return
        with self._frames_held():
            for i, text, where, replace_id in changes:
                item = c.addUserDebugText(text, list(where), list(_OVERLAY_COLOUR),
                                          textSize=_OVERLAY_TEXT_SIZE, replaceItemUniqueId=replace_id)
                shown[i] = (item, text, where)
            for item in gone:
                c.removeUserDebugItem(item)
        self._overlay = shown

    @contextmanager
    def _frames_held(self) -> Iterator[None]:
        """The window shows its last frame while the overlay's items change, then draws them
        all in its next frame (with rendering on; while loading, it is off already)."""
        c = self.client
        if not self._rendering:
            yield
            return
        c.configureDebugVisualizer(c.COV_ENABLE_RENDERING, 0)
        try:
            yield
        finally:
            if c.connected:   # a window closed meanwhile is the caller's news, not this one's
                c.configureDebugVisualizer(c.COV_ENABLE_RENDERING, 1)

    def follow_view(self) -> None:
        """A few times a second: once the user has moved the window's view or resized it and
        let it rest, the overlay goes back to the window's corner, wrapped to its width (not
        while the view moves: placing the lines costs frames)."""
        now = time.monotonic()
        if now < self._next_look:
            return
        self._next_look = now + _LOOK_PERIOD
        view = _size_and_view(self.client.getDebugVisualizerCamera())
        if self._overlay and view != self._overlay_view and view == self._view_seen:
            self.show_overlay(self._caption)
        self._view_seen = view

    # --- closing -------------------------------------------------------------------------------------
    def add_closed_listener(self, listener: Callable[[], None]) -> None:
        """Call ``listener()`` once, when the window is found gone (see :meth:`mark_closed`)."""
        self._closed_listeners.append(listener)

    def check(self, settle: float = 0.0) -> None:
        """Raise :class:`WindowClosed` if the window is gone (see :meth:`vanished` for
        ``settle``), telling the listeners the first time."""
        if self.closed or self.vanished(settle):
            self.mark_closed()
            raise WindowClosed()

    def mark_closed(self) -> None:
        """Once: the window is gone; call the closed listeners, in the order they were added."""
        if self.closed:
            return
        self.closed = True
        LOG.info("the PyBullet window was closed: the world stops")
        for listener in self._closed_listeners:
            try:
                listener()
            except Exception:  # a listener's bug must not hide the closing
                LOG.exception("window-closed listener %r failed", listener)

    def vanished(self, settle: float = 0.0) -> bool:
        """True if the window (the scene server) is gone.

        ``settle``: after a PyBullet call failed, give the closing window this long (s) to show
        it is gone (its threads end first, the connection a moment later): a failure when the
        window closes is not the action's.
        """
        gone = not self.client.connected
        deadline = time.monotonic() + settle
        while not gone and time.monotonic() < deadline:
            time.sleep(0.01)
            gone = not self.client.connected
        return gone
