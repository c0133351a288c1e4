#!/usr/bin/env python3
"""Write FABRIC's model files (the seed authors' successor task) from the authors' figures.

    python tools/make_fabric_models.py --out models/fabric

rewrites ``human/*.pomdpx`` (the ten human types, 12-state MDPs) and ``robot/*.pomdpx`` (the
base robot POMDP, four of its policy variants and the reactive robot MDP) under ``--out``.
The output is deterministic: a rerun writes the same bytes (a test checks the shipped files).

Where the figures come from: the GitHub repository ``cangorur/human_robot_collaboration``
(GPL-3.0), the files named in :data:`SOURCES` at the commits named there; the papers are Görür
et al., "Social Cobots", HRI 2018, and ACM THRI 2023 (DOI 10.1145/3585276). Only numbers are
taken (probabilities, rewards, discounts: facts); the tables below are our own layout and the
files are written by the package's own POMDPX writer. ``models/README.md`` ("FABRIC (the
successor task)") says file by file what was taken and what was changed.

Layout of the tables below. One line per *current* state: its name, then the probabilities of
the next states in the model's state order. A human line has 11 numbers, one per state but
``TaskRobot`` (the authors give that column 0 in every row a human leaves; the 12th number is
added here), or 12 for the ``TaskRobot`` row itself. ``stay`` means 0.9 on the current state and
0.01 on each other column the row spans (the authors' most common row). A state without a line
keeps its state with probability 1 (the terminal states, and most rows of ``warnRobot``).
Rewards are lists of (action, next state, value), ``*`` meaning every one; as in POMDPX a later
entry overrides an earlier one; the reward is earned on arriving in the next state, whatever the
state left (the authors' files reward ``R(action, state_1)``).

ROS-free: only numpy, scipy and ros_hrc.pomdp.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np
import scipy.sparse as sp

REPO = Path(__file__).resolve().parents[1]
if str(REPO / "src") not in sys.path:       # run from a checkout without an installed package
    sys.path.insert(0, str(REPO / "src"))

from ros_hrc.pomdp import pomdpx  # noqa: E402
from ros_hrc.pomdp.model import Model  # noqa: E402
from ros_hrc.pomdp.output import write_text_atomically  # noqa: E402
from ros_hrc.tasks.fabric import FABRIC  # noqa: E402

SOURCE_REPOSITORY = "cangorur/human_robot_collaboration"
#: The commit the task names (the repository's master) and the commits the figures were read at:
#: the files' stored versions (the figures of a file that changed later are its last version's).
TASK_COMMIT = "c0e027db586952ad69d5eac988aaf5d74f858933"
C8D1 = "c8d1a3767e40f8ad71cd6d18e970dbe9b268e5df"
A3F7 = "a3f79d3ded6491fd4dbb2230620a406df512e888"
FIRST = "615a156d0a3f146315e8b41b8fb24e955747ee76"

DISCOUNT = 0.98
STAY = 0.9          # a "stay" row: this on the current state ...
FLOOR = 0.01        # ... and this on every other column the row spans

# --------------------------------------------------------------------------------------------
# The human (12-state MDP): names and order as the authors' files, which the task holds
# --------------------------------------------------------------------------------------------
HUMAN_STATES = list(FABRIC.human_states)
HUMAN_ACTIONS = list(FABRIC.human_actions)

#: The one row every type shares outside the stay-where-you-are default: a task the robot
#: holds ends (success 0.4, fail 0.1) or draws a warning (0.2) when the human idles.
HUMAN_TASKROBOT_IDLE = "TaskRobot  0 0.4 0.1 0 0 0 0 0 0 0.2 0 0.3"


@dataclass(frozen=True)
class HumanType:
    """One of the ten human types: its source file, T rows per action, rewards."""
    source: str
    commit: str
    tables: Dict[str, str]
    rewards: Sequence[Tuple[str, str, float]]


_B_WALK = """
    TaskHuman        0.5  0.01 0.41 0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.41 0.5  0.01 0.01 0.01 0.01 0.01 0.01 0.01
    NoAttention      0.01 0.01 0.01 0.01 0.81 0.01 0.01 0.1  0.01 0.01 0.01
    Evaluating       0.01 0.01 0.32 0.01 0.01 0.5  0.01 0.1  0.01 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.01 0.8  0.11 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.1  0.81 0.01 0.01
    WarningTheRobot  0.01 0.01 0.3  0.01 0.01 0.01 0.01 0.22 0.01 0.4  0.01
    RobotIsWarned    0.01 0.01 0.45 0.01 0.01 0.01 0.01 0.15 0.01 0.01 0.32
"""

HUMAN_TYPES: Dict[str, HumanType] = {
    "beginner_nontired_collaborative": HumanType(
        "code/models/human_models/Evaluate/beginner_nontired_collaborative.POMDPx", C8D1,
        {"graspAttempt": """
    TaskHuman        0.2  0.09 0.2  0.44 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.1  0.22 0.43 0.01 0.01 0.07 0.01 0.12 0.01 0.01
    NoAttention      0.01 0.09 0.2  0.38 0.17 0.02 0.01 0.01 0.09 0.01 0.01
    Evaluating       0.01 0.24 0.1  0.58 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    Tired            0.01 0.01 0.1  0.35 0.01 0.01 0.47 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.1  0.15 0.08 0.01 0.01 0.01 0.01 0.46 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.1  0.29 0.3  0.01 0.01 0.01 0.01 0.01 0.01 0.24
""", "lookAround": """
    TaskHuman        0.1  0.01 0.01 0.01 0.38 0.3  0.15 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.1  0.23 0.38 0.09 0.01 0.1  0.05 0.01
    NoAttention      0.01 0.01 0.09 0.01 0.36 0.3  0.01 0.01 0.18 0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.33 0.41 0.1  0.01 0.09 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.21 0.15 0.56 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01 0.71 0.01 0.01
    WarningTheRobot  0.01 0.01 0.01 0.01 0.05 0.01 0.01 0.01 0.07 0.8  0.01
    RobotIsWarned    0.01 0.01 0.31 0.01 0.23 0.2  0.1  0.01 0.01 0.01 0.1
""", "idle": """
    TaskHuman        0.11 0.01 0.01 0.01 0.01 0.76 0.05 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.05 0.05 0.64 0.1  0.01 0.1  0.01 0.01
    NoAttention      0.01 0.1  0.1  0.01 0.63 0.01 0.01 0.01 0.1  0.01 0.01
    Evaluating       0.01 0.01 0.09 0.01 0.01 0.64 0.05 0.01 0.1  0.06 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.13 0.45 0.15 0.2  0.01 0.01
    Recovery         0.01 0.01 0.01 0.01 0.01 0.01 0.1  0.81 0.01 0.01 0.01
    RobotInterfered  0.01 0.3  0.05 0.01 0.01 0.01 0.01 0.01 0.43 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.01 0.01 0.01 0.01 0.76 0.15 0.01 0.01 0.01 0.01
""", "walkAway": _B_WALK, "warnRobot": """
    RobotInterfered  0 0 0 0 0 0 0 0 0.5 0.4  0.1
    WarningTheRobot  0 0 0 0 0 0 0 0 0   0.05 0.95
    RobotIsWarned    0 0 0.6 0 0 0 0 0 0 0 0.4
"""},
        [("graspAttempt", "GlobalSuccess", 4), ("idle", "GlobalSuccess", 1),
         ("idle", "Evaluating", 2), ("lookAround", "NoAttention", 1),
         ("walkAway", "Recovery", 4.2), ("graspAttempt", "FailedToGrasp", 2.5),
         ("graspAttempt", "GlobalFail", -2), ("*", "WarningTheRobot", -3),
         ("warnRobot", "*", -3), ("warnRobot", "RobotIsWarned", 3)]),

    "beginner_nontired_noncollaborative": HumanType(
        "code/models/human_models/beginner_nontired_noncollaborative.POMDPx", C8D1,
        {"graspAttempt": """
    TaskHuman        0.2  0.09 0.2  0.44 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.1  0.22 0.43 0.01 0.01 0.07 0.01 0.12 0.01 0.01
    NoAttention      0.01 0.09 0.2  0.38 0.17 0.02 0.01 0.01 0.09 0.01 0.01
    Evaluating       0.01 0.25 0.1  0.57 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    Tired            0.01 0.01 0.1  0.35 0.01 0.01 0.47 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.1  0.15 0.08 0.01 0.01 0.01 0.01 0.46 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.1  0.29 0.3  0.01 0.01 0.01 0.01 0.01 0.01 0.24
""", "lookAround": """
    TaskHuman        0.1  0.01 0.01 0.01 0.38 0.3  0.15 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.1  0.23 0.38 0.09 0.01 0.1  0.05 0.01
    NoAttention      0.01 0.01 0.09 0.01 0.36 0.3  0.01 0.01 0.18 0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.33 0.41 0.1  0.01 0.09 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.21 0.15 0.56 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01 0.71 0.01 0.01
    WarningTheRobot  0.01 0.01 0.01 0.01 0.05 0.01 0.01 0.01 0.07 0.8  0.01
    RobotIsWarned    0.01 0.01 0.31 0.01 0.23 0.2  0.1  0.01 0.01 0.01 0.1
""", "idle": """
    TaskHuman        0.11 0.01 0.01 0.01 0.01 0.76 0.05 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.05 0.05 0.64 0.1  0.01 0.1  0.01 0.01
    NoAttention      0.01 0.1  0.1  0.01 0.63 0.01 0.01 0.01 0.1  0.01 0.01
    Evaluating       0.01 0.01 0.09 0.01 0.01 0.64 0.05 0.01 0.1  0.06 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.13 0.45 0.15 0.2  0.01 0.01
    Recovery         0.01 0.01 0.01 0.01 0.01 0.01 0.1  0.81 0.01 0.01 0.01
    RobotInterfered  0.01 0.09 0.05 0.01 0.01 0.01 0.01 0.01 0.21 0.58 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.01 0.01 0.01 0.01 0.76 0.15 0.01 0.01 0.01 0.01
""", "walkAway": _B_WALK, "warnRobot": """
    RobotInterfered  0 0 0 0 0 0 0 0 0.5 0.4  0.1
    WarningTheRobot  0 0 0 0 0 0 0 0 0   0.05 0.95
    RobotIsWarned    0 0 0.6 0 0 0 0 0 0 0 0.4
"""},
        [("graspAttempt", "GlobalSuccess", 4), ("idle", "GlobalSuccess", 1),
         ("idle", "Evaluating", 2), ("lookAround", "NoAttention", 1),
         ("walkAway", "Recovery", 4.2), ("graspAttempt", "FailedToGrasp", 2.5),
         ("graspAttempt", "GlobalFail", -2), ("*", "WarningTheRobot", -3),
         ("warnRobot", "*", -3), ("warnRobot", "RobotIsWarned", 3)]),

    "beginner_tired_collaborative": HumanType(
        "code/models/human_models/Evaluate/beginner_tired_collaborative.POMDPx", A3F7,
        {"graspAttempt": """
    TaskHuman        0.2  0.09 0.3  0.34 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.1  0.22 0.43 0.01 0.01 0.07 0.01 0.12 0.01 0.01
    NoAttention      0.01 0.09 0.2  0.38 0.17 0.02 0.01 0.01 0.09 0.01 0.01
    Evaluating       0.01 0.25 0.1  0.57 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    Tired            0.01 0.01 0.1  0.4  0.01 0.01 0.42 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.1  0.15 0.08 0.01 0.01 0.01 0.01 0.46 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.1  0.29 0.3  0.01 0.01 0.01 0.01 0.01 0.01 0.24
""", "lookAround": """
    TaskHuman        0.1  0.01 0.01 0.01 0.23 0.1  0.5  0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.1  0.08 0.08 0.54 0.01 0.1  0.05 0.01
    NoAttention      0.01 0.01 0.09 0.01 0.26 0.2  0.21 0.01 0.18 0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.13 0.11 0.6  0.01 0.09 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.11 0.05 0.76 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01 0.52 0.2  0.01
    WarningTheRobot  0.01 0.01 0.01 0.01 0.05 0.01 0.01 0.01 0.07 0.8  0.01
    RobotIsWarned    0.01 0.01 0.31 0.01 0.23 0.2  0.1  0.01 0.01 0.01 0.1
""", "idle": """
    TaskHuman        0.11 0.01 0.01 0.01 0.01 0.51 0.3  0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.05 0.05 0.14 0.6  0.01 0.1  0.01 0.01
    NoAttention      0.01 0.1  0.1  0.01 0.63 0.01 0.01 0.01 0.1  0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.01 0.35 0.47 0.01 0.1  0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.18 0.33 0.22 0.2  0.01 0.01
    Recovery         0.01 0.01 0.01 0.01 0.01 0.01 0.05 0.86 0.01 0.01 0.01
    RobotInterfered  0.01 0.2  0.05 0.01 0.01 0.01 0.01 0.01 0.53 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.01 0.01 0.01 0.01 0.76 0.15 0.01 0.01 0.01 0.01
""", "walkAway": _B_WALK, "warnRobot": """
    RobotInterfered  0 0 0 0 0 0 0 0 0.5 0.4  0.1
    WarningTheRobot  0 0 0 0 0 0 0 0 0   0.05 0.95
    RobotIsWarned    0 0 0.6 0 0 0 0 0 0 0 0.4
"""},
        [("graspAttempt", "GlobalSuccess", 3), ("idle", "GlobalSuccess", 4.5),
         ("idle", "Evaluating", 4), ("lookAround", "NoAttention", 1),
         ("walkAway", "Recovery", 4.5), ("idle", "Tired", 2),
         ("graspAttempt", "FailedToGrasp", 1.8), ("graspAttempt", "GlobalFail", -2),
         ("warnRobot", "*", -3), ("*", "WarningTheRobot", -3),
         ("warnRobot", "RobotIsWarned", 3)]),

    "beginner_tired_noncollaborative": HumanType(
        "code/models/human_models/Evaluate/beginner_tired_noncollaborative.POMDPx", C8D1,
        {"graspAttempt": """
    TaskHuman        0.2  0.09 0.3  0.34 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.1  0.22 0.43 0.01 0.01 0.07 0.01 0.12 0.01 0.01
    NoAttention      0.01 0.09 0.2  0.38 0.17 0.02 0.01 0.01 0.09 0.01 0.01
    Evaluating       0.01 0.25 0.12 0.55 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    Tired            0.01 0.01 0.1  0.4  0.01 0.01 0.42 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.1  0.15 0.08 0.01 0.01 0.01 0.01 0.46 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.1  0.29 0.3  0.01 0.01 0.01 0.01 0.01 0.01 0.24
""", "lookAround": """
    TaskHuman        0.1  0.01 0.01 0.01 0.23 0.1  0.5  0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.1  0.08 0.08 0.54 0.01 0.1  0.05 0.01
    NoAttention      0.01 0.01 0.09 0.01 0.26 0.2  0.21 0.01 0.18 0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.13 0.11 0.6  0.01 0.09 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.11 0.05 0.76 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.3  0.01 0.01 0.01 0.22 0.4  0.01
    WarningTheRobot  0.01 0.01 0.01 0.01 0.05 0.01 0.01 0.01 0.07 0.8  0.01
    RobotIsWarned    0.01 0.01 0.31 0.01 0.23 0.2  0.1  0.01 0.01 0.01 0.1
""", "idle": """
    TaskHuman        0.11 0.01 0.01 0.01 0.01 0.51 0.3  0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.05 0.05 0.14 0.6  0.01 0.1  0.01 0.01
    NoAttention      0.01 0.1  0.1  0.01 0.63 0.01 0.01 0.01 0.1  0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.01 0.35 0.47 0.01 0.1  0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.18 0.33 0.22 0.2  0.01 0.01
    Recovery         0.01 0.01 0.01 0.01 0.01 0.01 0.08 0.83 0.01 0.01 0.01
    RobotInterfered  0.01 0.09 0.05 0.01 0.01 0.01 0.01 0.01 0.21 0.58 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.01 0.01 0.01 0.01 0.76 0.15 0.01 0.01 0.01 0.01
""", "walkAway": """
    TaskHuman        0.5  0.01 0.41 0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.41 0.5  0.01 0.01 0.01 0.01 0.01 0.01 0.01
    NoAttention      0.01 0.01 0.01 0.01 0.81 0.01 0.01 0.1  0.01 0.01 0.01
    Evaluating       0.01 0.01 0.32 0.01 0.01 0.5  0.01 0.1  0.01 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.01 0.8  0.11 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.2  0.71 0.01 0.01
    WarningTheRobot  0.01 0.01 0.3  0.01 0.01 0.01 0.01 0.22 0.01 0.4  0.01
    RobotIsWarned    0.01 0.01 0.45 0.01 0.01 0.01 0.01 0.15 0.01 0.01 0.32
""", "warnRobot": """
    RobotInterfered  0 0 0 0 0 0 0 0 0.5 0.4  0.1
    WarningTheRobot  0 0 0 0 0 0 0 0 0   0.05 0.95
    RobotIsWarned    0 0 0.2 0 0 0 0 0 0 0 0.8
"""},
        [("graspAttempt", "GlobalSuccess", 3), ("idle", "GlobalSuccess", 4.5),
         ("idle", "Evaluating", 4), ("lookAround", "NoAttention", 1),
         ("walkAway", "Recovery", 4.5), ("idle", "Tired", 2),
         ("graspAttempt", "FailedToGrasp", 1.8), ("graspAttempt", "GlobalFail", -2),
         ("warnRobot", "*", -3), ("*", "WarningTheRobot", -3),
         ("warnRobot", "RobotIsWarned", 3)]),

    "expert_nontired_collaborative": HumanType(
        "code/models/human_models/Evaluate/expert_nontired_collaborative.POMDPx", C8D1,
        {"graspAttempt": """
    TaskHuman        0.2  0.09 0.1  0.54 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.45 0.12 0.13 0.01 0.01 0.12 0.01 0.12 0.01 0.01
    NoAttention      0.01 0.09 0.2  0.38 0.17 0.02 0.01 0.01 0.09 0.01 0.01
    Evaluating       0.01 0.72 0.05 0.01 0.01 0.01 0.01 0.01 0.15 0.01 0.01
    Tired            0.01 0.01 0.1  0.4  0.01 0.01 0.42 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.1  0.15 0.08 0.01 0.01 0.01 0.01 0.46 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.1  0.29 0.3  0.01 0.01 0.01 0.01 0.01 0.01 0.24
""", "lookAround": """
    TaskHuman        0.1  0.01 0.01 0.01 0.38 0.3  0.15 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.1  0.23 0.38 0.09 0.01 0.1  0.05 0.01
    NoAttention      0.01 0.01 0.09 0.01 0.36 0.3  0.01 0.01 0.18 0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.33 0.41 0.1  0.01 0.09 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.21 0.15 0.56 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01 0.71 0.01 0.01
    WarningTheRobot  0.01 0.01 0.01 0.01 0.05 0.01 0.01 0.01 0.07 0.8  0.01
    RobotIsWarned    0.01 0.01 0.31 0.01 0.23 0.2  0.1  0.01 0.01 0.01 0.1
""", "idle": """
    TaskHuman        0.11 0.01 0.01 0.01 0.01 0.8  0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.05 0.05 0.64 0.1  0.01 0.1  0.01 0.01
    NoAttention      0.01 0.1  0.1  0.01 0.63 0.01 0.01 0.01 0.1  0.01 0.01
    Evaluating       0.01 0.09 0.01 0.01 0.01 0.64 0.05 0.01 0.1  0.06 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.18 0.33 0.22 0.2  0.01 0.01
    Recovery         0.01 0.01 0.01 0.01 0.01 0.01 0.2  0.71 0.01 0.01 0.01
    RobotInterfered  0.01 0.5  0.05 0.01 0.01 0.01 0.01 0.01 0.31 0.07 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.01 0.01 0.01 0.01 0.76 0.15 0.01 0.01 0.01 0.01
""", "walkAway": """
    TaskHuman        0.5  0.01 0.41 0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.41 0.5  0.01 0.01 0.01 0.01 0.01 0.01 0.01
    NoAttention      0.01 0.01 0.01 0.01 0.81 0.01 0.01 0.1  0.01 0.01 0.01
    Evaluating       0.01 0.01 0.32 0.01 0.01 0.5  0.01 0.1  0.01 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.01 0.8  0.11 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.2  0.71 0.01 0.01
    WarningTheRobot  0.01 0.01 0.3  0.01 0.01 0.01 0.01 0.22 0.01 0.4  0.01
    RobotIsWarned    0.01 0.01 0.45 0.01 0.01 0.01 0.01 0.15 0.01 0.01 0.32
""", "warnRobot": """
    RobotInterfered  0 0 0 0 0 0 0 0 0.5 0.2 0.3
    WarningTheRobot  0 0 0 0 0 0 0 0 0   0.3 0.7
    RobotIsWarned    0 0 0.6 0 0 0 0 0 0 0 0.4
"""},
        [("graspAttempt", "GlobalSuccess", 5), ("idle", "GlobalSuccess", 5),
         ("idle", "Evaluating", 2), ("lookAround", "NoAttention", 1),
         ("walkAway", "Recovery", 2), ("idle", "Recovery", 4),
         ("walkAway", "FailedToGrasp", -1), ("idle", "FailedToGrasp", -1),
         ("graspAttempt", "FailedToGrasp", -1), ("lookAround", "FailedToGrasp", -1),
         ("graspAttempt", "GlobalFail", -2), ("warnRobot", "*", -3),
         ("warnRobot", "RobotIsWarned", 1)]),

    "expert_nontired_noncollaborative": HumanType(
        "code/models/human_models/expert_nontired_noncollaborative.POMDPx", C8D1,
        {"graspAttempt": """
    TaskHuman        0.2  0.09 0.1  0.54 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.5  0.16 0.15 0.01 0.01 0.01 0.01 0.12 0.01 0.01
    NoAttention      0.01 0.09 0.2  0.38 0.17 0.02 0.01 0.01 0.09 0.01 0.01
    Evaluating       0.01 0.67 0.1  0.01 0.01 0.01 0.01 0.01 0.15 0.01 0.01
    Tired            0.01 0.01 0.1  0.4  0.01 0.01 0.42 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.1  0.15 0.08 0.01 0.01 0.01 0.01 0.46 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.1  0.29 0.3  0.01 0.01 0.01 0.01 0.01 0.01 0.24
""", "lookAround": """
    TaskHuman        0.1  0.01 0.01 0.01 0.38 0.3  0.15 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.1  0.23 0.38 0.09 0.01 0.1  0.05 0.01
    NoAttention      0.01 0.01 0.09 0.01 0.36 0.3  0.01 0.01 0.18 0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.33 0.41 0.1  0.01 0.09 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.21 0.15 0.56 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01 0.32 0.4  0.01
    WarningTheRobot  0.01 0.01 0.01 0.01 0.05 0.01 0.01 0.01 0.07 0.8  0.01
    RobotIsWarned    0.01 0.01 0.31 0.01 0.23 0.2  0.1  0.01 0.01 0.01 0.1
""", "idle": """
    TaskHuman        0.11 0.01 0.01 0.01 0.01 0.76 0.05 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.05 0.05 0.64 0.1  0.01 0.1  0.01 0.01
    NoAttention      0.01 0.1  0.1  0.01 0.63 0.01 0.01 0.01 0.1  0.01 0.01
    Evaluating       0.01 0.09 0.01 0.01 0.01 0.64 0.05 0.01 0.1  0.06 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.18 0.33 0.22 0.2  0.01 0.01
    Recovery         0.01 0.01 0.01 0.01 0.01 0.01 0.2  0.71 0.01 0.01 0.01
    RobotInterfered  0.01 0.1  0.05 0.01 0.01 0.01 0.01 0.01 0.21 0.57 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.01 0.01 0.01 0.01 0.76 0.15 0.01 0.01 0.01 0.01
""", "walkAway": """
    TaskHuman        0.5  0.01 0.41 0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.41 0.5  0.01 0.01 0.01 0.01 0.01 0.01 0.01
    NoAttention      0.01 0.01 0.01 0.01 0.81 0.01 0.01 0.1  0.01 0.01 0.01
    Evaluating       0.01 0.01 0.32 0.01 0.01 0.5  0.01 0.1  0.01 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.01 0.8  0.11 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.2  0.71 0.01 0.01
    WarningTheRobot  0.01 0.01 0.3  0.01 0.01 0.01 0.01 0.22 0.01 0.4  0.01
    RobotIsWarned    0.01 0.01 0.45 0.01 0.01 0.01 0.01 0.15 0.01 0.01 0.32
""", "warnRobot": """
    RobotInterfered  0 0 0 0 0 0 0 0 0.2 0.5  0.3
    WarningTheRobot  0 0 0 0 0 0 0 0 0   0.05 0.95
    RobotIsWarned    0 0 0.2 0 0 0 0 0 0 0 0.8
"""},
        [("graspAttempt", "GlobalSuccess", 5), ("idle", "GlobalSuccess", 5),
         ("idle", "Evaluating", 2), ("lookAround", "NoAttention", 1),
         ("walkAway", "Recovery", 2), ("idle", "Recovery", 4),
         ("walkAway", "FailedToGrasp", -1), ("idle", "FailedToGrasp", -1),
         ("graspAttempt", "FailedToGrasp", -1), ("lookAround", "FailedToGrasp", -1),
         ("graspAttempt", "GlobalFail", -2), ("warnRobot", "*", -3),
         ("warnRobot", "RobotIsWarned", 1)]),

    "expert_tired_collaborative": HumanType(
        "code/models/human_models/Evaluate/expert_tired_collaborative.POMDPx", C8D1,
        {"graspAttempt": """
    TaskHuman        0.2  0.09 0.1  0.54 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.45 0.12 0.13 0.01 0.01 0.12 0.01 0.12 0.01 0.01
    NoAttention      0.01 0.09 0.2  0.38 0.17 0.02 0.01 0.01 0.09 0.01 0.01
    Evaluating       0.01 0.63 0.1  0.15 0.01 0.01 0.01 0.01 0.05 0.01 0.01
    Tired            0.01 0.01 0.1  0.3  0.01 0.01 0.52 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.1  0.15 0.08 0.01 0.01 0.01 0.01 0.46 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.1  0.29 0.3  0.01 0.01 0.01 0.01 0.01 0.01 0.24
""", "lookAround": """
    TaskHuman        0.1  0.01 0.01 0.01 0.23 0.1  0.5  0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.1  0.08 0.08 0.54 0.01 0.1  0.05 0.01
    NoAttention      0.01 0.01 0.09 0.01 0.26 0.2  0.21 0.01 0.18 0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.13 0.11 0.6  0.01 0.09 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.11 0.05 0.76 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01 0.64 0.08 0.01
    WarningTheRobot  0.01 0.01 0.01 0.01 0.05 0.01 0.01 0.01 0.07 0.8  0.01
    RobotIsWarned    0.01 0.01 0.31 0.01 0.23 0.2  0.1  0.01 0.01 0.01 0.1
""", "idle": """
    TaskHuman        0.11 0.01 0.01 0.01 0.01 0.51 0.3  0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.05 0.05 0.14 0.6  0.01 0.1  0.01 0.01
    NoAttention      0.01 0.1  0.1  0.01 0.63 0.01 0.01 0.01 0.1  0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.01 0.32 0.5  0.01 0.1  0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.01 0.54 0.18 0.2  0.01 0.01
    Recovery         0.01 0.01 0.01 0.01 0.01 0.01 0.05 0.86 0.01 0.01 0.01
    RobotInterfered  0.01 0.3  0.05 0.01 0.01 0.01 0.01 0.01 0.51 0.07 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.01 0.01 0.01 0.01 0.76 0.15 0.01 0.01 0.01 0.01
""", "walkAway": """
    TaskHuman        0.5  0.01 0.41 0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.41 0.5  0.01 0.01 0.01 0.01 0.01 0.01 0.01
    NoAttention      0.01 0.01 0.01 0.01 0.81 0.01 0.01 0.1  0.01 0.01 0.01
    Evaluating       0.01 0.01 0.32 0.01 0.01 0.5  0.01 0.1  0.01 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.9  0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.26 0.65 0.01 0.01
    WarningTheRobot  0.01 0.01 0.3  0.01 0.01 0.01 0.01 0.22 0.01 0.4  0.01
    RobotIsWarned    0.01 0.01 0.45 0.01 0.01 0.01 0.01 0.15 0.01 0.01 0.32
""", "warnRobot": """
    RobotInterfered  0 0 0 0 0 0 0 0 0.5 0.2 0.3
    WarningTheRobot  0 0 0 0 0 0 0 0 0   0.3 0.7
    RobotIsWarned    0 0 0.6 0 0 0 0 0 0 0 0.4
"""},
        [("graspAttempt", "GlobalSuccess", 5), ("idle", "GlobalSuccess", 5),
         ("idle", "Evaluating", 2), ("lookAround", "NoAttention", 1),
         ("walkAway", "Recovery", 4), ("idle", "Recovery", 4),
         ("walkAway", "FailedToGrasp", -1), ("idle", "FailedToGrasp", -1),
         ("graspAttempt", "FailedToGrasp", -1), ("lookAround", "FailedToGrasp", -1),
         ("graspAttempt", "GlobalFail", -2), ("warnRobot", "*", -3),
         ("warnRobot", "RobotIsWarned", 1)]),

    "expert_tired_noncollaborative": HumanType(
        "code/models/human_models/Evaluate/expert_tired_noncollaborative.POMDPx", C8D1,
        {"graspAttempt": """
    TaskHuman        0.2  0.09 0.1  0.54 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.45 0.12 0.13 0.01 0.01 0.12 0.01 0.12 0.01 0.01
    NoAttention      0.01 0.09 0.2  0.38 0.17 0.02 0.01 0.01 0.09 0.01 0.01
    Evaluating       0.01 0.63 0.1  0.15 0.01 0.01 0.01 0.01 0.05 0.01 0.01
    Tired            0.01 0.01 0.1  0.3  0.01 0.01 0.52 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.1  0.15 0.08 0.01 0.01 0.01 0.01 0.46 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.1  0.29 0.3  0.01 0.01 0.01 0.01 0.01 0.01 0.24
""", "lookAround": """
    TaskHuman        0.1  0.01 0.01 0.01 0.23 0.1  0.5  0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.1  0.08 0.08 0.54 0.01 0.1  0.05 0.01
    NoAttention      0.01 0.01 0.09 0.01 0.26 0.2  0.21 0.01 0.18 0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.13 0.11 0.6  0.01 0.09 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.11 0.05 0.76 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.3  0.01 0.01 0.01 0.22 0.4  0.01
    WarningTheRobot  0.01 0.01 0.01 0.01 0.05 0.01 0.01 0.01 0.07 0.8  0.01
    RobotIsWarned    0.01 0.01 0.31 0.01 0.23 0.2  0.1  0.01 0.01 0.01 0.1
""", "idle": """
    TaskHuman        0.11 0.01 0.01 0.01 0.01 0.51 0.3  0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.05 0.05 0.14 0.6  0.01 0.1  0.01 0.01
    NoAttention      0.01 0.1  0.1  0.01 0.63 0.01 0.01 0.01 0.1  0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.01 0.32 0.5  0.01 0.1  0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.01 0.54 0.18 0.2  0.01 0.01
    Recovery         0.01 0.01 0.01 0.01 0.01 0.01 0.05 0.86 0.01 0.01 0.01
    RobotInterfered  0.01 0.1  0.05 0.01 0.01 0.01 0.01 0.01 0.21 0.57 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.01 0.01 0.01 0.01 0.76 0.15 0.01 0.01 0.01 0.01
""", "walkAway": """
    TaskHuman        0.5  0.01 0.41 0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.41 0.5  0.01 0.01 0.01 0.01 0.01 0.01 0.01
    NoAttention      0.01 0.01 0.01 0.01 0.81 0.01 0.01 0.1  0.01 0.01 0.01
    Evaluating       0.01 0.01 0.32 0.01 0.01 0.5  0.01 0.1  0.01 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.9  0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.26 0.65 0.01 0.01
    WarningTheRobot  0.01 0.01 0.3  0.01 0.01 0.01 0.01 0.22 0.01 0.4  0.01
    RobotIsWarned    0.01 0.01 0.45 0.01 0.01 0.01 0.01 0.15 0.01 0.01 0.32
""", "warnRobot": """
    RobotInterfered  0 0 0 0 0 0 0 0 0.2 0.5  0.3
    WarningTheRobot  0 0 0 0 0 0 0 0 0   0.05 0.95
    RobotIsWarned    0 0 0.2 0 0 0 0 0 0 0 0.8
"""},
        [("graspAttempt", "GlobalSuccess", 5), ("idle", "GlobalSuccess", 5),
         ("idle", "Evaluating", 2), ("lookAround", "NoAttention", 1),
         ("walkAway", "Recovery", 4), ("idle", "Recovery", 4),
         ("walkAway", "FailedToGrasp", -1), ("idle", "FailedToGrasp", -1),
         ("graspAttempt", "FailedToGrasp", -1), ("lookAround", "FailedToGrasp", -1),
         ("graspAttempt", "GlobalFail", -2), ("warnRobot", "*", -3),
         ("warnRobot", "RobotIsWarned", 3)]),

    "distracted_collaborative": HumanType(
        "code/models/human_models/distracted_collaborative.POMDPx", C8D1,
        {"graspAttempt": """
    TaskHuman        0.2  0.09 0.1  0.54 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.25 0.12 0.33 0.01 0.01 0.12 0.01 0.12 0.01 0.01
    NoAttention      0.01 0.09 0.2  0.38 0.17 0.02 0.01 0.01 0.09 0.01 0.01
    Evaluating       0.01 0.38 0.1  0.3  0.01 0.01 0.01 0.01 0.15 0.01 0.01
    Tired            0.01 0.01 0.1  0.3  0.01 0.01 0.52 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.1  0.15 0.08 0.01 0.01 0.01 0.01 0.46 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.1  0.29 0.3  0.01 0.01 0.01 0.01 0.01 0.01 0.24
""", "lookAround": """
    TaskHuman        0.1  0.01 0.01 0.01 0.68 0.1  0.05 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.1  0.38 0.23 0.09 0.01 0.1  0.05 0.01
    NoAttention      0.01 0.01 0.09 0.01 0.46 0.2  0.01 0.01 0.18 0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.7  0.09 0.05 0.01 0.09 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.51 0.05 0.36 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01 0.71 0.01 0.01
    WarningTheRobot  0.01 0.01 0.01 0.01 0.05 0.01 0.01 0.01 0.07 0.8  0.01
    RobotIsWarned    0.01 0.01 0.31 0.01 0.23 0.2  0.1  0.01 0.01 0.01 0.1
""", "idle": """
    TaskHuman        0.11 0.01 0.01 0.01 0.01 0.8  0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.05 0.45 0.24 0.1  0.01 0.1  0.01 0.01
    NoAttention      0.01 0.1  0.1  0.01 0.63 0.01 0.01 0.01 0.1  0.01 0.01
    Evaluating       0.01 0.09 0.01 0.01 0.41 0.19 0.1  0.01 0.1  0.06 0.01
    Tired            0.01 0.01 0.1  0.01 0.01 0.01 0.54 0.01 0.2  0.09 0.01
    Recovery         stay
    RobotInterfered  0.01 0.5  0.05 0.01 0.01 0.01 0.01 0.01 0.31 0.07 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.01 0.01 0.01 0.01 0.76 0.15 0.01 0.01 0.01 0.01
""", "walkAway": """
    TaskHuman        0.5  0.01 0.41 0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.41 0.5  0.01 0.01 0.01 0.01 0.01 0.01 0.01
    NoAttention      0.01 0.01 0.01 0.01 0.81 0.01 0.01 0.1  0.01 0.01 0.01
    Evaluating       0.01 0.01 0.32 0.01 0.01 0.5  0.01 0.1  0.01 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.9  0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.26 0.65 0.01 0.01
    WarningTheRobot  0.01 0.01 0.3  0.01 0.01 0.01 0.01 0.22 0.01 0.4  0.01
    RobotIsWarned    0.01 0.01 0.45 0.01 0.01 0.01 0.01 0.15 0.01 0.01 0.32
""", "warnRobot": """
    RobotInterfered  0 0 0 0 0 0 0 0 0.5 0.2 0.3
    WarningTheRobot  0 0 0 0 0 0 0 0 0   0.3 0.7
    RobotIsWarned    0 0 0.6 0 0 0 0 0 0 0 0.4
"""},
        [("graspAttempt", "GlobalSuccess", 3), ("idle", "GlobalSuccess", 1),
         ("idle", "Evaluating", 0), ("lookAround", "NoAttention", 5),
         ("walkAway", "Recovery", 2), ("idle", "Recovery", 1),
         ("walkAway", "FailedToGrasp", -1), ("idle", "FailedToGrasp", -1),
         ("idle", "NoAttention", 1), ("graspAttempt", "FailedToGrasp", -1),
         ("lookAround", "FailedToGrasp", -1), ("graspAttempt", "GlobalFail", -2),
         ("warnRobot", "*", -3), ("warnRobot", "RobotIsWarned", 1),
         ("walkAway", "RobotInterfered", -1), ("lookAround", "RobotInterfered", -1)]),

    "distracted_noncollaborative": HumanType(
        "code/models/human_models/distracted_noncollaborative.POMDPx", C8D1,
        {"graspAttempt": """
    TaskHuman        0.2  0.09 0.1  0.54 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.25 0.12 0.33 0.01 0.01 0.12 0.01 0.12 0.01 0.01
    NoAttention      0.01 0.09 0.2  0.38 0.17 0.02 0.01 0.01 0.09 0.01 0.01
    Evaluating       0.01 0.48 0.1  0.2  0.01 0.01 0.01 0.01 0.15 0.01 0.01
    Tired            0.01 0.01 0.1  0.4  0.01 0.01 0.42 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.1  0.15 0.08 0.01 0.01 0.01 0.01 0.46 0.15 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.1  0.29 0.3  0.01 0.01 0.01 0.01 0.01 0.01 0.24
""", "lookAround": """
    TaskHuman        0.1  0.01 0.01 0.01 0.68 0.1  0.05 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.1  0.38 0.23 0.09 0.01 0.1  0.05 0.01
    NoAttention      0.01 0.01 0.09 0.01 0.46 0.2  0.01 0.01 0.18 0.01 0.01
    Evaluating       0.01 0.01 0.01 0.01 0.7  0.09 0.05 0.01 0.09 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.51 0.05 0.36 0.01 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.1  0.01 0.01 0.01 0.2  0.62 0.01
    WarningTheRobot  0.01 0.01 0.01 0.01 0.05 0.01 0.01 0.01 0.07 0.8  0.01
    RobotIsWarned    0.01 0.01 0.31 0.01 0.23 0.2  0.1  0.01 0.01 0.01 0.1
""", "idle": """
    TaskHuman        0.11 0.01 0.01 0.01 0.01 0.8  0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.01 0.05 0.45 0.24 0.1  0.01 0.1  0.01 0.01
    NoAttention      0.01 0.1  0.1  0.01 0.63 0.01 0.01 0.01 0.1  0.01 0.01
    Evaluating       0.01 0.09 0.01 0.01 0.41 0.19 0.1  0.01 0.1  0.06 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.18 0.33 0.22 0.2  0.01 0.01
    Recovery         0.01 0.01 0.01 0.01 0.01 0.01 0.2  0.71 0.01 0.01 0.01
    RobotInterfered  0.01 0.05 0.05 0.01 0.01 0.01 0.01 0.01 0.1  0.73 0.01
    WarningTheRobot  stay
    RobotIsWarned    0.01 0.01 0.01 0.01 0.01 0.76 0.15 0.01 0.01 0.01 0.01
""", "walkAway": """
    TaskHuman        0.5  0.01 0.41 0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.01
    FailedToGrasp    0.01 0.01 0.41 0.5  0.01 0.01 0.01 0.01 0.01 0.01 0.01
    NoAttention      0.01 0.01 0.01 0.01 0.81 0.01 0.01 0.1  0.01 0.01 0.01
    Evaluating       0.01 0.01 0.32 0.01 0.01 0.5  0.01 0.1  0.01 0.01 0.01
    Tired            0.01 0.01 0.01 0.01 0.01 0.01 0.8  0.11 0.01 0.01 0.01
    Recovery         stay
    RobotInterfered  0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.2  0.71 0.01 0.01
    WarningTheRobot  0.01 0.01 0.3  0.01 0.01 0.01 0.01 0.22 0.01 0.4  0.01
    RobotIsWarned    0.01 0.01 0.45 0.01 0.01 0.01 0.01 0.15 0.01 0.01 0.32
""", "warnRobot": """
    RobotInterfered  0 0 0 0 0 0 0 0 0.3 0.6  0.1
    WarningTheRobot  0 0 0 0 0 0 0 0 0   0.05 0.95
    RobotIsWarned    0 0 0.2 0 0 0 0 0 0 0 0.8
"""},
        [("graspAttempt", "GlobalSuccess", 2), ("idle", "GlobalSuccess", 2),
         ("idle", "Evaluating", 3.5), ("lookAround", "NoAttention", 7.5),
         ("walkAway", "Recovery", 1), ("idle", "Tired", 2),
         ("graspAttempt", "FailedToGrasp", -1), ("graspAttempt", "GlobalFail", -2),
         ("warnRobot", "*", -3), ("*", "WarningTheRobot", -3),
         ("warnRobot", "RobotIsWarned", 3)]),
}

# --------------------------------------------------------------------------------------------
# The robot POMDP (11 states, 5 actions, 12 observations)
# --------------------------------------------------------------------------------------------
ROBOT_STATES = list(FABRIC.robot_states)
ROBOT_ACTIONS = list(FABRIC.robot_actions)
#: The authors' files number the 12 observations (``<NumValues>12``); ObservationAgent maps the
#: observed bits to them. We name each after the smallest bit sum that maps to it (bits: 1 the
#: human looks at the object, 2 the human is detected, 4 a grasp attempt, 8 the product arrived
#: inspected, 16 a warning, 32 the human idles, 64 the product arrived uninspected); the whole
#: table is in docs/tasks_fabric_facts.md.
ROBOT_OBSERVATIONS = list(FABRIC.observations.names)

ROBOT_T: Dict[str, str] = {"idle": """
    TaskHuman          0.3  0.15 0.22 0.15 0.01 0.01 0.01 0.01 0.12 0.01 0.01
    MayNotBeCapable    stay
    MayBeTired         stay
    NoFocus            stay
    NeedsToBeReminded  stay
    NeedsHelp          stay
    NoNeedHelp         0.01 0.1  0.1  0.1  0.01 0.01 0.1  0.01 0.35 0.2  0.01
    WarningReceived    stay
    GlobalSuccess      stay
    GlobalFail         stay
    TaskRobot          stay
""", "grasp": """
    TaskHuman          0.51 0.01 0.01 0.01 0.01 0.01 0.01 0.4  0.01 0.01 0.01
    MayNotBeCapable    0.01 0.71 0.01 0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01
    MayBeTired         0.01 0.01 0.71 0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01
    NoFocus            0.01 0.01 0.01 0.71 0.01 0.01 0.01 0.2  0.01 0.01 0.01
    NeedsToBeReminded  0.01 0.01 0.01 0.01 0.71 0.01 0.01 0.2  0.01 0.01 0.01
    NeedsHelp          0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.1  0.81 0.01 0.01
    NoNeedHelp         0.01 0.01 0.01 0.01 0.01 0.01 0.41 0.5  0.01 0.01 0.01
    WarningReceived    stay
    GlobalSuccess      0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.11 0.7  0.01 0.11
    GlobalFail         stay
    TaskRobot          0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.15 0.6  0.17 0.01
""", "cancel": """
    TaskHuman          stay
    MayNotBeCapable    stay
    MayBeTired         stay
    NoFocus            stay
    NeedsToBeReminded  stay
    NeedsHelp          stay
    NoNeedHelp         stay
    WarningReceived    0.01 0.11 0.01 0.01 0.01 0.01 0.3  0.01 0.42 0.1  0.01
    GlobalSuccess      stay
    GlobalFail         stay
    TaskRobot          stay
""", "point": """
    TaskHuman          0.71 0.01 0.01 0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01
    MayNotBeCapable    0.01 0.71 0.01 0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01
    MayBeTired         0.01 0.01 0.71 0.01 0.01 0.01 0.01 0.2  0.01 0.01 0.01
    NoFocus            0.01 0.01 0.01 0.71 0.01 0.01 0.01 0.2  0.01 0.01 0.01
    NeedsToBeReminded  0.01 0.01 0.01 0.1  0.01 0.01 0.01 0.13 0.5  0.2  0.01
    NeedsHelp          stay
    NoNeedHelp         0.01 0.01 0.01 0.01 0.01 0.01 0.71 0.2  0.01 0.01 0.01
    WarningReceived    stay
    GlobalSuccess      0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.21 0.7  0.01 0.01
    GlobalFail         stay
    TaskRobot          stay
""", "graspPlanning": """
    TaskHuman          stay
    MayNotBeCapable    0.01 0.23 0.1  0.1  0.01 0.25 0.13 0.01 0.14 0.01 0.01
    MayBeTired         0.01 0.1  0.23 0.1  0.01 0.25 0.13 0.01 0.14 0.01 0.01
    NoFocus            0.01 0.1  0.1  0.23 0.25 0.01 0.1  0.01 0.17 0.01 0.01
    NeedsToBeReminded  0.01 0.01 0.01 0.1  0.81 0.01 0.01 0.01 0.01 0.01 0.01
    NeedsHelp          stay
    NoNeedHelp         0.01 0.05 0.05 0.05 0.01 0.02 0.6  0.01 0.12 0.07 0.01
    WarningReceived    stay
    GlobalSuccess      0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.11 0.7  0.01 0.11
    GlobalFail         stay
    TaskRobot          stay
"""}

#: O(o | s', a): one table, the same for every action in the authors' files.
ROBOT_O = """
    TaskHuman          0.01 0.1   0.3  0.01 0.15 0.01 0.01 0.06  0.1  0.23 0.01 0.01
    MayNotBeCapable    0.01 0.01  0.1  0.2  0.32 0.01 0.01 0.01  0.08 0.23 0.01 0.01
    MayBeTired         0.05 0.039 0.2  0.12 0.1  0.01 0.01 0.001 0.15 0.3  0.01 0.01
    NoFocus            0.01 0.41  0.01 0.1  0.01 0.01 0.01 0.01  0.4  0.01 0.01 0.01
    NeedsToBeReminded  0.01 0.41  0.01 0.1  0.01 0.01 0.01 0.01  0.4  0.01 0.01 0.01
    NeedsHelp          0.2  0.05  0.01 0.05 0.07 0.01 0.01 0.1   0.2  0.28 0.01 0.01
    NoNeedHelp         0.01 0.05  0.1  0.27 0.38 0.01 0.01 0.01  0.01 0.13 0.01 0.01
    WarningReceived    0.01 0.01  0.01 0.01 0.01 0.01 0.89 0.01  0.01 0.01 0.01 0.01
    GlobalSuccess      0.01 0.01  0.01 0.01 0.01 0.45 0.01 0.01  0.01 0.01 0.45 0.01
    GlobalFail         0.01 0.01  0.01 0.01 0.01 0.01 0.01 0.01  0.01 0.01 0.01 0.89
    TaskRobot          0.01 0.01  0.01 0.01 0.01 0.01 0.01 0.3   0.21 0.4  0.01 0.01
"""

ROBOT_REWARDS: List[Tuple[str, str, float]] = [
    ("grasp", "TaskHuman", -1), ("point", "TaskHuman", -1), ("cancel", "TaskHuman", -1),
    ("grasp", "GlobalSuccess", 6), ("idle", "GlobalSuccess", 6), ("point", "GlobalSuccess", 6),
    ("cancel", "GlobalSuccess", 3), ("graspPlanning", "GlobalSuccess", 6),
    ("idle", "GlobalFail", -3), ("point", "GlobalFail", -3), ("grasp", "GlobalFail", -3),
    ("cancel", "GlobalFail", -3), ("graspPlanning", "GlobalFail", -3),
    ("grasp", "WarningReceived", -3), ("idle", "WarningReceived", -3)]

#: Policies 1, 3, 6 and 9 of the authors' library: the base model with these rows and rewards
#: replaced (the rest is the base's, figure for figure).
_GENTLER_FAIL = [("point", "GlobalFail", -1), ("graspPlanning", "GlobalFail", -1)]
_POLICY3_T = {"idle": """
    MayNotBeCapable    0.3  0.32 0.01 0.01 0.01 0.01 0.3  0.01 0.01 0.01 0.01
    NoFocus            0.32 0.01 0.01 0.3  0.01 0.01 0.3  0.01 0.01 0.01 0.01
    WarningReceived    0.01 0.01 0.01 0.01 0.01 0.01 0.9  0.01 0.01 0.01 0.01
""", "grasp": """
    NeedsHelp          0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.05 0.82 0.05 0.01
""", "cancel": """
    WarningReceived    0.01 0.01 0.01 0.01 0.01 0.01 0.9  0.01 0.01 0.01 0.01
""", "graspPlanning": """
    WarningReceived    0.01 0.01 0.01 0.01 0.01 0.01 0.9  0.01 0.01 0.01 0.01
"""}


@dataclass(frozen=True)
class RobotPolicy:
    """A variant of the base robot model: its source file and what differs from the base."""
    source: str
    commit: str
    rows: Dict[str, str] = field(default_factory=dict)
    rewards: Sequence[Tuple[str, str, float]] = ()


ROBOT_BASE_SOURCE = ("code/models/robot_models/base.pomdpx", C8D1)
ROBOT_POLICIES: Dict[str, RobotPolicy] = {
    "policy1": RobotPolicy("code/models/robot_models/Evaluate/policy1.pomdpx", C8D1, {"grasp": """
    MayNotBeCapable    0.01 0.25 0.01 0.01 0.21 0.23 0.01 0.24 0.01 0.01 0.01
    MayBeTired         0.01 0.01 0.25 0.01 0.23 0.21 0.01 0.24 0.01 0.01 0.01
    NoFocus            0.01 0.01 0.01 0.25 0.21 0.25 0.01 0.22 0.01 0.01 0.01
    NeedsHelp          0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.31 0.31 0.3  0.01
"""}, _GENTLER_FAIL),
    "policy3": RobotPolicy("code/models/robot_models/Evaluate/policy3.pomdpx", C8D1,
                           _POLICY3_T, _GENTLER_FAIL),
    "policy6": RobotPolicy("code/models/robot_models/Evaluate/policy6.pomdpx", C8D1,
                           {**_POLICY3_T, "grasp": """
    NeedsHelp          0.01 0.01 0.01 0.01 0.01 0.01 0.01 0.2  0.64 0.08 0.01
"""}, _GENTLER_FAIL),
    "policy9": RobotPolicy("code/models/robot_models/Evaluate/policy9.pomdpx", C8D1, _POLICY3_T),
}

# --------------------------------------------------------------------------------------------
# The reactive robot MDP (6 states, 3 actions)
# --------------------------------------------------------------------------------------------
REACTIVE_SOURCE = ("code/models/robot_models/reactive_robot_pomdp.pomdpx", FIRST)
REACTIVE_STATES = ["TaskHuman", "GlobalSuccess", "HumanNeedsHelp", "WarningReceived",
                   "TaskRobot", "GlobalFail"]
REACTIVE_ACTIONS = ["idle", "grasp", "cancel"]
REACTIVE_T: Dict[str, str] = {"idle": """
    TaskHuman        0.39 0.29 0.1  0.01 0.01 0.2
    GlobalSuccess    0.01 0.95 0.01 0.01 0.01 0.01
    HumanNeedsHelp   0.01 0.01 0.95 0.01 0.01 0.01
    WarningReceived  0.01 0.01 0.01 0.95 0.01 0.01
    TaskRobot        0.01 0.01 0.01 0.01 0.95 0.01
    GlobalFail       0.47 0.01 0.01 0.01 0.4  0.1
""", "grasp": """
    TaskHuman        0.95 0.01 0.01 0.01 0.01 0.01
    GlobalSuccess    0.1  0.65 0.01 0.01 0.15 0.08
    HumanNeedsHelp   0.01 0.75 0.08 0.05 0.01 0.1
    WarningReceived  0.01 0.01 0.01 0.95 0.01 0.01
    TaskRobot        0    0.5  0.01 0.29 0.01 0.19
    GlobalFail       0.01 0.01 0.01 0.01 0.01 0.95
""", "cancel": """
    TaskHuman        0.95 0.01 0.01 0.01 0.01 0.01
    GlobalSuccess    0.01 0.95 0.01 0.01 0.01 0.01
    HumanNeedsHelp   0.01 0.01 0.95 0.01 0.01 0.01
    WarningReceived  0.01 0.24 0.01 0.58 0.01 0.15
    TaskRobot        0.01 0.01 0.01 0.01 0.95 0.01
    GlobalFail       0.01 0.01 0.01 0.01 0.01 0.95
"""}
REACTIVE_REWARDS: List[Tuple[str, str, float]] = [
    ("idle", "GlobalSuccess", 6), ("grasp", "GlobalSuccess", 6), ("cancel", "GlobalSuccess", 3),
    ("idle", "HumanNeedsHelp", 0), ("idle", "GlobalFail", -3), ("grasp", "GlobalFail", -3),
    ("cancel", "GlobalFail", -3), ("grasp", "WarningReceived", -3), ("grasp", "TaskHuman", -3),
    ("cancel", "TaskHuman", -3), ("idle", "WarningReceived", -3)]


# --------------------------------------------------------------------------------------------
# Building the models
# --------------------------------------------------------------------------------------------
@dataclass
class Notes:
    """What the builder changed in the authors' figures (printed, and checked by the tests)."""
    normalised: List[str] = field(default_factory=list)


def parse_rows(text: str, states: Sequence[str], width: int, spans: Sequence[int],
               label: str) -> Dict[str, np.ndarray]:
    """The lines of a table as {state: row of ``width`` numbers}. A line names its state, then
    gives either ``stay`` or the numbers of the columns ``spans`` (the rest are 0), or all
    ``width`` numbers. Lines must follow the model's state order."""
    rows: Dict[str, np.ndarray] = {}
    last = -1
    for line in text.strip().splitlines():
        name, *words = line.split()
        if name not in states:
            raise ValueError(f"{label}: unknown state {name!r}")
        if states.index(name) <= last:
            raise ValueError(f"{label}: {name} is out of order or repeated")
        last = states.index(name)
        row = np.zeros(width)
        if words == ["stay"]:
            row[list(spans)] = FLOOR
            row[states.index(name)] = STAY
        elif len(words) == len(spans):
            row[list(spans)] = [float(w) for w in words]
        elif len(words) == width:
            row[:] = [float(w) for w in words]
        else:
            raise ValueError(f"{label}: {name} has {len(words)} numbers, expected "
                             f"{len(spans)} or {width}")
        rows[name] = row
    return rows


def transition_tables(states: Sequence[str], actions: Sequence[str],
                      tables: Dict[str, Dict[str, np.ndarray]], notes: Notes,
                      label: str) -> List[sp.csr_matrix]:
    """T[a] from the given rows; a state without a row keeps its state. A row that does not
    sum to one (beyond float rounding) is normalised and noted."""
    out = []
    for action in actions:
        T = np.eye(len(states))
        for name, row in tables.get(action, {}).items():
            T[states.index(name)] = _normalised(row, f"{label} T {action} {name}", notes)
        out.append(sp.csr_matrix(T))
    return out


def _normalised(row: np.ndarray, label: str, notes: Notes) -> np.ndarray:
    total = float(row.sum())
    if abs(total - 1.0) <= 1e-9:
        return row
    notes.normalised.append(f"{label}: sums to {total:g}, divided by it")
    return row / total


def reward_tables(states: Sequence[str], actions: Sequence[str],
                  entries: Sequence[Tuple[str, str, float]]) -> List[sp.csr_matrix]:
    """R[a][s, s'] from (action, next state, value) entries, ``*`` for every one, later entries
    overriding earlier ones; the value is the same whatever the state left."""
    R = np.zeros((len(actions), len(states), len(states)))
    for action, state, value in entries:
        a_sel = slice(None) if action == "*" else actions.index(action)
        s_sel = slice(None) if state == "*" else states.index(state)
        R[a_sel, :, s_sel] = value
    return [sp.csr_matrix(R[a]) for a in range(len(actions))]


def _start(states: Sequence[str], start: str) -> np.ndarray:
    b = np.zeros(len(states))
    b[states.index(start)] = 1.0
    return b


def human_model(name: str, notes: Notes) -> Model:
    """The human type ``name`` as a 12-state MDP."""
    kind = HUMAN_TYPES[name]
    spans = [i for i, s in enumerate(HUMAN_STATES) if s != "TaskRobot"]
    tables = {a: parse_rows(text, HUMAN_STATES, len(HUMAN_STATES), spans, f"{name} {a}")
              for a, text in kind.tables.items()}
    tables["idle"].update(parse_rows(HUMAN_TASKROBOT_IDLE, HUMAN_STATES, len(HUMAN_STATES),
                                     spans, f"{name} idle"))
    S = len(HUMAN_STATES)
    model = Model(states=list(HUMAN_STATES), actions=list(HUMAN_ACTIONS),
                  observations=list(HUMAN_STATES), discount=DISCOUNT,
                  initial_belief=_start(HUMAN_STATES, "TaskHuman"),
                  T=transition_tables(HUMAN_STATES, HUMAN_ACTIONS, tables, notes, name),
                  O=[sp.identity(S, format="csr") for _ in HUMAN_ACTIONS],
                  R=reward_tables(HUMAN_STATES, HUMAN_ACTIONS, kind.rewards),
                  fully_observable=True, name=f"fabric_human_{name}")
    model.validate()
    return model


def robot_model(name: str, notes: Notes) -> Model:
    """The base robot POMDP (``name`` = "base") or one of :data:`ROBOT_POLICIES`."""
    spans = range(len(ROBOT_STATES))
    tables = {a: parse_rows(text, ROBOT_STATES, len(ROBOT_STATES), spans, f"base {a}")
              for a, text in ROBOT_T.items()}
    rewards = list(ROBOT_REWARDS)
    if name != "base":
        policy = ROBOT_POLICIES[name]
        for action, text in policy.rows.items():
            tables[action].update(parse_rows(text, ROBOT_STATES, len(ROBOT_STATES), spans,
                                             f"{name} {action}"))
        rewards += list(policy.rewards)
    o_rows = parse_rows(ROBOT_O, ROBOT_STATES, len(ROBOT_OBSERVATIONS),
                        range(len(ROBOT_OBSERVATIONS)), "O")
    O = np.vstack([_normalised(o_rows[s], f"{name} O {s}", notes) for s in ROBOT_STATES])
    model = Model(states=list(ROBOT_STATES), actions=list(ROBOT_ACTIONS),
                  observations=list(ROBOT_OBSERVATIONS), discount=DISCOUNT,
                  initial_belief=_start(ROBOT_STATES, "TaskHuman"),
                  T=transition_tables(ROBOT_STATES, ROBOT_ACTIONS, tables, notes, name),
                  O=[sp.csr_matrix(O) for _ in ROBOT_ACTIONS],
                  R=reward_tables(ROBOT_STATES, ROBOT_ACTIONS, rewards),
                  name=f"fabric_robot_{name}")
    model.validate()
    return model


def reactive_model(notes: Notes) -> Model:
    """The reactive robot as a 6-state MDP."""
    spans = range(len(REACTIVE_STATES))
    tables = {a: parse_rows(text, REACTIVE_STATES, len(REACTIVE_STATES), spans, f"reactive {a}")
              for a, text in REACTIVE_T.items()}
    S = len(REACTIVE_STATES)
    model = Model(states=list(REACTIVE_STATES), actions=list(REACTIVE_ACTIONS),
                  observations=list(REACTIVE_STATES), discount=DISCOUNT,
                  initial_belief=_start(REACTIVE_STATES, "TaskHuman"),
                  T=transition_tables(REACTIVE_STATES, REACTIVE_ACTIONS, tables, notes,
                                      "reactive"),
                  O=[sp.identity(S, format="csr") for _ in REACTIVE_ACTIONS],
                  R=reward_tables(REACTIVE_STATES, REACTIVE_ACTIONS, REACTIVE_REWARDS),
                  fully_observable=True, name="fabric_robot_reactive")
    model.validate()
    return model


def _header(source: str, commit: str) -> str:
    return (f"<!-- FABRIC, the seed authors' successor task. Figures of {SOURCE_REPOSITORY} "
            f"{source} (commit {commit[:7]}; GPL-3.0); file written by "
            f"tools/make_fabric_models.py, see models/README.md. -->")


def model_texts() -> Tuple[Dict[str, str], Notes]:
    """Every file's relative path and text, and the notes on what was changed."""
    notes = Notes()
    texts: Dict[str, str] = {}

    def add(path: str, model: Model, source: Tuple[str, str]) -> None:
        head, rest = pomdpx.dump(model).split("\n", 1)
        texts[path] = f"{head}\n{_header(*source)}\n{rest}"

    for name, kind in HUMAN_TYPES.items():
        add(f"human/{name}.pomdpx", human_model(name, notes), (kind.source, kind.commit))
    add("robot/base.pomdpx", robot_model("base", notes), ROBOT_BASE_SOURCE)
    for name, policy in ROBOT_POLICIES.items():
        add(f"robot/{name}.pomdpx", robot_model(name, notes), (policy.source, policy.commit))
    add("robot/reactive.pomdpx", reactive_model(notes), REACTIVE_SOURCE)
    return texts, notes


def write_models(out: Path) -> Notes:
    """Write every file under ``out`` (human/ and robot/); each file whole or not at all."""
    texts, notes = model_texts()
    for relative, text in texts.items():
        path = out / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomically(path, text)
    return notes


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(REPO / "models" / "fabric"),
                        help="the folder to write human/ and robot/ into (default: %(default)s)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    try:
        notes = write_models(out)
    except OSError as exc:
        print(f"make_fabric_models: cannot write under {out}: {exc.strerror or exc}",
              file=sys.stderr)
        return 1
    for line in notes.normalised:
        print(f"normalised: {line}")
    print(f"wrote {len(HUMAN_TYPES)} human and {len(ROBOT_POLICIES) + 2} robot models "
          f"under {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
