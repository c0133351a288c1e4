"""The episode schedule of the loop (Sans-I/O): which episode a reset starts, when an episode
ends, and what comes after its end.

**Episode numbers.** An episode's number names its random streams (:mod:`ros_hrc.streams`:
the MDP, the world and the planner reseed from (seed, episode) at its reset), so it is the
study's number, not a count of resets. Without a schedule (a live launch) every reset that
succeeds starts the next number, 1, 2, 3 ... With one (``CoordinatorConfig.episodes``, an
experiment cell's episodes, e.g. 5 and 7 only) the episodes are the schedule's, in order: the
next one starts only after an episode *ended* (success, the object left the belt, the step
limit, the goal); a reset before that (a failed step, a process that restarted) plays the same
episode again from its start, so every scheduled episode is played whole, on its own streams.
After the schedule's last episode ended the loop waits: no reset starts another.

**An episode's end.** After a step, when someone holds the object (``success``), the object
left the belt (``object_left_belt``), the human MDP reached the goal (``human_goal``, with
``end_on_goal``), a task of a sequence ran out of time (``task_timeout``) or after
``max_steps`` steps (``step_limit``). Then, by ``on_episode_end``: ``wait`` for a reset,
``reset`` at once, ``continue`` stepping (the end reported once).
"""
from __future__ import annotations

from typing import Optional, Tuple

from ros_hrc.loop.config import CoordinatorConfig
from ros_hrc.command_line import counted
from ros_hrc.loop.effects import StepReport
from ros_hrc.streams import EpisodeSchedule
from ros_hrc.tasks.utility import sim_span

#: What comes after an episode's end (:meth:`Episodes.after_end`): refuse steps until a
#: reset, reset at once, go on stepping.
WAIT, RESET, CONTINUE = "wait", "reset", "continue"


class Episodes:
    """The episodes a loop plays: the one under way (``number``, its ``start_time``), which
    one the next reset starts, and how each ends (see the module docstring)."""

    def __init__(self, config: CoordinatorConfig) -> None:
        self.config = config
        self.number = 0                 # the episode under way (0: none yet)
        self.start_time = 0.0           # the world's simulated time at its start
        self.done = False               # it ended (not only cut short)
        self.end_reported = False       # with on_episode_end=continue: its end was reported
        self._started_any = False       # an episode has started since the loop began

    def next(self) -> Optional[int]:
        """The number of the episode the next reset starts; None when the schedule's last
        episode has ended."""
        schedule = self.config.episodes
        if schedule is None:
            return self.number + 1
        if not self._started_any:
            return schedule.first()
        if not self.done:
            return self.number      # cut short: played again, whole, on its own streams
        return schedule.after(self.number)

    def reset_begins(self) -> None:
        """A reset begins: the episode it starts reports its own end."""
        self.end_reported = False

    def start(self, sim_time: float) -> int:
        """A reset finished at the world's ``sim_time``: the next episode starts; its number."""
        self.start_time = sim_time
        self.number = self.next()
        self._started_any = True
        self.done = False
        return self.number

    def end_reason(self, report: StepReport) -> str:
        """Why the episode ends at the step ``report`` ("": it goes on, or its end was
        reported already and stepping goes on)."""
        if self.end_reported:
            return ""
        config = self.config
        if report.object_holder in ("human", "robot"):
            return "success"
        if report.object_left_belt:
            return "object_left_belt"
        if config.end_on_goal and report.human_state == config.goal_state:
            return "human_goal"
        if config.tasks and (sim_span(self.start_time, report.sim_time)
                             >= config.task_timeout):
            return "task_timeout"
        if config.max_steps and report.step + 1 >= config.max_steps:
            return "step_limit"
        return ""

    def step_ended(self, reason: str) -> Tuple[bool, bool]:
        """A step ended the episode for ``reason`` ("": it did not): (played out: no episode
        of the schedule is left after this one; stops: the MDP stops stepping until a
        reset, which ``on_episode_end:=continue`` does not ask but after the last episode or
        in a sequence)."""
        if reason:
            self.done = True
        played_out = bool(reason) and self.next() is None
        stops = bool(reason) and (self.config.on_episode_end != CONTINUE or played_out
                                  or self.config.tasks > 0)
        return played_out, stops

    def after_end(self, reason: str, steps: int, played_out: bool) -> Tuple[str, str]:
        """The episode ended for ``reason`` after ``steps`` steps: (what comes next:
        :data:`WAIT`, :data:`RESET` or :data:`CONTINUE`; the terminal's line saying so)."""
        on_end = self.config.on_episode_end
        line = episode_over_line(self.number, reason, steps, on_end,
                                 self.config.episodes if played_out else None)
        if played_out or on_end == WAIT:
            return WAIT, line
        if on_end == RESET:
            return RESET, line
        self.end_reported = True
        return CONTINUE, line


def episode_over_line(episode: int, reason: str, steps: int, on_end: str,
                      played: Optional[EpisodeSchedule] = None) -> str:
    """What the terminal says, once, when an episode ends: how, after how many steps, and
    what happens next by ``on_end`` (the ``on_episode_end`` setting), or that the episodes
    asked for (``played``) are all played."""
    over = f"episode {episode} over ({reason}) after {counted(steps, 'step')}"
    if played is not None:
        return (f"{over}: the episodes asked for ({played.text()}) are all played: no reset "
                "starts another")
    if on_end == WAIT:
        return (f"{over}: Enter (or `rosservice call /hrc/reset`) resets and starts the next, "
                "or on_episode_end:=reset to go on by itself")
    if on_end == RESET:
        return f"{over}: the next starts now (on_episode_end:=reset)"
    return f"{over}: stepping goes on (on_episode_end:=continue)"
