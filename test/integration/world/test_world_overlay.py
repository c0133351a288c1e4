"""The caption over PyBullet's window: whole captions only, never half of the next one over
the last, and lines wrapped to the window's width instead of cut at its edge.

The wrapping is checked as text (no display); the window under a private Xvfb (skipped
without Xvfb), read pixel by pixel as a user sees it: frames grabbed from the X server as fast
as it gives them while the world changes its caption.
"""
import ctypes
import ctypes.util
import json
import os
import select
import shutil
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from ros_hrc.world.window import overlay_columns
from ros_hrc.world.wrap import CONTINUATION_INDENT, wrap_lines

from test_world_window import _start_xvfb

LONG = ("robot: reaches for the object -> cannot grasp: the object is out of reach, 1.00 m from "
        "the right shoulder (the arm reaches 0.90 m)")


# --- wrapping, as text ----------------------------------------------------------------------------
@pytest.mark.parametrize("columns", [8, 20, 40, 79, 109, 200])
def test_wrapped_lines_fit_the_width_and_keep_every_word_in_order(columns):
    lines = ["episode 1, step 1: done", LONG, "  -> " + LONG, "", "P(human needs help) = 1.00"]
    wrapped = wrap_lines(lines, columns)
    assert all(len(line) <= columns for line in wrapped), wrapped
    # No word is cut unless it is longer than a line can hold; the words read as before.
    room = columns - len(CONTINUATION_INDENT) - 2
    words = " ".join(lines).split()
    if all(len(word) <= room for word in words):
        assert " ".join(wrapped).split() == words
    else:
        assert "".join(" ".join(wrapped).split()) == "".join(words)
    assert wrap_lines(lines, 500) == lines   # short enough: untouched


def test_a_continued_line_is_indented_and_a_long_word_broken():
    wrapped = wrap_lines(["  -> " + LONG], 40)
    assert wrapped[0].startswith("  -> robot:")
    assert all(line.startswith("    ") and not line.startswith("     ") for line in wrapped[1:])
    word = "x" * 50
    assert wrap_lines([word], 20) == ["x" * 20, "  " + "x" * 18, "  " + "x" * 12]
    assert wrap_lines(["human: walks away\nrobot: decides"], 40) == ["human: walks away", "robot: decides"]
    with pytest.raises(ValueError):
        wrap_lines(["x"], 7)


def test_the_columns_fit_the_window_at_its_size():
    # Caption text measured 8.2 to 8.7 px a character at the overlay's size (1.3): a line of
    # as many characters as the columns, at 8.7 px, fits between the margins.
    for width in (640, 1024, 1920):
        columns = overlay_columns(width)
        assert 14 + columns * 8.7 <= width - 14
        assert columns * 8.2 > 0.8 * (width - 28)   # and uses most of the width
    assert overlay_columns(1024) > overlay_columns(640)
    assert overlay_columns(50) == 20   # never a column of single words


# --- the window, under a private X server ------------------------------------------------------
_SCRIPT = textwrap.dedent("""\
    import json, sys
    from ros_hrc.world import World, WorldConfig
    world = World(WorldConfig(gui=True, seed=1))
    world.start(real_time_factor=1.0)
    long_line = "long line " * 7
    first = ["A0 " + long_line, "A1 short", "A2 " + long_line, "A3 short", "A4 " + long_line]
    second = ["B0 short", "B1 " + long_line, "B2 short"]
    for caption in (first, second):
        world.show_overlay(caption)
        print("RESULT shown", flush=True)
        sys.stdin.readline()
    for i in range(8):
        sys.stdin.readline()
        world.show_overlay(first if i % 2 == 0 else second)
        print("RESULT swapped", flush=True)
    sys.stdin.readline()
    world.show_overlay(["episode 1, step 1: done", sys.argv[1], "P(human needs help) = 1.00"])
    print("RESULT wrapped " + json.dumps(world.overlay()), flush=True)
    sys.stdin.readline()
    world.close()
    """)


class _XImage(ctypes.Structure):
    _fields_ = [("width", ctypes.c_int), ("height", ctypes.c_int), ("xoffset", ctypes.c_int),
                ("format", ctypes.c_int), ("data", ctypes.POINTER(ctypes.c_ubyte)),
                ("byte_order", ctypes.c_int), ("bitmap_unit", ctypes.c_int),
                ("bitmap_bit_order", ctypes.c_int), ("bitmap_pad", ctypes.c_int),
                ("depth", ctypes.c_int), ("bytes_per_line", ctypes.c_int),
                ("bits_per_pixel", ctypes.c_int)]


class _Screen:
    """What an X screen shows, grabbed with XGetImage (a few ms: every frame of the window)."""

    def __init__(self, display: str) -> None:
        x = ctypes.CDLL(ctypes.util.find_library("X11") or "libX11.so.6")
        x.XOpenDisplay.restype = ctypes.c_void_p
        x.XOpenDisplay.argtypes = [ctypes.c_char_p]
        x.XDefaultRootWindow.restype = ctypes.c_ulong
        x.XDefaultRootWindow.argtypes = [ctypes.c_void_p]
        x.XGetImage.restype = ctypes.POINTER(_XImage)
        x.XGetImage.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_int, ctypes.c_int,
                                ctypes.c_uint, ctypes.c_uint, ctypes.c_ulong, ctypes.c_int]
        x.XDestroyImage.argtypes = [ctypes.POINTER(_XImage)]
        x.XCloseDisplay.argtypes = [ctypes.c_void_p]
        self.x, self.display = x, x.XOpenDisplay(display.encode())
        assert self.display, f"cannot open the display {display}"
        self.root = x.XDefaultRootWindow(self.display)

    def dark(self, width: int, height: int) -> np.ndarray:
        """Which pixels of the screen's top-left ``width`` x ``height`` are dark (text)."""
        image = self.x.XGetImage(self.display, self.root, 0, 0, width, height, 0xFFFFFFFF, 2)
        try:
            shot = image.contents
            assert shot.bits_per_pixel == 32
            raw = np.ctypeslib.as_array(shot.data, shape=(shot.height * shot.bytes_per_line,))
            pixels = raw.reshape(shot.height, shot.bytes_per_line)[:, :width * 4]
            rgb = pixels.reshape(height, width, 4)[:, :, :3].astype(int)
            return rgb.sum(axis=2) < 250    # the overlay's ink, not the sky (about 680)
        finally:
            self.x.XDestroyImage(image)

    def close(self) -> None:
        self.x.XCloseDisplay(self.display)


def _ink_per_line(dark: np.ndarray, lines: int = 5) -> tuple:
    """How much ink each of the overlay's first ``lines`` lines holds (baselines at 26 + 22 i px)."""
    return tuple(int(dark[26 + 22 * i - 17:26 + 22 * i + 5].sum()) for i in range(lines))


def _same(ink: tuple, reference: tuple) -> bool:
    return all(abs(a - b) <= 0.15 * max(a, b) + 20 for a, b in zip(ink, reference))


def _wait_for(process: subprocess.Popen, word: str) -> str:
    """The process's next RESULT line, which must start with ``word``."""
    while True:
        ready, _, _ = select.select([process.stdout], [], [], 60.0)
        line = process.stdout.readline() if ready else ""
        assert line, f"the world's process ended or hung before {word!r}"
        if line.startswith("RESULT "):
            assert line.split()[1] == word, line
            return line.split(" ", 2)[2] if line.count(" ") > 1 else ""


@pytest.mark.skipif(not shutil.which("Xvfb"), reason="needs Xvfb")
def test_the_window_shows_whole_captions_wrapped_to_its_width(tmp_path):
    """Two captions of different shapes, swapped eight times: every frame the window shows is
    one of them whole (before, each line was replaced in a frame of its own: the next
    caption's first line over the last one's others). Then a line three times the window's
    width: wrapped to its width, its ink stops before the window's edge (before, cut there)."""
    server, number = _start_xvfb()
    screen = _Screen(f":{number}")
    errors = (tmp_path / "world.err").open("w")
    world = subprocess.Popen([sys.executable, "-c", _SCRIPT, " ".join([LONG] * 3)],
                             env=dict(os.environ, DISPLAY=f":{number}"), stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, stderr=errors, text=True)
    try:
        references = []
        for _ in range(2):
            _wait_for(world, "shown")
            time.sleep(1.5)   # a few frames, however slow: the caption is drawn
            references.append(_ink_per_line(screen.dark(1024, 140)))
            world.stdin.write("\n")
            world.stdin.flush()
        assert references[0][4] > 500 and references[1][4] == 0, references   # both drawn
        # Eight swaps, each started by the test and watched frame by frame until the window
        # shows the new caption: whatever the machine's load, every swap is seen, and every
        # frame on the way is one of the two captions whole.
        mixed = []
        for i in range(8):
            target, former = (references[0], references[1]) if i % 2 == 0 else references[::-1]
            world.stdin.write("\n")
            world.stdin.flush()
            _wait_for(world, "swapped")
            for _ in range(5000):   # a guard against a hang, far more frames than a swap takes
                ink = _ink_per_line(screen.dark(1024, 140))
                if _same(ink, target):
                    break
                if not _same(ink, former):
                    mixed.append(ink)
            else:
                pytest.fail(f"swap {i + 1}: the window never showed the new caption {target}")
        assert not mixed, f"frames of neither caption (whole: {references}): {mixed[:5]}"
        world.stdin.write("\n")
        world.stdin.flush()

        shown = json.loads(_wait_for(world, "wrapped"))
        columns = overlay_columns(1024)
        assert len(shown) >= 5 and all(len(line) <= columns for line in shown), shown
        assert " ".join(shown).split() == " ".join(
            ["episode 1, step 1: done", LONG, LONG, LONG, "P(human needs help) = 1.00"]).split()
        time.sleep(1.0)
        ink = screen.dark(1024, 26 + 22 * len(shown) + 5)
        right = np.nonzero(ink.any(axis=0))[0].max()
        assert right < 1024 - 7, f"the text reaches the window's edge (x = {right})"
        world.stdin.write("\n")
        world.stdin.flush()
        assert world.wait(timeout=30) == 0
    finally:
        if world.poll() is None:
            world.kill()
            world.wait()
        errors.close()
        screen.close()
        server.terminate()
        server.wait(timeout=10)
