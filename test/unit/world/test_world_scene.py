"""The world as a whole: resets, interruptions, queues, threads, snapshots, several worlds."""
import threading

import numpy as np
import pytest

from ros_hrc.errors import SimulationError
from ros_hrc.world import PREDICATES, World, WorldConfig


def test_reset_restores_everything(world):
    initial = {name: world.query(name).value for name in PREDICATES}
    rest = world.robot.positions(world.robot.joints)
    world.run("human", "grasp")
    world.run("human", "warn_robot")
    world.run("robot", "point_to_obj")
    world.advance(1.0)
    outcome = world.reset()
    assert outcome.success
    assert {name: world.query(name).value for name in PREDICATES} == initial
    assert np.allclose(world.object.position(), world.object.start_position, atol=2e-3)
    assert world.human.at_station() and world.human.activity == "idle"
    after = world.robot.positions(world.robot.joints)
    assert all(after[n] == pytest.approx(rest[n], abs=1e-3) for n in rest)


def test_reset_interrupts_a_motion_in_progress(world):
    walking = world.submit("human", "walk_away")
    queued = world.submit("human", "look_around")
    world.advance(0.8)   # half-way
    assert not walking.done()
    reset = world.run("human", "reset")
    assert reset.success
    assert not walking.outcome.success and "interrupted by human/reset" in walking.outcome.message
    assert not queued.outcome.success and "before it started" in queued.outcome.message
    assert world.human.at_station() and not world.human.moving


def test_actions_of_one_agent_queue_and_agents_move_together(still_world):
    first = still_world.submit("human", "warn_robot")
    second = still_world.submit("human", "idle")
    robot = still_world.submit("robot", "point_to_obj")
    still_world.advance(1.25)   # pointing takes 1.2 s; the warning 2.2 s
    assert robot.done() and not first.done()   # the robot did not wait for the human
    while not second.done():
        still_world.step()
    assert first.outcome.success and second.outcome.success
    assert not still_world.query("is_h4").value  # idle came after the warning


def test_unknown_actions_and_predicates_are_refused(world):
    with pytest.raises(SimulationError, match="unknown action"):
        world.submit("human", "fly")
    with pytest.raises(SimulationError, match="unknown predicate"):
        world.query("is_happy")


def test_gui_without_a_display_is_refused_not_fatal(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(SimulationError, match="display"):
        World(WorldConfig(gui=True))


def test_missing_models_are_reported(tmp_path):
    with pytest.raises(SimulationError, match="human.urdf"):
        World(model_dir=tmp_path)


def test_state_is_plain_data(world):
    state = world.state()
    assert set(state) >= {"sim_time", "object", "human", "robot", "belt_speed", "predicates"}
    assert state["object"]["holder"] == "none" and state["object"]["on_belt"]
    assert set(state["predicates"]) == set(PREDICATES)


def test_snapshot_writes_a_png_headless(world, tmp_path):
    from PIL import Image

    path = world.snapshot(tmp_path / "shots" / "scene.png", width=160, height=120)
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 1000
    with Image.open(path) as png:             # the rendered frame, pixel for pixel
        assert (png.format, png.mode, png.size) == ("PNG", "RGB", (160, 120))
        assert np.array_equal(np.asarray(png), world.render(160, 120))
    image = world.render(80, 60)
    assert image.shape == (60, 80, 3) and image.std() > 10  # not a blank frame


def test_worlds_coexist_in_one_process():
    with World(WorldConfig(belt_speed=0.3)) as fast, World(WorldConfig(belt_speed=0.0)) as still:
        fast.advance(0.5)
        still.run("human", "grasp")
        assert still.object.holder == "human" and fast.object.holder == "none"
        assert fast.object.position()[0] > fast.object.start_position[0] + 0.1
        fast.close()
        assert still.query("is_ho").value


def test_the_same_seed_gives_the_same_run():
    results = []
    for _ in range(2):
        with World(WorldConfig(seed=11)) as world:
            outcome = world.run("human", "attempt_grasp")
            results.append((outcome.message, tuple(np.round(world.object.position(), 6))))
    assert results[0] == results[1]


def test_threaded_loop_serves_concurrent_callers_without_deadlock(still_world):
    still_world.start(real_time_factor=0.0)
    try:
        errors, outcomes = [], []

        def ask(agent, action):
            try:
                outcomes.append(still_world.run(agent, action, timeout=30))
            except Exception as error:  # collected and asserted on below
                errors.append(error)

        def query():
            try:
                for _ in range(50):
                    still_world.query("is_ov")
                    still_world.state()
            except Exception as error:
                errors.append(error)

        threads = [threading.Thread(target=ask, args=("human", "warn_robot")),
                   threading.Thread(target=ask, args=("robot", "point_to_obj")),
                   threading.Thread(target=ask, args=("human", "idle")),
                   threading.Thread(target=query), threading.Thread(target=query)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=60)
        assert not errors and len(outcomes) == 3 and all(o.success for o in outcomes)
        with pytest.raises(SimulationError, match="stepping thread"):
            still_world.step()
        assert still_world.reset(timeout=10).success
    finally:
        still_world.stop()
    assert not still_world.running


def test_pause_when_idle_freezes_time_between_actions(still_world):
    still_world.start(real_time_factor=0.0, pause_when_idle=True)
    try:
        still_world.run("robot", "point_to_obj", timeout=30)
        frozen = still_world.sim_time
        threading.Event().wait(0.2)
        assert still_world.sim_time == frozen
    finally:
        still_world.stop()


def test_closing_releases_waiters():
    world = World()
    ticket = world.submit("human", "walk_away")
    world.close()
    assert ticket.done() and "closed" in ticket.outcome.message
    with pytest.raises(SimulationError, match="closed"):
        world.submit("human", "idle")
