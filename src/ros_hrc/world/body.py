"""An articulated body loaded from URDF, moved kinematically by joints looked up by name.

The agents' motions are scripted and touch nothing (the object is held by the world, not by
contact), so their joints are set, not simulated: each command puts the joints exactly at
their targets. Their bodies live in the world's scene server, which is never stepped
(see :mod:`.scene`).

Motions are generators: each ``next()`` sets the joint targets for one control step and the
world's stepping loop steps the physics in between. That keeps every PyBullet call on the
stepping thread and lets a reset stop a motion between two steps (``generator.close()``).
"""
from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Dict, Iterable, Iterator, List, Mapping, Optional, Sequence, Tuple
from xml.etree import ElementTree

import numpy as np

from ..errors import SimulationError
from .client import PhysicsClient
from .geometry import min_jerk, quat_to_matrix, yaw_quaternion
from .visuals import visual_layers

#: A motion: advanced once per control step; its return value (StopIteration.value) is the result.
Motion = Iterator[None]
#: A tracking motion solves its goal again every this many control steps (20 Hz at 60 Hz): the
#: object moves 1 mm in that time on the belt, and the goal's solution (arm IK) is most of a
#: control step's Python time.
TRACK_EVERY = 3


@dataclass(frozen=True)
class Joint:
    """A movable joint of the URDF, as PyBullet reports it."""

    name: str
    index: int           # PyBullet's joint index, which is also the child link's index
    lower: float
    upper: float

    def clamp(self, value: float) -> float:
        """``value`` limited to the joint's range (URDF limits; none when lower > upper)."""
        if self.lower > self.upper:
            return value
        return min(self.upper, max(self.lower, value))


class ArticulatedBody:
    """A fixed-base multibody whose movable joints are set kinematically.

    ``commanded`` keeps the last target of every joint: where a new motion starts from.
    """

    def __init__(self, client: PhysicsClient, urdf_path: str, position: Sequence[float],
                 yaw: float, control_period: float, split_visuals: Optional[bool] = None) -> None:
        self.client = client
        self.control_period = control_period   # simulated seconds per motion step
        self.urdf_path = urdf_path
        # With split_visuals (default: in PyBullet's window) the body is loaded in colour
        # layers (see .visuals): body_id is layer 0, with the URDF's links, joints and
        # collision shapes; `twins` are the other layers, visual only, moved along.
        self.twins: List[int] = []
        if split_visuals is None:
            split_visuals = client.gui
        ids = self._load(urdf_path, position, yaw, split_visuals)
        self.body_id, self.twins = ids[0], ids[1:]
        for twin in self.twins:   # looks only: nothing collides with them, no ray hits them
            _set_collision_group(client, twin, 0, 0)
        self.joints: Dict[str, Joint] = {}
        self.links: Dict[str, int] = {client.getBodyInfo(self.body_id)[0].decode(): -1}
        for index in range(client.getNumJoints(self.body_id)):
            info = client.getJointInfo(self.body_id, index)
            self.links[info[12].decode()] = index
            if info[2] in (client.JOINT_REVOLUTE, client.JOINT_PRISMATIC):
                name = info[1].decode()
                self.joints[name] = Joint(name, index, info[8], info[9])
        self.commanded: Dict[str, float] = {name: 0.0 for name in self.joints}

    def _load(self, urdf_path: str, position: Sequence[float], yaw: float,
              split_visuals: bool) -> List[int]:
        """Load the URDF (in colour layers with ``split_visuals``); the body ids, layer 0 first."""
        pose = dict(basePosition=list(position), baseOrientation=yaw_quaternion(yaw), useFixedBase=True)
        try:
            if not split_visuals:
                return [self.client.loadURDF(urdf_path, **pose)]
            text = Path(urdf_path).read_text(encoding="utf-8")
            layers = visual_layers(text, str(Path(urdf_path).resolve().parent))
            ids = []
            with tempfile.TemporaryDirectory(prefix="ros_hrc_urdf_") as tmp:
                for k, layer in enumerate(layers):
                    path = Path(tmp) / f"{Path(urdf_path).stem}_{k}.urdf"
                    path.write_text(layer, encoding="utf-8")
                    ids.append(self.client.loadURDF(str(path), **pose))
            return ids
        except (self.client.error, OSError, ElementTree.ParseError) as error:  # a missing or malformed file
            raise SimulationError(f"cannot load {urdf_path}: {error}") from error

    # --- lookup -------------------------------------------------------------------------
    def joint(self, name: str) -> Joint:
        """The movable joint called ``name`` in the URDF."""
        try:
            return self.joints[name]
        except KeyError:
            raise SimulationError(f"URDF of body {self.body_id} has no movable joint {name!r}") from None

    def link(self, name: str) -> int:
        """PyBullet link index of the URDF link ``name`` (-1 for the root link)."""
        try:
            return self.links[name]
        except KeyError:
            raise SimulationError(f"URDF of body {self.body_id} has no link {name!r}") from None

    # --- reading state ----------------------------------------------------------------------
    def positions(self, names: Iterable[str]) -> Dict[str, float]:
        """Measured positions of the named joints."""
        names = list(names)
        states = self.client.getJointStates(self.body_id, [self.joint(n).index for n in names])
        return {n: s[0] for n, s in zip(names, states)}

    def link_pose(self, name: str) -> Tuple[Sequence[float], Sequence[float]]:
        """World position and quaternion (x, y, z, w) of the URDF frame of link ``name``."""
        index = self.link(name)
        if index < 0:
            return self.client.getBasePositionAndOrientation(self.body_id)
        state = self.client.getLinkState(self.body_id, index, computeForwardKinematics=True)
        return state[4], state[5]

    def link_frame(self, name: str) -> Tuple[np.ndarray, np.ndarray]:
        """World position and 3x3 rotation of the URDF frame of link ``name``."""
        position, orientation = self.link_pose(name)
        return np.array(position), quat_to_matrix(orientation)

    def frames(self) -> Dict[str, object]:
        """Where the body is, as plain data (for /tf and joint states): its URDF file, root
        link, base pose and movable joints' positions."""
        c = self.client
        return {"urdf": self.urdf_path, "root": c.getBodyInfo(self.body_id)[0].decode(),
                "base": c.getBasePositionAndOrientation(self.body_id),
                "joints": self.positions(self.joints)}

    # --- commanding -----------------------------------------------------------------------
    def command(self, targets: Mapping[str, float]) -> None:
        """Put the named joints at their targets (clamped to the joint limits)."""
        if not targets:
            return
        indices, values = [], []
        for name, value in targets.items():   # on the per-step path: plain loops, one call
            joint = self.joint(name)
            value = joint.clamp(value)
            indices.append(joint.index)
            values.append([value])
            self.commanded[name] = value
        self.client.resetJointStatesMultiDof(self.body_id, indices, values)
        for twin in self.twins:   # the other colour layers: same tree, same joint indices
            self.client.resetJointStatesMultiDof(twin, indices, values)

    def teleport(self, pose: Mapping[str, float]) -> None:
        """Set joints instantly (resets: one command, not a motion)."""
        self.command(pose)

    # --- motions --------------------------------------------------------------------------
    def steps(self, duration: float) -> int:
        """Number of control steps in ``duration`` seconds (at least one)."""
        return max(1, int(round(duration / self.control_period)))

    def move(self, goal: Mapping[str, float], duration: float,
             extra: Optional[Callable[[float], Mapping[str, float]]] = None) -> Motion:
        """Motion: joints from their commanded positions to ``goal`` along a minimum-jerk profile.

        ``extra(fraction)`` may add targets for other joints at each step (e.g. legs swinging
        while walking).
        """
        start = {n: self.commanded[n] for n in goal}
        n_steps = self.steps(duration)
        for i in range(1, n_steps + 1):
            s = min_jerk(i / n_steps)
            targets = {n: start[n] + s * (goal[n] - start[n]) for n in goal}
            if extra is not None:
                targets.update(extra(i / n_steps))
            self.command(targets)
            yield

    def track(self, solve: Callable[[], Mapping[str, float]], duration: float) -> Motion:
        """Motion: like :meth:`move`, but the goal is solved again as it goes (a moving target):
        every ``TRACK_EVERY`` steps, and at the last step."""
        goal = solve()
        start = {n: self.commanded[n] for n in goal}
        n_steps = self.steps(duration)
        for i in range(1, n_steps + 1):
            s = min_jerk(i / n_steps)
            if i > 1 and (i % TRACK_EVERY == 0 or i == n_steps):
                goal = solve()
            self.command({n: start[n] + s * (goal[n] - start[n]) for n in goal})
            yield

    def pause(self, duration: float) -> Motion:
        """Motion: keep the current targets for ``duration`` seconds."""
        for _ in range(self.steps(duration)):
            yield

    def set_collision_group(self, group: int, mask: int) -> None:
        """Put the root and every link into collision ``group``, colliding with ``mask``."""
        _set_collision_group(self.client, self.body_id, group, mask)

    def joint_names(self, prefix: str = "") -> List[str]:
        """Names of the movable joints starting with ``prefix``."""
        return [n for n in self.joints if n.startswith(prefix)]


def _set_collision_group(client: PhysicsClient, body_id: int, group: int, mask: int) -> None:
    """Put the root and every link of ``body_id`` into collision ``group``, colliding with ``mask``."""
    for index in [-1] + list(range(client.getNumJoints(body_id))):
        client.setCollisionFilterGroupMask(body_id, index, group, mask)
