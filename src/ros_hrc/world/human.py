"""The simulated human: an articulated body that walks, looks, warns and reaches, and the
predicates the robot's observer reads (seed Table 3.2).

Every action is a motion (see :mod:`.body`): a generator stepped by the world's loop that
moves real joints and returns an :class:`~.outcome.Outcome`. The predicates are computed from
the current geometry on each call, except the ones that describe what the human is doing
(attempting, idle, warning), which follow the last action:

* ``is_ov``  object inside the eyes' field-of-view cone and the line of sight not blocked
  (a ray from the eyes to the object's centre hits the object first);
* ``is_oir`` one hand can be brought to the object: arm inverse kinematics from the shoulder,
  leaning forwards at the waist if need be (up to ``max_lean_deg``);
* ``is_ho``  the object is attached to one of the human's hands;
* ``is_a0``  a reach is under way, or the last action was a reach that ended empty-handed;
* ``is_a2``  idle: at the belt, not moving, hands empty, not warning and not attempting;
* ``is_h4``  the last action was ``warn_robot`` (the arm stays raised until the next action).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Dict, Optional, Tuple

import numpy as np

from .body import ArticulatedBody, Motion
from .client import PhysicsClient
from .geometry import angle_between, clamp_to_sphere, rot_y, two_link_ik, wrap_angle
from .object import NOBODY, WorkObject
from .outcome import Outcome, Reading

#: Collision group of the human's links. With mask 1 they touch neither the scenery nor the
#: robot (their motion is scripted), yet rays still hit them, so the human can block a line
#: of sight; the world switches off their contacts with the object pair by pair.
HUMAN_GROUP = 4

SIDES = ("left", "right")


@dataclass(frozen=True)
class HumanConfig:
    """Where the human stands and the parameters of perception and motion."""

    station: Tuple[float, float] = (-0.45, -0.42)  # root on the floor at the belt, m
    facing: float = math.pi / 2                    # yaw of the station: +pi/2 faces +y (the belt)
    fov_half_angle_deg: float = 45.0               # half-angle of the field-of-view cone
    max_lean_deg: float = 30.0                     # forward lean allowed when reaching
    grasp_tolerance: float = 0.05                  # hand-to-object distance that closes a grasp, m
    miss_distance: Tuple[float, float] = (0.08, 0.13)  # how far attempt_grasp misses by, m
    walk_distance: float = 1.5                     # walk_away, m
    look_angle_deg: float = 80.0                   # look_around turns the head this far each way
    reach_time: float = 1.2                        # s
    walk_time: float = 1.6                         # s, for walk_distance
    turn_time: float = 0.8                         # s, to turn round
    # A walk away while already away: he stays away this long, and the belt runs on (0: the
    # step takes no time, the seed study's world; docs/world.md).
    away_time: float = 0.0                         # s


@dataclass(frozen=True)
class _Arm:
    side: str
    yaw: str
    pitch: str
    elbow: str
    hand: str
    shoulder_link: str
    offset: np.ndarray   # shoulder position in the torso frame (waist joint at the origin)
    upper: float         # shoulder to elbow, m
    lower: float         # elbow to palm centre, m
    inward: float        # sign of shoulder yaw that swings the arm across the body


@dataclass(frozen=True)
class ArmSolution:
    """Joint targets that put a hand on a point, and the lean they need."""

    side: str
    targets: Dict[str, float]
    lean: float
    exact: bool  # False: best effort towards a point out of reach


_REST = {"base_x": 0.0, "base_y": 0.0, "base_yaw": 0.0, "waist_pitch": 0.0, "neck_yaw": 0.0,
         "left_hip": 0.0, "right_hip": 0.0}
_ARM_REST = {"yaw": 0.0, "pitch": 0.08, "elbow": 0.25}
_ARM_CARRY = {"yaw": 0.35, "pitch": 0.85, "elbow": 1.45}   # object held in front of the chest
_ARM_WARN = {"yaw": -0.25, "pitch": 2.9, "elbow": 0.25}    # raised high, slightly outwards


class Human(ArticulatedBody):
    """The human body, its actions (motions) and its predicates."""

    def __init__(self, client: PhysicsClient, urdf_path: str, config: HumanConfig,
                 control_period: float, work_object: WorkObject, rng: np.random.Generator,
                 split_visuals: Optional[bool] = None) -> None:
        super().__init__(client, urdf_path, (*config.station, 0.0), config.facing, control_period,
                         split_visuals)
        self.config = config
        self.object = work_object
        self.rng = rng
        self.set_collision_group(HUMAN_GROUP, 1)
        self.arms = {side: self._measure_arm(side) for side in SIDES}
        self.activity = "idle"      # last action started (and, for gestures, still shown)
        self.attempting = False     # see is_a0
        self.moving = False         # set by the world while a motion runs
        self._holding_side: Optional[str] = None
        self.teleport(self.rest_pose())

    def _measure_arm(self, side: str) -> _Arm:
        # Lengths and offsets come from the URDF itself, measured in the zero pose at load time.
        torso_position, torso_rotation = self.link_frame("torso")
        shoulder, _ = self.link_frame(f"{side}_shoulder")
        elbow, _ = self.link_frame(f"{side}_forearm")
        hand, _ = self.link_frame(f"{side}_hand")
        return _Arm(side, f"{side}_shoulder_yaw", f"{side}_shoulder_pitch", f"{side}_elbow",
                    f"{side}_hand", f"{side}_shoulder",
                    torso_rotation.T @ (shoulder - torso_position),
                    float(np.linalg.norm(elbow - shoulder)), float(np.linalg.norm(hand - elbow)),
                    -1.0 if side == "left" else 1.0)

    # --- poses ------------------------------------------------------------------------------
    def _arm_pose(self, side: str, pose: Dict[str, float]) -> Dict[str, float]:
        arm = self.arms[side]
        return {arm.yaw: pose["yaw"] * arm.inward, arm.pitch: pose["pitch"], arm.elbow: pose["elbow"]}

    def rest_pose(self) -> Dict[str, float]:
        """Standing at the station, arms down, looking at the belt."""
        pose = dict(_REST)
        for side in SIDES:
            pose.update(self._arm_pose(side, _ARM_REST))
        return pose

    def holding_side(self) -> Optional[str]:
        """Which hand holds the object, if the human holds it."""
        return self._holding_side if self.object.holder == "human" else None

    def _relax(self, keep_holding: bool = True) -> Dict[str, float]:
        """Targets that lower the free arms and straighten up, keeping the holding arm as it is."""
        pose = {"waist_pitch": 0.0, "neck_yaw": 0.0}
        for side in SIDES:
            if keep_holding and side == self.holding_side():
                continue
            pose.update(self._arm_pose(side, _ARM_REST))
        return pose

    # --- geometry -----------------------------------------------------------------------------
    def at_station(self) -> bool:
        """True when the human stands at the belt, facing it."""
        q = self.positions(("base_x", "base_y", "base_yaw"))
        return math.hypot(q["base_x"], q["base_y"]) < 0.2 and abs(wrap_angle(q["base_yaw"])) < 0.3

    def shoulder_distance(self, side: str, point: np.ndarray) -> float:
        """Distance from the shoulder of ``side`` to ``point``."""
        return float(np.linalg.norm(self.link_frame(self.arms[side].shoulder_link)[0] - point))

    def nearer_side(self, point: np.ndarray) -> str:
        """The arm whose shoulder is closer to ``point`` (a free arm when one hand holds the object)."""
        free = [s for s in SIDES if s != self.holding_side()]
        return min(free, key=lambda s: self.shoulder_distance(s, point))

    def _arm_ik(self, arm: _Arm, target: np.ndarray, lean: float,
                pelvis_rotation: np.ndarray, pivot: np.ndarray, exact: bool) -> Optional[Dict[str, float]]:
        rotation = pelvis_rotation @ rot_y(lean)
        shoulder = pivot + rotation @ arm.offset
        if not exact:
            target = clamp_to_sphere(target, shoulder, 0.97 * (arm.upper + arm.lower))
        local = rotation.T @ (target - shoulder)
        yaw = math.atan2(local[1], local[0])
        yaw_joint = self.joint(arm.yaw)
        if not exact:
            yaw = yaw_joint.clamp(yaw)
        elif yaw_joint.clamp(yaw) != yaw:
            return None
        forward = local[0] * math.cos(yaw) + local[1] * math.sin(yaw)
        solution = two_link_ik(forward, local[2], arm.upper, arm.lower)
        if solution is None:
            if exact:
                return None
            solution = (math.atan2(local[2], max(forward, 0.05)), 0.3)
        pitch, elbow = solution[0] + math.pi / 2, solution[1]
        joints = {arm.pitch: pitch, arm.elbow: elbow}
        if exact and any(self.joint(n).clamp(v) != v for n, v in joints.items()):
            return None
        return {arm.yaw: yaw, **joints, "waist_pitch": lean}

    def solve_reach(self, side: str, target: np.ndarray, best_effort: bool = False) -> Optional[ArmSolution]:
        """Joint targets putting the ``side`` palm on ``target`` with the least forward lean.

        None when no lean up to ``max_lean_deg`` makes it reachable, unless ``best_effort``: then
        the arm stretches towards the target as far as it can, leaning fully.
        """
        arm = self.arms[side]
        pivot, _ = self.link_frame("torso")
        _, pelvis_rotation = self.link_frame("pelvis")
        max_lean = math.radians(self.config.max_lean_deg)

        def solve(lean: float) -> Optional[Dict[str, float]]:
            return self._arm_ik(arm, target, lean, pelvis_rotation, pivot, exact=True)

        coarse = [max_lean * i / 6 for i in range(7)]
        for i, lean in enumerate(coarse):
            targets = solve(lean)
            if targets is None:
                continue
            # Refine between the last failing and first working lean: the smallest lean that
            # works, so the human does not bob up and down as the goal moves.
            low, high = (coarse[i - 1], lean) if i else (lean, lean)
            for _ in range(6 if i else 0):
                mid = (low + high) / 2
                found = solve(mid)
                if found is None:
                    low = mid
                else:
                    high, targets = mid, found
            return ArmSolution(side, targets, high, True)
        if not best_effort:
            return None
        targets = self._arm_ik(arm, target, max_lean, pelvis_rotation, pivot, exact=False)
        return ArmSolution(side, targets, max_lean, False)

    def hand_position(self, side: str) -> np.ndarray:
        """World position of the palm centre of ``side``."""
        return self.link_frame(self.arms[side].hand)[0]

    # --- predicates -------------------------------------------------------------------------------
    def is_ov(self) -> Reading:
        """Object visible: inside the field-of-view cone of the eyes and not occluded."""
        eyes, rotation = self.link_frame("eyes")
        target = self.object.position()
        off_axis = math.degrees(angle_between(rotation[:, 0], target - eyes))
        limit = self.config.fov_half_angle_deg
        if off_axis > limit:
            return Reading(False, f"object out of view: {off_axis:.0f} deg from the line of sight "
                                  f"(field of view +/-{limit:.0f} deg)")
        # The human's own body is left out of the ray (its group bit is not in the mask).
        hit = self.client.rayTest(eyes.tolist(), target.tolist(),
                                  collisionFilterMask=0xFF & ~HUMAN_GROUP)[0]
        if hit[0] not in (-1, self.object.body_id):
            name = self.client.getBodyInfo(hit[0])[1].decode() or f"body {hit[0]}"
            return Reading(False, f"object in the field of view ({off_axis:.0f} deg off the line "
                                  f"of sight) but hidden behind {name}")
        return Reading(True, f"object in view: {off_axis:.0f} deg from the line of sight "
                             f"(field of view +/-{limit:.0f} deg), line of sight clear")

    def is_oir(self) -> Reading:
        """Object in reach of a hand (arm from the shoulder, leaning forward if need be)."""
        if self.object.holder == "human":
            return Reading(True, f"object in reach: held in the {self.holding_side()} hand")
        target = self.object.position()
        for side in sorted(SIDES, key=lambda s: self.shoulder_distance(s, target)):
            solution = self.solve_reach(side, target)
            if solution is not None:
                return Reading(True, f"object in reach of the {side} hand "
                                     f"(leaning {math.degrees(solution.lean):.0f} deg)")
        side = min(SIDES, key=lambda s: self.shoulder_distance(s, target))
        arm = self.arms[side]
        return Reading(False, f"object out of reach: {self.shoulder_distance(side, target):.2f} m from "
                              f"the nearer ({side}) shoulder; the arm reaches "
                              f"{arm.upper + arm.lower:.2f} m, leaning up to "
                              f"{self.config.max_lean_deg:.0f} deg")

    def is_ho(self) -> Reading:
        """The human holds the object."""
        holder = self.object.holder
        if holder == "human":
            return Reading(True, f"the human holds the object in the {self.holding_side()} hand")
        return Reading(False, "the robot holds the object" if holder == "robot"
                       else "nobody holds the object")

    def is_a0(self) -> Reading:
        """The human is attempting a grasp (or the last reach ended empty-handed)."""
        if self.attempting:
            state = "reaching" if self.moving else "the reach ended empty-handed"
            return Reading(True, f"attempting a grasp ({self.activity}: {state})")
        return Reading(False, f"not attempting a grasp (last action: {self.activity})")

    def is_a2(self) -> Reading:
        """The human is idle at the belt."""
        if self.moving:
            return Reading(False, f"not idle: busy with {self.activity}")
        if not self.at_station():
            return Reading(False, "not idle: away from the belt")
        if self.object.holder == "human":
            return Reading(False, "not idle: holds the object")
        if self.activity == "warn_robot":
            return Reading(False, "not idle: warning the robot")
        if self.attempting:
            return Reading(False, "not idle: attempting a grasp")
        return Reading(True, f"idle at the belt (last action: {self.activity})")

    def is_h4(self) -> Reading:
        """The human is warning the robot (arm raised)."""
        if self.activity == "warn_robot":
            return Reading(True, "warning the robot: arm raised" + (" (raising)" if self.moving else ""))
        return Reading(False, f"not warning the robot (last action: {self.activity})")

    # --- actions (motions) ----------------------------------------------------------------------
    def _start(self, activity: str, attempting: bool = False) -> None:
        self.activity = activity
        self.attempting = attempting

    @staticmethod
    def _legs(cycles: int) -> Callable[[float], Dict[str, float]]:
        amplitude = 0.35

        def swing(fraction: float) -> Dict[str, float]:
            phase = amplitude * math.sin(2 * math.pi * cycles * fraction)
            return {"left_hip": phase, "right_hip": -phase}
        return swing

    def _walk_back(self) -> Motion:
        """Turn round and walk back to the station, facing the belt."""
        c = self.config
        yield from self.move({**self._relax(), "base_yaw": 0.0}, c.turn_time)
        q = self.positions(("base_x", "base_y"))
        distance = math.hypot(q["base_x"], q["base_y"])
        yield from self.move({"base_x": 0.0, "base_y": 0.0},
                             max(0.5, c.walk_time * distance / c.walk_distance), extra=self._legs(3))

    def walk_away(self) -> Motion:
        """Turn round and walk away from the belt (carrying the object if holding it)."""
        self._start("walk_away")
        c = self.config
        if not self.at_station():
            if c.away_time > 0:
                yield from self.pause(c.away_time)
                return Outcome(True, f"stays away from the belt for {c.away_time:g} s")
            return Outcome(True, "already away from the belt")
        yield from self.move({**self._relax(), "base_yaw": math.pi}, c.turn_time)
        yield from self.move({"base_x": -c.walk_distance}, c.walk_time, extra=self._legs(3))
        distance = self.shoulder_distance(self.nearer_side(self.object.position()), self.object.position())
        if self.object.holder == "human":
            return Outcome(True, f"walked {c.walk_distance:.1f} m away from the belt, carrying the object")
        return Outcome(True, f"walked {c.walk_distance:.1f} m away from the belt; the object is "
                             f"{distance:.2f} m away, out of reach")

    def look_around(self) -> Motion:
        """Turn the head to one side, then the other, then back to the belt."""
        self._start("look_around")
        angle = math.radians(self.config.look_angle_deg)
        seen = {"before": self.is_ov().value, "left": False, "hidden": 0}
        visible_steps = {"count": 0}

        def watched(motion: Motion) -> Motion:
            for _ in motion:
                if not self.is_ov().value:
                    seen["hidden"] += 1
                else:
                    visible_steps["count"] += 1
                yield

        yield from watched(self.move({"neck_yaw": angle}, 0.8))
        yield from watched(self.pause(0.25))
        yield from watched(self.move({"neck_yaw": -angle}, 1.3))
        yield from watched(self.pause(0.25))
        yield from watched(self.move({"neck_yaw": 0.0}, 0.8))
        hidden = seen["hidden"] * self.control_period
        now = self.is_ov().value
        if not seen["before"] and not visible_steps["count"]:
            return Outcome(True, f"looked {self.config.look_angle_deg:.0f} deg left and right; "
                                 "the object was never in view")
        if not hidden:
            return Outcome(True, "looked left and right; the object stayed in view")
        return Outcome(True, f"looked {self.config.look_angle_deg:.0f} deg left and right; the "
                             f"object was out of view for {hidden:.1f} s and "
                             + ("is back in view" if now else "is still out of view"))

    def warn_robot(self) -> Motion:
        """Raise the left arm (the right one if the left holds the object) and wave once."""
        self._start("warn_robot")
        side = "right" if self.holding_side() == "left" else "left"
        raised = self._arm_pose(side, _ARM_WARN)
        elbow = self.arms[side].elbow
        yield from self.move({**self._relax(), **raised}, 1.0)
        for _ in range(2):
            yield from self.move({elbow: 0.9}, 0.3)
            yield from self.move({elbow: raised[elbow]}, 0.3)
        return Outcome(True, f"raised the {side} arm to warn the robot")

    def attempt_grasp(self) -> Motion:
        """Reach for the object and miss it (walking back to the belt first if away)."""
        self._start("attempt_grasp", attempting=True)
        if self.object.holder == "human":
            self.attempting = False
            return Outcome(False, "cannot attempt a grasp: already holds the object")
        if not self.at_station():
            yield from self._walk_back()
        low, high = self.config.miss_distance
        heading = self.rng.uniform(0, 2 * math.pi)
        offset = self.rng.uniform(low, high) * np.array([math.cos(heading), math.sin(heading), 0.0])
        offset[2] = 0.04  # pass just above it, as a fumbled grasp does
        side = self.nearer_side(self.object.position())
        yield from self.track(lambda: self.solve_reach(
            side, self.object.position() + offset, best_effort=True).targets, self.config.reach_time)
        yield from self.pause(0.3)
        miss = float(np.linalg.norm(self.hand_position(side) - self.object.position()))
        yield from self.move(self._relax(), 0.9)
        return Outcome(True, f"reached for the object with the {side} hand and missed it by {miss:.2f} m")

    def grasp(self) -> Motion:
        """Reach for the object and take it if the hand gets to it; otherwise say why not."""
        self._start("grasp", attempting=True)
        if self.object.holder == "human":
            self.attempting = False
            return Outcome(True, f"already holds the object in the {self.holding_side()} hand")
        if self.object.holder == "robot":
            self.attempting = False
            return Outcome(False, "cannot grasp: the robot holds the object")
        walked = ""
        if not self.at_station():
            yield from self._walk_back()
            walked = "walked back to the belt and "
        target = self.object.position()
        side = self.nearer_side(target)
        reachable = self.solve_reach(side, target) is not None
        distance_at_start = self.shoulder_distance(side, target)
        yield from self.track(lambda: self.solve_reach(
            side, self.object.position(), best_effort=True).targets, self.config.reach_time)
        arm = self.arms[side]
        gap = float(np.linalg.norm(self.hand_position(side) - self.object.position()))
        if gap <= self.config.grasp_tolerance and self.object.holder == NOBODY:
            self.object.attach("human", lambda: self.link_pose(arm.hand))
            self._holding_side = side
            self.attempting = False
            yield from self.move({**self._arm_pose(side, _ARM_CARRY), "waist_pitch": 0.0}, 0.8)
            return Outcome(True, f"{walked}grasped the object with the {side} hand")
        yield from self.move(self._relax(), 0.8)
        if self.object.holder == "robot":
            return Outcome(False, "missed: the robot took the object first")
        if not reachable:
            return Outcome(False, f"{walked}failed: the object was out of reach, "
                                  f"{distance_at_start:.2f} m from the {side} shoulder (the arm "
                                  f"reaches {arm.upper + arm.lower:.2f} m, leaning up to "
                                  f"{self.config.max_lean_deg:.0f} deg)")
        return Outcome(False, f"{walked}failed: the hand ended {gap:.2f} m from the object "
                              "(it moved out of reach)")

    def idle(self) -> Motion:
        """Lower the arms, look at the belt and do nothing (stays where it is)."""
        self._start("idle")
        yield from self.move(self._relax(), 0.8)
        where = "at the belt" if self.at_station() else "away from the belt"
        return Outcome(True, f"stands idle {where}")

    def reset(self) -> Outcome:
        """Back to the station, at rest, instantly (the world puts the object back)."""
        self._start("idle")
        self._holding_side = None
        self.teleport(self.rest_pose())
        return Outcome(True, "human back at the belt, at rest")
