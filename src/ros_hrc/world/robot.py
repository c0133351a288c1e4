"""The PR2-like robot: points at the object, plans a grasp, grasps it with the right gripper,
stops, resets.

The right arm is solved in closed form (shoulder pan, then a planar shoulder-lift / elbow /
wrist chain with the roll joints at 0), with link lengths measured from the URDF at load time.
The robot plans before it moves: a grasp of an object out of reach fails with the distance,
after a reach that stops short (the arm stretched towards the object, then back), so that a
watcher sees the attempt; it never closes the gripper on nothing, unlike the human, who tries.
Planning a grasp (FABRIC's fifth robot action, ``graspPlanning``) is the grasp's first half
alone: the open gripper goes to the pre-grasp pose over where the object will be, and waits.

Two facts of FABRIC's robot, off by default (the seed's robot): ``plan_time``, the motion
planning a grasp or a point does first unless a graspPlanning has just done it; and
``delivery_time``, the time the robot then needs to put the object in its own tray: until
then the object is only carried (:attr:`Robot.carrying`), and a cancel puts it back on the
belt where it started.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from .body import ArticulatedBody, Motion
from .client import PhysicsClient
from .object import NOBODY, WorkObject
from .outcome import Outcome
from .geometry import two_link_ik

#: Collision group of the robot's links (touch nothing; visible to rays, so it can occlude).
ROBOT_GROUP = 8

_REST = {
    "torso_lift_joint": 0.30, "head_pan_joint": 0.0, "head_tilt_joint": 0.75,
    # Right arm ready: upper arm forwards, forearm up, gripper high, clear of the belt.
    "r_shoulder_pan_joint": -0.5, "r_shoulder_lift_joint": 0.0, "r_upper_arm_roll_joint": 0.0,
    "r_elbow_flex_joint": -2.0, "r_forearm_roll_joint": 0.0, "r_wrist_flex_joint": -0.3,
    "r_wrist_roll_joint": 0.0, "r_gripper_l_finger_joint": 0.04, "r_gripper_r_finger_joint": 0.04,
    # The left arm stays tucked, as a PR2 does when it works one-handed.
    "l_shoulder_pan_joint": 0.06, "l_shoulder_lift_joint": 1.25, "l_upper_arm_roll_joint": 1.79,
    "l_elbow_flex_joint": -1.68, "l_forearm_roll_joint": -1.73, "l_wrist_flex_joint": -0.1,
    "l_wrist_roll_joint": -0.09, "l_gripper_l_finger_joint": 0.0, "l_gripper_r_finger_joint": 0.0,
}
_FINGERS = ("r_gripper_l_finger_joint", "r_gripper_r_finger_joint")
#: The right gripper open, and the right arm (with its gripper) at rest.
_OPEN = {f: 0.045 for f in _FINGERS}
_RIGHT_REST = {n: v for n, v in _REST.items() if n.startswith("r_")}
#: Gripper pitches tried for a grasp, most vertical first (a top grasp is the safest on a belt).
_GRASP_PITCHES = tuple(math.radians(a) for a in (-90, -80, -70, -60, -50, -40, -30))


@dataclass(frozen=True)
class RobotConfig:
    """Where the robot stands and how it moves."""

    position: Tuple[float, float] = (0.45, 0.60)  # base centre on the floor, m
    facing: float = -math.pi / 2                  # yaw: -pi/2 faces -y (the belt)
    grasp_tolerance: float = 0.04                 # tool-to-object distance that closes a grasp, m
    approach: float = 0.10                        # pre-grasp distance back along the gripper, m
    point_gap: float = 0.22                       # pointing stops this far short of the object, m
    reach_time: float = 1.2                       # s
    descend_time: float = 0.6                     # s
    close_time: float = 0.4                       # s
    lift_time: float = 0.8                        # s
    lift_height: float = 0.20                     # m
    short_hold_time: float = 0.3                  # s a reach for an object out of reach is held
    #: Motion planning before a grasp or a point, unless a grasp_planning planned it since the
    #: robot's last grasp or point (0: none, the seed's robot; FABRIC's robot plans 4 s).
    plan_time: float = 0.0                        # s
    #: After a grasp, how long the robot carries the object to its own tray (0: holding it is
    #: having taken it, the seed's robot). Meanwhile a cancel puts it back on the belt.
    delivery_time: float = 0.0                    # s


class Robot(ArticulatedBody):
    """The robot body, its actions (motions) and what it can reach."""

    def __init__(self, client: PhysicsClient, urdf_path: str, config: RobotConfig,
                 control_period: float, work_object: WorkObject,
                 split_visuals: Optional[bool] = None,
                 predict: Optional[Callable[[float], np.ndarray]] = None) -> None:
        super().__init__(client, urdf_path, (*config.position, 0.0), config.facing, control_period,
                         split_visuals)
        self.config = config
        self.object = work_object
        #: ``predict(seconds)``: where the object will be then, if nobody touches it (the world
        #: knows the belt); without it the robot assumes the object stays where it is.
        self.predict = predict or (lambda _seconds: self.object.position())
        self.set_collision_group(ROBOT_GROUP, 1)
        # Arm geometry from the URDF in its zero pose (arm straight forwards).
        pan, _ = self.link_frame("r_shoulder_pan_link")
        lift, _ = self.link_frame("r_shoulder_lift_link")
        elbow, _ = self.link_frame("r_elbow_flex_link")
        wrist, _ = self.link_frame("r_wrist_flex_link")
        tool, _ = self.link_frame("r_gripper_tool_frame")
        self.shoulder_offset = float(np.linalg.norm(lift - pan))
        self.upper = float(np.linalg.norm(elbow - lift))
        self.lower = float(np.linalg.norm(wrist - elbow))
        self.gripper = float(np.linalg.norm(tool - wrist))
        self.activity = "idle"
        self.moving = False
        #: A grasp_planning has planned the next grasp or point (plan_time is then not spent).
        self.planned = False
        #: Seconds of carrying left before a grasped object lies in the robot's tray.
        self.delivery_left = 0.0
        self.teleport(_REST)

    @property
    def plan_lead(self) -> float:
        """How far ahead a planned grasp aims, s: the planning motion's own duration, so the
        open gripper arrives over the object as the belt brings it there, and a grasp begun
        next starts from the pre-grasp pose over the object (the grasp plans on where the
        object is when it starts)."""
        return self.config.reach_time

    @property
    def carrying(self) -> bool:
        """True while the robot holds the object on its way to its tray (``delivery_time``):
        grasped, but not yet taken."""
        return self.object.holder == "robot" and self.delivery_left > 0.0

    def deliver(self, seconds: float) -> None:
        """``seconds`` of simulated time went by: the carried object gets that much nearer
        the robot's tray (it lies there once ``delivery_time`` is used up)."""
        if self.carrying:
            self.delivery_left = max(0.0, self.delivery_left - seconds)

    def _plan_first(self) -> Motion:
        """Plan the motion (``plan_time``, the arm still, the head on the object) unless a
        grasp_planning did; either way the plan is used up (a grasp_planning that succeeds
        makes a new one)."""
        planned, self.planned = self.planned, False
        if self.config.plan_time > 0 and not planned:
            self.command(self.look_at(self.object.position()))
            yield from self.pause(self.config.plan_time)

    @property
    def reach(self) -> float:
        """Longest distance from the shoulder-lift joint to the tool frame, m."""
        return self.upper + self.lower + self.gripper

    # --- kinematics ----------------------------------------------------------------------------
    def _arm_frame(self) -> Tuple[np.ndarray, np.ndarray]:
        pan_origin, _ = self.link_frame("r_shoulder_pan_link")
        _, torso_rotation = self.link_frame("torso_lift_link")
        return pan_origin, torso_rotation

    def solve_tool(self, target: Sequence[float], pitch: float) -> Optional[Dict[str, float]]:
        """Right-arm joints putting the tool frame on ``target`` with the gripper at ``pitch``
        (radians above horizontal, in the arm's plane), or None if out of reach or limits.

        The elbow and the wrist of a PR2 bend one way only; rolling the upper arm (or the
        forearm) half a turn reverses that way. Elbow up is tried first (the PR2's usual way
        of reaching down to a table), then elbow down, each with either wrist roll.
        """
        pan_origin, rotation = self._arm_frame()
        local = rotation.T @ (np.asarray(target, float) - pan_origin)
        pan = math.atan2(local[1], local[0])
        forward = math.hypot(local[0], local[1]) - self.shoulder_offset
        wrist_forward = forward - self.gripper * math.cos(pitch)
        wrist_up = local[2] - self.gripper * math.sin(pitch)
        for upper_roll in (-math.pi, 0.0):
            solution = two_link_ik(wrist_forward, wrist_up, self.upper, self.lower,
                                   elbow_up=upper_roll != 0.0)
            if solution is None:
                return None
            elevation, flex = solution
            forearm = elevation + flex  # the forearm's angle above horizontal
            sign_upper = -1.0 if upper_roll else 1.0
            for forearm_roll in (0.0, math.pi):
                sign_wrist = sign_upper * (-1.0 if forearm_roll else 1.0)
                joints = {"r_shoulder_pan_joint": pan, "r_shoulder_lift_joint": -elevation,
                          "r_upper_arm_roll_joint": upper_roll, "r_elbow_flex_joint": -sign_upper * flex,
                          "r_forearm_roll_joint": forearm_roll,
                          "r_wrist_flex_joint": sign_wrist * (forearm - pitch), "r_wrist_roll_joint": 0.0}
                if all(self.joint(n).clamp(v) == v for n, v in joints.items()):
                    return joints
        return None

    def _gripper_direction(self, target: Sequence[float], pitch: float) -> np.ndarray:
        pan_origin, rotation = self._arm_frame()
        local = rotation.T @ (np.asarray(target, float) - pan_origin)
        pan = math.atan2(local[1], local[0])
        return rotation @ np.array([math.cos(pitch) * math.cos(pan), math.cos(pitch) * math.sin(pan),
                                    math.sin(pitch)])

    def plan_grasp(self, target: Sequence[float]) -> Optional[float]:
        """The most vertical gripper pitch at which both the pre-grasp and the grasp are reachable."""
        for pitch in _GRASP_PITCHES:
            approach = np.asarray(target) - self.config.approach * self._gripper_direction(target, pitch)
            if self.solve_tool(target, pitch) is not None and self.solve_tool(approach, pitch) is not None:
                return pitch
        return None

    def shoulder_distance(self, point: Sequence[float]) -> float:
        """Distance from the right shoulder-lift joint to ``point``."""
        return float(np.linalg.norm(self.link_frame("r_shoulder_lift_link")[0] - np.asarray(point)))

    def tool_position(self) -> np.ndarray:
        """World position of the right gripper's tool frame (between the fingertips)."""
        return self.link_frame("r_gripper_tool_frame")[0]

    def look_at(self, target: Sequence[float]) -> Dict[str, float]:
        """Head pan/tilt targets that point the head at ``target``."""
        origin, _ = self.link_frame("head_pan_link")
        _, rotation = self.link_frame("torso_lift_link")
        local = rotation.T @ (np.asarray(target, float) - origin)
        return {"head_pan_joint": math.atan2(local[1], local[0]),
                "head_tilt_joint": math.atan2(-local[2], math.hypot(local[0], local[1]))}

    def point_pose(self, target: Sequence[float], gap: Optional[float] = None) -> Dict[str, float]:
        """Arm (and head) targets that point the gripper at ``target`` from ``gap`` short of it
        (default ``point_gap``), or from as near as the arm reaches."""
        lift_origin, _ = self.link_frame("r_shoulder_lift_link")
        offset = np.asarray(target, float) - lift_origin
        distance = float(np.linalg.norm(offset))
        direction = offset / max(distance, 1e-6)
        pitch = math.asin(max(-1.0, min(1.0, direction[2])))
        gap = self.config.point_gap if gap is None else gap
        # Stretch as far as the arm allows, stopping `gap` short of the object.
        reach = min(distance - gap, 0.95 * self.reach)
        pose = None
        while pose is None and reach > self.gripper + 0.1:
            pose = self.solve_tool(lift_origin + direction * reach, pitch)
            reach -= 0.03
        arm = pose or {n: _REST[n] for n in _REST if n.startswith("r_") and n not in _FINGERS}
        return {**arm, **self.look_at(target)}

    # --- actions (motions) -------------------------------------------------------------------------
    def point_to_obj(self) -> Motion:
        """Point the right gripper (and the head) at the object, and hold the pose."""
        self.activity = "point_to_obj"
        if self.object.holder == "robot":
            return Outcome(False, "cannot point: the robot holds the object")
        yield from self._plan_first()
        yield from self.track(lambda: self.point_pose(self.object.position()), self.config.reach_time)
        distance = self.shoulder_distance(self.object.position())
        return Outcome(True, f"pointing at the object, {distance:.2f} m from the right shoulder")

    def grasp(self) -> Motion:
        """Take the object with the right gripper if it is in reach, and lift it."""
        self.activity = "grasp"
        c = self.config
        if self.object.holder == "robot":
            return Outcome(True, "already holds the object")
        if self.object.holder == "human":
            return Outcome(False, "cannot grasp: the human holds the object")
        if self.object.gone:
            return Outcome(False, f"cannot grasp: {self.object.gone}")
        yield from self._plan_first()
        if self.object.gone:   # the belt took it away while the robot planned
            return Outcome(False, f"cannot grasp: {self.object.gone}")
        pitch = self.plan_grasp(self.object.position())
        if pitch is None:
            # A reach that stops short, and back: a watcher sees the robot try and fail (a
            # refusal that moved only the head looked like nothing happened).
            distance = self.shoulder_distance(self.object.position())
            self.command(_OPEN)
            yield from self.track(lambda: self.point_pose(self.object.position(), gap=0.0),
                                  c.reach_time)
            yield from self.pause(c.short_hold_time)
            yield from self.move({**_RIGHT_REST, **self.look_at(self.object.position())}, c.reach_time)
            return Outcome(False, f"cannot grasp: the object is out of reach, {distance:.2f} m from "
                                  f"the right shoulder (the arm reaches {self.reach:.2f} m)")
        last: Dict[str, Dict[str, float]] = {}

        def towards(backoff: float) -> Dict[str, float]:
            # The goal follows the object along the belt; keep the last good pose if a step fails.
            target = self.object.position()
            goal = target - backoff * self._gripper_direction(target, pitch)
            pose = self.solve_tool(goal, pitch)
            if pose is not None:
                last["pose"] = {**pose, **self.look_at(target)}
            return last["pose"]

        self.command(_OPEN)
        yield from self.track(lambda: towards(c.approach), c.reach_time)
        yield from self.track(lambda: towards(0.0), c.descend_time)
        # Close while still following the object, so a moving belt does not pull it away.
        half = self.object.config.size / 2
        start = self.commanded[_FINGERS[0]]
        n_close = self.steps(c.close_time)
        for i in range(1, n_close + 1):
            fingers = start + (half - start) * i / n_close
            self.command({**towards(0.0), **{f: fingers for f in _FINGERS}})
            yield
        gap = float(np.linalg.norm(self.tool_position() - self.object.position()))
        if gap <= c.grasp_tolerance and self.object.holder == NOBODY:
            self.object.attach("robot", lambda: self.link_pose("r_gripper_palm_link"))
            self.delivery_left = c.delivery_time
            on_its_way = (f"; taking it to the robot's tray ({c.delivery_time:g} s)"
                          if c.delivery_time > 0 else "")
            lifted = self._lift_pose(self.object.position(), pitch)
            if lifted is None:
                return Outcome(True, "grasped the object (no room to lift it: holding it on the "
                                     f"belt){on_its_way}")
            yield from self.move(lifted, c.lift_time)
            return Outcome(True, f"grasped the object and lifted it off the belt{on_its_way}")
        yield from self.move(_OPEN, 0.2)
        yield from self.move(_RIGHT_REST, 1.0)
        if self.object.holder == "human":
            return Outcome(False, "missed: the human took the object first")
        return Outcome(False, f"missed: the gripper closed {gap:.2f} m from the object")

    def grasp_planning(self) -> Motion:
        """Open the right gripper over where the object will be (the pre-grasp pose, ``approach``
        back along the gripper from it) and hold there: no grasp. Where the object will be
        is :meth:`predict` ``plan_lead`` seconds ahead (the belt carries it; it stops at the
        belt's end); out of reach there, where it is now; out of reach both, the arm stretches
        towards the predicted position and the plan fails with the distance. With
        ``plan_time``, the motion is planned first (that long, unless it already is), and the
        plan is kept for the next grasp or point."""
        self.activity = "grasp_planning"
        c = self.config
        if self.object.holder != NOBODY:
            return Outcome(False, f"cannot plan a grasp: the {self.object.holder} holds the object")
        if self.object.gone:
            return Outcome(False, f"cannot plan a grasp: {self.object.gone}")
        yield from self._plan_first()
        lead = self.plan_lead
        predicted = np.asarray(self.predict(lead), float)
        target, where = predicted, f"where it will be in {lead:.1f} s"
        pitch = self.plan_grasp(target)
        if pitch is None:
            target, where = self.object.position(), "where it is (its predicted place is out of reach)"
            pitch = self.plan_grasp(target)
        if pitch is None:
            distance = self.shoulder_distance(predicted)
            yield from self.move({**self.point_pose(predicted, gap=c.approach), **_OPEN},
                                 c.reach_time)
            return Outcome(False, f"cannot plan a grasp: the object's predicted place, x = "
                                  f"{predicted[0]:+.2f} m in {lead:.1f} s, is out of reach, "
                                  f"{distance:.2f} m from the right shoulder (the arm reaches "
                                  f"{self.reach:.2f} m)")
        pregrasp = target - c.approach * self._gripper_direction(target, pitch)
        pose = self.solve_tool(pregrasp, pitch)   # plan_grasp checked it is reachable
        yield from self.move({**pose, **_OPEN, **self.look_at(target)}, c.reach_time)
        self.planned = True
        return Outcome(True, f"gripper open {c.approach:.2f} m back from the object's place at "
                             f"x = {target[0]:+.2f} m ({where}), pitched "
                             f"{math.degrees(-pitch):.0f} deg down: ready to grasp")

    def _lift_pose(self, grasped_at: np.ndarray, pitch: float) -> Optional[Dict[str, float]]:
        """Arm joints holding the object ``lift_height`` above where it was taken (or as high as
        the arm allows), with the gripper at ``pitch`` or whatever pitch works."""
        for fraction in (1.0, 0.75, 0.5):
            above = grasped_at + np.array([0.0, 0.0, self.config.lift_height * fraction])
            for candidate in (pitch, *_GRASP_PITCHES):
                pose = self.solve_tool(above, candidate)
                if pose is not None:
                    return pose
        return None

    def cancel(self, interrupted: Optional[str]) -> Outcome:
        """Stop where it is and hold (keeps a held object), instantly. An object being carried
        to the robot's tray goes back on the belt where it started, and the arm to rest
        (FABRIC's cancel of a grasp under way)."""
        self.activity = "cancel_action"   # the joints stay where the last command put them
        self.planned = False
        if self.carrying:
            self.delivery_left = 0.0
            self.object.reset()
            self.teleport(_REST)
            return Outcome(True, "cancelled the grasp before the object was in the robot's "
                                 "tray: the object is back on the belt where it started")
        if interrupted:
            return Outcome(True, f"cancelled {interrupted}; holding still")
        return Outcome(True, "nothing to cancel; holding still")

    def reset(self) -> Outcome:
        """Back to the rest pose, instantly (the world takes care of a held object)."""
        self.activity = "idle"
        self.planned = False
        self.delivery_left = 0.0
        self.teleport(_REST)
        return Outcome(True, "robot back in its rest pose")

    def can_reach(self) -> bool:
        """True when a grasp of the object, where it is now, would be reachable."""
        return self.plan_grasp(self.object.position()) is not None
