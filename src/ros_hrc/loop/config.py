"""How the episode coordinator's parts are set up (:class:`CoordinatorConfig`) and the
default waits of the loop; every part of :mod:`ros_hrc.loop.coordinator` reads its own
fields of the one configuration."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

from ros_hrc import settings
from ros_hrc.streams import EpisodeSchedule
from ros_hrc.tasks.definition import Task
from ros_hrc.tasks.schedule import Schedule
from ros_hrc.tasks.seed import SEED


#: Episode policies after an episode ends (the ``on_episode_end`` setting).
EPISODE_END_POLICIES = settings.SETTINGS["on_episode_end"].choices

#: Seconds before the first retry of a failed reset; each retry doubles it up to
#: :data:`MAX_RETRY_DELAY`.
RETRY_DELAY = 1.0
MAX_RETRY_DELAY = 10.0
#: Seconds after a reset finished during which a reset asked for from outside is that reset.
RESET_JOIN_WINDOW = 1.0
#: Seconds between the lines that say what a step waits for.
WAIT_NOTE_EVERY = 5.0
#: Seconds a step waits for one call to the world before it fails.
WORLD_CALL_TIMEOUT = 30.0
#: A call to the robot executor is normal for this many of the task's robot actions
#: (``Task.robot_action_seconds``, simulated, at the default real-time factor 1): it may wait
#: behind the robot's previous action still under way (FABRIC's grasp is answered as it
#: starts, then plans and carries on) and then take its own. Its first wait line comes after
#: that, or after ``wait_note_every`` when that is longer (docs/loop.md).
ROBOT_WAIT_ACTIONS = 2


@dataclass(frozen=True)
class CoordinatorConfig:
    """How episodes end and how the loop recovers.

    ``max_steps``: end an episode after this many steps (0: no limit). ``end_on_goal``: also
    end it when the human MDP reaches ``goal_state`` (the seed's end), besides the world's
    ends (someone holds the object, or it left the belt). ``on_episode_end``: ``wait`` for a
    reset, ``reset`` at once, or ``continue`` stepping. ``retry_delay``: seconds between
    attempts to recover by a reset (doubling up to ``max_retry_delay``). ``first_epoch``: the
    first epoch minted (adapters give a random one, so a restarted coordinator never reuses
    an epoch of its predecessor). ``reset_join_window``: a reset asked for from outside
    (``reset_requested``) the same way as the reset that finished, less than this many
    seconds after it or after the latest request that joined it, while the loop steps, is that
    reset (a burst of calls is one reset, however long it is spread). ``wait_note_every``: while a
    step's call is out, say every this many seconds what the step waits for.
    ``world_call_timeout``: a step whose call to the world (the human's action, a snapshot)
    has not come back after this many seconds fails, naming the call. ``episodes``: the
    episode numbers to play, in order (None: 1, 2, 3 ...; see :mod:`ros_hrc.loop.schedule`).
    ``task``: the collaboration task (the seed's by default); ``goal_state`` None is the
    task's goal. ``seed``: the run's seed, whose (seed, episode) stream the task's
    observation noise draws from. ``human_model``: the human model's name or path, for the
    task's labels of the robot's true state (fabric: a tired human's). ``tasks``: play a
    sequence of this many tasks (0: none; see :mod:`ros_hrc.loop.sequence`), ``schedule`` says
    who plays each (None: ``human_model`` every task), ``task_timeout``: simulated seconds
    after which a task of the sequence ends with outcome timeout."""

    max_steps: int = settings.default("max_steps")
    end_on_goal: bool = settings.default("end_on_goal")
    goal_state: Optional[str] = None
    on_episode_end: str = settings.default("on_episode_end")
    retry_delay: float = RETRY_DELAY
    max_retry_delay: float = MAX_RETRY_DELAY
    first_epoch: int = 1
    reset_join_window: float = RESET_JOIN_WINDOW
    wait_note_every: float = WAIT_NOTE_EVERY
    world_call_timeout: float = WORLD_CALL_TIMEOUT
    episodes: Optional[EpisodeSchedule] = None
    task: Task = SEED
    seed: int = settings.default("seed")
    human_model: str = ""
    tasks: int = 0
    schedule: Optional[Schedule] = None
    task_timeout: Optional[float] = None

    def __post_init__(self) -> None:
        if self.goal_state is None:
            object.__setattr__(self, "goal_state", self.task.goal_state)
        if self.task_timeout is None:
            object.__setattr__(self, "task_timeout", self.task.task_timeout)
        if self.tasks < 0 or not self.task_timeout > 0:
            raise ValueError("tasks >= 0 and task_timeout > 0 are required")
        if self.on_episode_end not in EPISODE_END_POLICIES:
            raise ValueError(f"on_episode_end must be one of {', '.join(EPISODE_END_POLICIES)}, "
                             f"not {self.on_episode_end!r}")
        if self.max_steps < 0 or self.retry_delay <= 0 or self.first_epoch < 0:
            raise ValueError("max_steps >= 0, retry_delay > 0 and first_epoch >= 0 are required")
        if (self.reset_join_window < 0 or self.wait_note_every <= 0
                or self.world_call_timeout <= 0):
            raise ValueError("reset_join_window >= 0, wait_note_every > 0 and "
                             "world_call_timeout > 0 are required")
