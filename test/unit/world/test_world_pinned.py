"""The world's behaviour, pinned: a scripted run through every action of both agents gives
what it gave before the speed work of issue #11 (test/unit/world/data/pinned_run.json).

Pinned exactly: each action's success and message, who holds the object, whether it left the
belt, and every predicate. Within a tolerance, because how the world is integrated may change
but not what happens in it: each action's simulated duration (one control step: the record
was taken with motions at 240 Hz, they now run at 60 Hz), the simulated clock (which adds up
those differences) and the object's position (a few millimetres).
HRC_RECORD_PINNED_RUN=1 rewrites the record, for a deliberate change of the world's behaviour.

Re-recorded once, on purpose, for issue #21 (independent episodes): the world's draws now come
from the stream of (seed, episode 0, "world") (``ros_hrc.streams``) instead of the bare
seed, so the two fumbled grasps miss by other distances (0.14 and 0.13 m instead of 0.10 and
0.11 m); nothing else changed.
"""
import json
import os
from pathlib import Path

import pytest

from ros_hrc.world import World, WorldConfig

RECORD = Path(__file__).resolve().parent / "data" / "pinned_run.json"
#: Positions may differ by this much from the record, m.
POSITION_TOLERANCE = 0.005
#: An action's duration may differ by one control step, s; the clock by a few over the run.
DURATION_TOLERANCE = 1.0 / 60.0
CLOCK_TOLERANCE = 0.05

#: (agent, action), or ("wait", seconds) to let the belt carry the object.
PLAN = [("human", "look_around"), ("robot", "point_to_obj"), ("human", "attempt_grasp"),
        ("human", "grasp"), ("human", "walk_away"), ("human", "reset"), ("human", "warn_robot"),
        ("robot", "grasp"), ("robot", "reset"), ("human", "idle"), ("world", "reset"),
        ("human", "walk_away"), ("wait", 30.0), ("robot", "point_to_obj"), ("robot", "grasp"),
        ("human", "look_around"), ("robot", "cancel_action"), ("robot", "reset"),
        ("human", "reset"), ("wait", 75.0), ("human", "grasp"), ("robot", "grasp"),
        ("world", "reset"), ("human", "attempt_grasp"), ("human", "grasp")]


def run_plan() -> list:
    rows = []
    with World(WorldConfig(seed=3)) as world:
        for agent, what in PLAN:
            if agent == "wait":
                world.advance(what)
                success, message, duration = True, "", what
            else:
                outcome = world.run(agent, what)
                success, message, duration = outcome.success, outcome.message, outcome.duration
            state = world.state()
            rows.append({"do": f"{agent}/{what}", "success": success, "message": message,
                         "duration": round(duration, 6), "sim_time": round(state["sim_time"], 6),
                         "holder": state["object"]["holder"],
                         "left_belt": state["object"]["left_belt"],
                         "predicates": state["predicates"],
                         "position": [round(x, 4) for x in state["object"]["position"]]})
    return rows


@pytest.fixture(scope="module")
def run() -> list:
    rows = run_plan()
    if os.environ.get("HRC_RECORD_PINNED_RUN"):
        RECORD.parent.mkdir(exist_ok=True)
        RECORD.write_text(json.dumps(rows, indent=1) + "\n")
    return rows


def test_every_action_does_what_it_did(run):
    recorded = json.loads(RECORD.read_text())
    assert len(run) == len(recorded)
    for now, then in zip(run, recorded):
        now, then = dict(now), dict(then)
        position_now, position_then = now.pop("position"), then.pop("position")
        duration_now, duration_then = now.pop("duration"), then.pop("duration")
        clock_now, clock_then = now.pop("sim_time"), then.pop("sim_time")
        assert now == then
        assert abs(duration_now - duration_then) <= DURATION_TOLERANCE + 1e-9, \
            f"{then['do']}: took {duration_now} s, took {duration_then} s"
        assert abs(clock_now - clock_then) <= CLOCK_TOLERANCE, \
            f"{then['do']}: ended at {clock_now} s, ended at {clock_then} s"
        assert max(abs(a - b) for a, b in zip(position_now, position_then)) <= POSITION_TOLERANCE, \
            f"{then['do']}: the object is at {position_now}, was at {position_then}"


def test_the_run_covers_both_agents_holding_and_the_belt_end(run):
    holders = {row["holder"] for row in run}
    assert {"human", "robot", "none"} <= holders
    assert any(row["left_belt"] for row in run), "the object never reached the belt's end"
