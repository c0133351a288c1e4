"""PyBullet's window explains itself: every visual in its colour, a camera on the scene, an
overlay, and a closed window that stops the world instead of breaking every later call.

Headless (DIRECT) for everything that does not need a display; one test opens the window
under a private Xvfb (skipped without Xvfb and xdotool) and closes it with Esc, as a user does.
"""
import logging
import os
import select
import shutil
import subprocess
import sys
import textwrap
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pybullet
import pytest

from ros_hrc.errors import SimulationError
from ros_hrc.world import World, WindowClosed, WorldConfig
from ros_hrc.world.scene import default_model_dir
from ros_hrc.world.visuals import link_colours, visual_layers
from ros_hrc.world.window import WINDOW_TITLE, screen_points, window_options

AGENTS = {"human": "human.urdf", "robot": "pr2_like.urdf"}


@pytest.fixture
def split_world():
    """The default scene, headless, with the agents in colour layers as in the window."""
    with World(WorldConfig(seed=3, split_visuals=True)) as w:
        yield w


def _rgba(colour):
    return tuple(round(float(x), 3) for x in colour)


def _colours_by_link(client, body_ids, links):
    """Per link name, the colours the scene server holds for it across ``body_ids``."""
    names = {index: name for name, index in links.items()}
    out = {name: set() for name in links}
    for body in body_ids:
        for row in client.getVisualShapeData(body):
            out[names[row[1]]].add(_rgba(row[7]))
    return out


# --- colours: one colour per link and body, every visual's colour kept ------------------------
def test_a_link_of_several_colours_is_split_into_layers():
    urdf = textwrap.dedent("""\
        <robot name="r">
          <material name="red"><color rgba="1 0 0 1"/></material>
          <link name="a">
            <visual><geometry><box size="1 1 1"/></geometry><material name="red"/></visual>
            <visual><geometry><sphere radius="1"/></geometry><material name="x"><color rgba="0 1 0 1"/></material></visual>
            <visual><geometry><sphere radius="2"/></geometry><material name="red"/></visual>
            <visual><geometry><sphere radius="3"/></geometry><material name="y"><color rgba="0 0 1 1"/></material></visual>
            <collision><geometry><box size="1 1 1"/></geometry></collision>
          </link>
          <joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
            <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
          <link name="b"><visual><geometry><box size="1 1 1"/></geometry><material name="red"/></visual>
            <collision><geometry><box size="1 1 1"/></geometry></collision></link>
        </robot>""")
    assert link_colours(urdf) == {"a": [(1, 0, 0, 1), (0, 1, 0, 1), (0, 0, 1, 1)], "b": [(1, 0, 0, 1)]}
    layers = visual_layers(urdf)
    assert len(layers) == 3
    base, green, blue = (link_colours(layer) for layer in layers)
    assert base == {"a": [(1, 0, 0, 1)], "b": [(1, 0, 0, 1)]}
    assert green == {"a": [(0, 1, 0, 1)], "b": []} and blue == {"a": [(0, 0, 1, 1)], "b": []}
    assert layers[0].count("<visual>") == 3   # both red visuals of a, and b's
    assert layers[0].count("<collision>") == 2 and "<collision>" not in layers[1] + layers[2]
    assert all("<joint" in layer for layer in layers)   # the same tree in every layer
    one_colour = urdf.replace('<color rgba="0 1 0 1"/>', '<color rgba="1 0 0 1"/>') \
                     .replace('<color rgba="0 0 1 1"/>', '<color rgba="1 0 0 1"/>')
    assert visual_layers(one_colour) == [one_colour]


def test_every_visual_keeps_its_colour_in_the_scene_server(split_world):
    c = split_world.client
    for agent, urdf in AGENTS.items():
        body = getattr(split_world, agent)
        wanted = {link: {_rgba(colour) for colour in colours}
                  for link, colours in link_colours((default_model_dir() / urdf).read_text()).items()}
        assert body.twins, f"the {agent} has links of two colours: it needs a second layer"
        assert _colours_by_link(c, [body.body_id] + body.twins, body.links) == wanted
        # Each body of the layers draws each link in one colour: what PyBullet's window can do.
        for body_id in [body.body_id] + body.twins:
            colours = _colours_by_link(c, [body_id], body.links)
            assert all(len(found) <= 1 for found in colours.values()), (agent, body_id, colours)
    shirt, skin, hair = (0.2, 0.45, 0.75, 1.0), (0.93, 0.75, 0.62, 1.0), (0.3, 0.18, 0.08, 1.0)
    human = _colours_by_link(c, [split_world.human.body_id], split_world.human.links)
    assert human["torso"] == {shirt} and human["head"] == {skin}
    assert hair in _colours_by_link(c, split_world.human.twins, split_world.human.links)["head"]


def test_layers_change_no_link_joint_or_collision_shape(world, split_world):
    for agent in AGENTS:
        plain, split = getattr(world, agent), getattr(split_world, agent)
        assert split.links == plain.links and split.joints == plain.joints
        for index in range(world.client.getNumJoints(plain.body_id)):
            assert split_world.client.getJointInfo(split.body_id, index) == \
                world.client.getJointInfo(plain.body_id, index)
        for index in [-1] + list(range(world.client.getNumJoints(plain.body_id))):
            # Each row without its first field, the body's id (the human's layers come first).
            assert [row[1:] for row in split_world.client.getCollisionShapeData(split.body_id, index)] == \
                [row[1:] for row in world.client.getCollisionShapeData(plain.body_id, index)]
        for twin in split.twins:   # visual only: rays and contacts go through
            for index in [-1] + list(range(split_world.client.getNumJoints(twin))):
                assert split_world.client.getCollisionShapeData(twin, index) == ()


def test_layers_move_together_and_the_run_is_the_same(world, split_world):
    for w in (world, split_world):
        w.run("robot", "point_to_obj")
        w.run("human", "grasp")
        w.run("human", "walk_away")
    assert split_world.state() == world.state()
    for agent in AGENTS:
        plain, split = getattr(world, agent), getattr(split_world, agent)
        for name in plain.links:
            assert np.allclose(split.link_pose(name)[0], plain.link_pose(name)[0], atol=1e-9)
        indices = [j.index for j in split.joints.values()]
        reference = [s[0] for s in split_world.client.getJointStates(split.body_id, indices)]
        for twin in split.twins:
            assert [s[0] for s in split_world.client.getJointStates(twin, indices)] == reference


def test_rays_do_not_hit_the_colour_layers(split_world):
    head, _ = split_world.human.link_frame("head")
    top = head + np.array([0.0, 0.0, 0.13])   # the hair is a layer of its own
    hit = split_world.client.rayTest((top + [0, 0, 0.5]).tolist(), (top - [0, 0, 0.2]).tolist())[0]
    assert hit[0] == split_world.human.body_id
    assert split_world.query("is_ov").value


def test_the_object_has_a_colour_of_its_own(split_world):
    """Far from every visual of every other body (the gripper that holds it, the hand, the
    belt), in the window and in RViz's marker."""
    from ros_hrc.nodes.viz_node import scenery_markers

    c = split_world.client
    mine = np.array(split_world.object.config.colour[:3])
    others = {_rgba(row[7])[:3] for body in (c.getBodyUniqueId(i) for i in range(c.getNumBodies()))
              if body != split_world.object.body_id for row in c.getVisualShapeData(body)}
    assert len(others) > 8   # the agents' every layer, the belt and the floor
    nearest = min(others, key=lambda colour: np.linalg.norm(mine - colour))
    assert np.linalg.norm(mine - nearest) > 0.35, f"the object's colour is near {nearest}"
    assert [row[7] for row in c.getVisualShapeData(split_world.object.body_id)] == \
        [pytest.approx(split_world.object.config.colour)]
    marker = next(m for m in scenery_markers([2.0, 0.4, 0.04], 0.06) if m.header.frame_id == "object")
    assert (marker.color.r, marker.color.g, marker.color.b, marker.color.a) == \
        pytest.approx(split_world.object.config.colour)


# --- the camera ---------------------------------------------------------------------------------------
def _in_view(world, points, window_view):
    """Each point's place in the view (normalised device coordinates, -1..1 across)."""
    view, projection = world.camera_matrices(window_view=window_view)
    full = np.array(projection).reshape(4, 4).T @ np.array(view).reshape(4, 4).T
    clip = (full @ np.c_[points, np.ones(len(points))].T).T
    return clip[:, :3] / clip[:, 3:4]


def _corners(world, body_ids):
    """The corners of every link's bounding box of these bodies."""
    c = world.client
    points = []
    for body in body_ids:
        for link in range(-1, c.getNumJoints(body)):
            low, high = c.getAABB(body, link)
            points += [(x, y, z) for x in (low[0], high[0]) for y in (low[1], high[1])
                       for z in (low[2], high[2])]
    return np.array(points)


@pytest.mark.parametrize("window_view", [True, False])
def test_both_agents_stay_in_frame_whatever_they_do(still_world, window_view):
    """Every link of both agents projects inside the view (with a margin) at rest, with the
    human's arm raised, at the end of the human's walk-away and while the robot reaches."""
    w = still_world
    poses = {"at rest": lambda: None, "warning": lambda: w.run("human", "warn_robot"),
             "walked away": lambda: w.run("human", "walk_away"),
             "warning, away": lambda: w.run("human", "warn_robot"),
             "robot reaching": lambda: w.run("robot", "point_to_obj")}
    for name, act in poses.items():
        act()
        for agent in ("human", "robot"):
            points = _in_view(w, _corners(w, [getattr(w, agent).body_id]), window_view)
            inside = bool(np.all(np.abs(points[:, :2]) < 0.95) and np.all(points[:, 2] < 1.0))
            assert inside, \
                f"{name}: the {agent} leaves the view (x {points[:, 0].min():.2f}..{points[:, 0].max():.2f}, " \
                f"y {points[:, 1].min():.2f}..{points[:, 1].max():.2f})"
    assert not w.human.at_station()   # the walk-away was checked where it ends



def _visible_links(world, window_view):
    """(body, link) pairs with pixels in the image of the window's view or the snapshot camera."""
    c = world.client
    width, height = 256, 192
    view, projection = world.camera_matrices(width, height, window_view)
    mask = np.asarray(c.getCameraImage(width, height, view, projection, renderer=c.ER_TINY_RENDERER,
                                       flags=c.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX)[4]).reshape(height, width)
    seen = {(int(v) & ((1 << 24) - 1), (int(v) >> 24) - 1) for v in np.unique(mask) if v >= 0}
    return seen, float(np.mean(mask < 0))


@pytest.mark.parametrize("window_view", [True, False])
def test_the_cameras_see_both_agents_at_work(still_world, window_view):
    w = still_world
    w.submit("robot", "point_to_obj")
    grasp = w.submit("human", "grasp")
    w.step(int(1.0 / w.control_period))   # the reach is nearly over: the hand is at the object
    assert not grasp.done() and w.human.activity == "grasp"
    seen, sky = _visible_links(w, window_view)
    human, robot = w.human, w.robot
    for body, link in [(human, "left_forearm"), (human, "head"), (human, "torso"),
                       (robot, "r_gripper_palm_link"), (robot, "head_tilt_link"), (robot, "torso_lift_link")]:
        assert (body.body_id, body.link(link)) in seen, f"{link} is not in view"
    assert (w.object.body_id, -1) in seen and (w.scenery.belt_id, -1) in seen
    assert sky < 0.25, f"{sky:.0%} of the view is sky"


def test_the_window_camera_is_the_configured_one():
    config = WorldConfig(seed=1)
    with World(config) as w:
        distance, yaw, pitch, target = w.gui_camera()
        assert (distance, yaw, pitch, target) == (config.window.distance, config.window.yaw_deg,
                                                  config.window.pitch_deg, config.window.target)
    options = window_options(1280, 800, (0.5, 0.25, 1.0))
    assert options.split() == ["--width=1280", "--height=800", "--background_color_red=0.500",
                               "--background_color_green=0.250", "--background_color_blue=1.000"]


def test_overlay_points_land_on_their_pixels():
    width, height = 1024, 768
    view = pybullet.computeViewMatrixFromYawPitchRoll([0.1, 0.2, 0.9], 1.8, -76, -36, 0, 2)
    projection = pybullet.computeProjectionMatrixFOV(90, width / height, 0.01, 1000)
    camera = (width, height, view, projection)
    pixels = [(14, 26), (500, 400), (1000, 700)]
    eye = np.linalg.inv(np.array(view).reshape(4, 4).T)[:3, 3]
    full = np.array(projection).reshape(4, 4).T @ np.array(view).reshape(4, 4).T
    for (x, y), point in zip(pixels, screen_points(camera, pixels, depth=0.5)):
        clip = full @ np.array([*point, 1.0])
        ndc = clip[:3] / clip[3]
        assert (width * (ndc[0] + 1) / 2, height * (1 - ndc[1]) / 2) == pytest.approx((x, y), abs=1e-3)
        assert np.linalg.norm(np.array(point) - eye) >= 0.5   # in front of everything in the scene


# --- the API without a window ------------------------------------------------------------------------
def test_without_a_window_the_overlay_is_a_no_op(world):
    world.show_overlay(["episode 1, step 2", "human: grasp -> S1"])
    assert world.overlay() == []
    assert world.window_closed is False
    assert issubclass(WindowClosed, SimulationError)
    assert "ros_hrc" in WINDOW_TITLE


def test_a_lost_window_stops_the_loop_once_and_every_later_call(caplog):
    """The scene server's disconnection, as Esc causes it, here without a display: a headless
    world made to take its scene server for a window, whose server is then disconnected."""
    world = World(WorldConfig(seed=3))
    world.config = replace(world.config, gui=True)   # checks the scene server like a window
    calls = []
    world.add_window_closed_listener(lambda: calls.append(world.sim_time))
    try:
        world.start(real_time_factor=1.0)
        running = world.submit("human", "look_around")   # 3.4 s
        queued = world.submit("human", "grasp")           # behind it
        time.sleep(0.1)
        assert not running.done() and not queued.done()
        with caplog.at_level(logging.INFO, logger="ros_hrc.world"):
            with world._lock:   # as the window's thread ends: between two steps
                pybullet.disconnect(physicsClientId=world.client.client_id)
            deadline = time.monotonic() + 5.0
            while world.running and time.monotonic() < deadline:
                time.sleep(0.01)
            time.sleep(0.2)   # a loop that went on would log again, or step
        assert not world.running and world.window_closed and len(calls) == 1
        for ticket in (running, queued):
            with pytest.raises(WindowClosed):
                ticket.wait(1.0)
        for call in (lambda: world.run("robot", "grasp", timeout=1.0), lambda: world.query("is_ov"),
                     world.state, lambda: world.show_overlay(["x"])):
            with pytest.raises(WindowClosed):
                call()
        # Said once, and not as an error: closing the window is how a user ends a run.
        said = [r for r in caplog.records if "window was closed" in r.getMessage()]
        assert len(said) == 1 and said[0].levelno < logging.WARNING
        assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
        assert len(calls) == 1
    finally:
        world.close()


# --- the window itself, under a private X server --------------------------------------------------
_WINDOW_SCRIPT = textwrap.dedent("""\
    import subprocess, sys, time
    from ros_hrc.world import World, WorldConfig, WindowClosed
    world = World(WorldConfig(gui=True, seed=1))
    closed = []
    world.add_window_closed_listener(lambda: closed.append(1))
    world.start(real_time_factor=1.0)
    lines = ["episode 1, step 1", "human: grasp -> S1", "P(human needs help) = 0.50"]
    world.show_overlay(lines)
    world.show_overlay(lines[:2])
    print("RESULT overlay", world.overlay() == lines[:2], flush=True)
    found = subprocess.run(["xdotool", "search", "--name", "^ros_hrc"], capture_output=True, text=True)
    windows = found.stdout.split()
    print("RESULT titled", len(windows), flush=True)
    ticket = world.submit("human", "look_around")   # 3.4 s: under way when the window closes
    time.sleep(0.3)
    subprocess.run(["xdotool", "key", "--window", windows[0], "Escape"], check=True)
    deadline = time.monotonic() + 5.0
    while (world.running or not world.window_closed) and time.monotonic() < deadline:
        time.sleep(0.02)
    print("RESULT closed", world.window_closed, "running", world.running, flush=True)
    try:
        ticket.wait(2.0)
        print("RESULT ticket returned", flush=True)
    except WindowClosed:
        print("RESULT ticket WindowClosed", flush=True)
    try:
        world.run("human", "idle", timeout=2.0)
        print("RESULT run returned", flush=True)
    except WindowClosed:
        print("RESULT run WindowClosed", flush=True)
    print("RESULT listener", len(closed), flush=True)
    world.close()
    print("RESULT done", flush=True)
    """)


def _start_xvfb():
    """An Xvfb of the test's own, once it accepts clients: (process, display number). It picks
    a free display itself and writes the number to -displayfd only when it is ready (the
    socket file appears earlier, which made this test fail on a loaded machine)."""
    read_end, write_end = os.pipe()
    server = subprocess.Popen(["Xvfb", "-displayfd", str(write_end), "-screen", "0",
                               "1280x800x24", "-nolisten", "tcp"], pass_fds=(write_end,),
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write_end)
    with os.fdopen(read_end) as announced:
        ready, _, _ = select.select([announced], [], [], 30.0)
        line = announced.readline() if ready else ""
    if not line.strip().isdigit():
        server.kill()
        server.wait()
        pytest.skip("Xvfb could not start")
    return server, int(line)


def _atom(ask=False):
    """Make (or, with ``ask``, look up) an atom on the display from a client that then leaves:
    "there" or "gone". Atoms live until the X server resets, which it does when its last client
    leaves: an atom still there after its maker left tells that another client held the
    server."""
    from ros_hrc.world.x11 import open_display

    deadline = time.monotonic() + 20
    d = open_display()
    while d is None and time.monotonic() < deadline:   # cut while the server resets
        time.sleep(0.1)
        d = open_display()
    assert d is not None, "no display"
    try:
        return "there" if d.intern_atom("_ROS_HRC_PROBE", only_if_exists=ask) else "gone"
    finally:
        d.close()


def _atom_goes(within=10.0):
    """True once the atom is gone (the server reset), polled: the reset follows the last
    client's leaving, not at once on a loaded machine."""
    deadline = time.monotonic() + within
    while _atom(ask=True) != "gone":
        if time.monotonic() > deadline:
            return False
        time.sleep(0.2)
    return True


@pytest.mark.skipif(not shutil.which("Xvfb"), reason="needs Xvfb")
def test_the_window_namer_holds_the_x_server_from_resetting_under_the_window(monkeypatch):
    # On a display nobody else uses, the namer's connection is open before PyBullet connects
    # and until the window is named: a client that leaves in between must not make the server
    # reset (a connection arriving during a reset is cut, and PyBullet then ends the process
    # with "cannot connect to X server").
    from ros_hrc.world.x11 import WindowNamer

    server, number = _start_xvfb()
    try:
        monkeypatch.setenv("DISPLAY", f":{number}")
        # The control: alone, a leaving client resets the server and its atom is gone.
        _atom()
        assert _atom_goes()
        namer = WindowNamer()
        try:
            assert _atom() == "there"
            time.sleep(0.5)   # a reset, if one came, would be over
            assert _atom(ask=True) == "there"
            assert namer.name("nothing to name", wait=0.2) is False   # no PyBullet window here
        finally:
            namer.close()
        namer.close()   # twice is safe
        assert _atom_goes()   # the namer was the server's last client
    finally:
        server.terminate()
        server.wait(timeout=10)


@pytest.mark.skipif(not (shutil.which("Xvfb") and shutil.which("xdotool")), reason="needs Xvfb and xdotool")
def test_the_window_under_xvfb_closes_with_esc_and_the_world_says_so():
    server, number = _start_xvfb()
    try:
        env = dict(os.environ, DISPLAY=f":{number}")
        run = subprocess.run([sys.executable, "-c", _WINDOW_SCRIPT], env=env,
                             capture_output=True, text=True, timeout=60)
    finally:
        server.terminate()
        server.wait(timeout=10)
    results = [line.split(" ", 1)[1] for line in run.stdout.splitlines() if line.startswith("RESULT ")]
    assert run.returncode == 0, run.stderr[-2000:]
    assert results == ["overlay True", "titled 1", "closed True running False", "ticket WindowClosed",
                       "run WindowClosed", "listener 1", "done"], run.stdout[-3000:]


#: A world started and closed, as hrc_world does, with a line of our own on each stream.
_START_SCRIPT = textwrap.dedent("""
    import sys, time
    from ros_hrc.world import World, WorldConfig
    world = World(WorldConfig(gui=sys.argv[1] == "gui"))
    world.start()
    while world.sim_time < 1.0:      # the window draws meanwhile
        time.sleep(0.05)
    print("ours: the world is up", flush=True)
    print("ours: on stderr", file=sys.stderr, flush=True)
    world.close()
    print("ours: closed", flush=True)
    """)
#: What PyBullet's C code printed on its own (issue #41): with its window, and headless.
_CHATTER = ("argv[0]=", "GL_VENDOR=", "ven = ", "b3Printf: Selected demo", "semaphore destroyed",
            "pybullet build time", "startThreads", "Thread TERMINATED")


def _started_and_closed(gui, env=None):
    run = subprocess.run([sys.executable, "-c", _START_SCRIPT, "gui" if gui else "direct"],
                         env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.splitlines() == ["ours: the world is up", "ours: closed"], run.stdout
    assert run.stderr.splitlines() == ["ours: on stderr"], run.stderr


def test_a_headless_world_prints_nothing_of_pybullets_own():
    _started_and_closed(gui=False)


@pytest.mark.skipif(not shutil.which("Xvfb"), reason="needs Xvfb")
def test_a_world_with_its_window_prints_nothing_of_pybullets_own():
    server, number = _start_xvfb()
    try:
        _started_and_closed(gui=True, env=dict(os.environ, DISPLAY=f":{number}"))
    finally:
        server.terminate()
        server.wait(timeout=10)
