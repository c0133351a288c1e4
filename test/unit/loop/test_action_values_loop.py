"""The planner's action values from the robot process to a step's report, through the whole
loop without ROS (local_loop.py: the real coordinator, world, MDP process and POMDP process,
DESPOT bounded by trials): every step's report names the robot model's actions with a finite
value each, the chosen action's the best, and the same seed gives the same values. A baseline
robot's steps carry none."""
import math

from ros_hrc.pomdp.despot import TIE_TOLERANCE

from local_loop import LocalLoop

ROBOT_ACTIONS = ("rIdle", "rPoint_obj", "rGrasp_obj", "rStop_all")


def run(planner="despot", seed=3, steps=8):
    loop = LocalLoop("seed", "tired", "robot", seed=seed, max_steps=6, planner=planner)
    try:
        return list(loop.run(steps))
    finally:
        loop.close()


def test_each_step_reports_the_value_of_every_action_and_the_chosen_is_the_best():
    reports = run()
    assert len(reports) == 8
    for report in reports:
        where = f"episode {report.episode} step {report.step}"
        assert report.fault == "", where
        assert report.action_names == ROBOT_ACTIONS, where
        values = dict(zip(report.action_names, report.action_values))
        assert all(math.isfinite(v) for v in values.values()), where
        best = max(values.values())
        assert values[report.robot_action] >= best - TIE_TOLERANCE * max(1.0, abs(best)), where
    again = run()
    assert [(r.robot_action, r.action_values) for r in again] == \
        [(r.robot_action, r.action_values) for r in reports]


def test_a_baseline_robot_s_steps_carry_no_values():
    for report in run(planner="reactive", steps=4):
        assert report.rule and report.action_names == () and report.action_values == ()
