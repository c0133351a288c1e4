"""Epochs and resets of the loop (Sans-I/O).

**The epoch.** Every reset mints a new epoch, and every call carries the epoch it was made in;
the coordinator drops anything of an older epoch. A reset first waits for the calls still out
(**draining**: a world action under way is interrupted by an early world reset), then resets
the world and the planner into the new epoch (**resetting**), then reads the world once, the
episode's start (**starting**); only then is the MDP told, so nothing of the old epoch can act
in the new one.

**Joining.** Resets asked for while one is under way join it (a burst of fifty is one reset),
and so does one asked for from outside the same way as the reset that finished, within
``reset_join_window`` seconds of it or of the latest request that joined it.

**Retrying.** A reset that fails answers everyone who asked for it at once, saying what it
could and could not reset, and is retried after ``retry_delay`` seconds, doubling up to
``max_retry_delay``, until it works.
"""
from __future__ import annotations

from typing import Any, Dict, List, Optional, Tuple

from ros_hrc.loop.config import CoordinatorConfig
from ros_hrc.loop.effects import (ActHuman, ActRobot, Call, Fault, ObserveWorld, Outcome,
                                  ResetDone, ResetPlanner, ResetWorld, Snapshot)
from ros_hrc.loop.outbox import Outbox

#: What a timer of the resets was for (:meth:`Resets.timer_fired`).
RETRY, JOIN_CLOSED = "retry", "join_closed"


class Resets:
    """The epoch (``epoch``: the current one, None before the first reset) and the reset
    under way: why (``reason``), who asked (their tokens, answered by :class:`ResetDone`),
    its stage and the parts reset so far; a failed reset's retry and a finished reset's
    window for joiners. See the module docstring."""

    def __init__(self, config: CoordinatorConfig, outbox: Outbox) -> None:
        self.config = config
        self.outbox = outbox
        self.epoch: Optional[int] = None
        self._next_epoch = config.first_epoch
        self.reason = ""
        self._tokens: List[Any] = []
        self._stage = ""                # draining -> resetting -> starting
        self._calls: Dict[int, str] = {}   # the reset's calls out: id -> the part it resets
        self._problems: List[str] = []
        self._parts_done: List[str] = []
        self.retry_timer: Optional[int] = None
        self._retry_delay = config.retry_delay
        self.join_timer: Optional[int] = None   # runs while a finished reset can be joined
        self._join_reason = ""          # how that reset was asked for
        self._asked = ""                # how the reset under way was asked for from outside
        self._last_text = ""

    # -- asking --------------------------------------------------------------------------------
    def joins_finished(self, reason: str, token: Any) -> bool:
        """A reset asked for ``reason`` is the reset that finished last (its window is open
        and it was asked for the same way): ``token`` is answered at once, and the window
        runs from this request. The caller knows the loop steps since."""
        if self.join_timer is None or reason != self._join_reason:
            return False
        if token is not None:
            self.outbox.emit(ResetDone((token,), True, f"{self._last_text} (this request "
                                                       "joined it: it came as it finished)"))
        # The burst goes on: the window runs from its latest request.
        self.join_timer = self.outbox.timer(self.config.reset_join_window)
        return True

    def asked_from_outside(self, reason: str) -> None:
        """The reset that starts now was asked for from outside, ``reason``: for a while after
        it finished, more requests asked the same way are it."""
        self._asked = reason

    def join(self, token: Any) -> None:
        """``token`` asked for a reset while this one is under way: it is answered with it."""
        if token is not None:
            self._tokens.append(token)

    def refuse(self, token: Any, message: str) -> None:
        """No reset comes for ``token``: say why."""
        if token is not None:
            self.outbox.emit(ResetDone((token,), False, message))

    # -- the reset under way -----------------------------------------------------------------
    def begin(self, reason: str, token: Any) -> int:
        """A reset begins, for ``reason`` (``token``: who asked, or None): the new epoch."""
        self.retry_timer = None
        self.epoch = self._next_epoch
        self._next_epoch += 1
        self.reason = reason
        self._tokens = [token] if token is not None else []
        self._problems = []
        self._parts_done = []
        self._calls = {}
        self._stage = "draining"
        return self.epoch

    def interrupt_motions(self) -> None:
        """Stop the motions under way now, so the calls waiting on them come back soon."""
        if any(isinstance(c, (ActHuman, ActRobot)) for c in self.outbox.outstanding.values()):
            self.outbox.call(ResetWorld, self.epoch, None, interrupt=True)

    def drained(self) -> bool:
        """The reset drains, and nothing of an older epoch is out any more (nor the
        interrupting world reset): the world and the planner can be reset."""
        if self._stage != "draining":
            return False
        out = self.outbox.outstanding.values()
        if any(c.epoch != self.epoch for c in out):
            return False   # calls of the old epoch still out: they could act after the reset
        return not any(isinstance(c, ResetWorld) and c.interrupt for c in out)

    def reset_parts(self, episode: int, task_index: int, true_type: str) -> None:
        """Reset the world and the planner into the epoch, for ``episode`` (in a sequence:
        task ``task_index``, whose human is ``true_type``), together."""
        self._stage = "resetting"
        world = self.outbox.call(ResetWorld, self.epoch, None, episode=episode)
        planner = self.outbox.call(ResetPlanner, self.epoch, None, episode=episode,
                                   task_index=task_index, true_type=true_type)
        self._calls = {world.id: "world", planner.id: "robot planner"}

    def part_reset(self, call: Call, result: Any) -> Optional[str]:
        """A reset call (of this epoch) came back: when every part is reset, the world is
        read for the episode's start. Why the reset failed (None: it goes on)."""
        if isinstance(call, ResetWorld) and call.interrupt:
            return None
        what = self._calls.pop(call.id, None)
        if what is None:
            return None
        if isinstance(result, Fault):
            self._problems.append(f"{what}: {result.message}")
        elif isinstance(result, Outcome) and not result.success:
            self._problems.append(f"{what}: {result.message}")
        else:
            self._parts_done.append(what)
        if self._calls:
            return None
        if self._problems:
            done = ", ".join(self._parts_done) or "nothing"
            return (f"not reset: {'; '.join(self._problems)}; reset: {done}; the human MDP is "
                    "told when all are")
        self._stage = "starting"
        self.outbox.call(ObserveWorld, self.epoch, None, purpose="episode_start")
        return None

    @staticmethod
    def start_time(result: Any) -> Tuple[Optional[float], str]:
        """The world's answer at the episode's start: (its simulated time, "") or (None, why
        the reset fails)."""
        if isinstance(result, Fault):
            return None, f"world: {result.message}"
        if not isinstance(result, Snapshot) or not isinstance(result.sim_time, (int, float)):
            return None, f"world: the snapshot at the episode's start is {result!r}"
        return float(result.sim_time), ""

    def finished(self, episode: int) -> Tuple[Tuple[Any, ...], str]:
        """The reset worked and started ``episode``: (who asked, what they are answered)."""
        self._retry_delay = self.config.retry_delay
        tokens, self._tokens = tuple(self._tokens), []
        text = (f"world, robot belief and human MDP reset ({self.reason}): episode "
                f"{episode}")
        if self._asked and self.config.reset_join_window > 0:
            # Asked for from outside: for a while, more requests asked the same way are it
            # (resets the loop makes itself in between, e.g. at an episode's end, do not
            # close the window).
            self._last_text = text
            self._join_reason, self._asked = self._asked, ""
            self.join_timer = self.outbox.timer(self.config.reset_join_window)
        return tokens, text

    def answer(self, tokens: Tuple[Any, ...], success: bool, text: str) -> None:
        if tokens:
            self.outbox.emit(ResetDone(tokens, success, text))

    def failed(self, why: str) -> None:
        """The reset failed (``why``): say so, answer who asked, retry it after a while."""
        tokens, self._tokens = tuple(self._tokens), []
        self.outbox.note("error", f"reset failed: {why}; retrying in {self._retry_delay:g} s")
        self.answer(tokens, False, f"reset failed: {why}; retried in {self._retry_delay:g} s "
                                   f"(then every up to {self.config.max_retry_delay:g} s) until "
                                   "it works")
        self.retry_timer = self.outbox.timer(self._retry_delay)
        self._retry_delay = min(self._retry_delay * 2, self.config.max_retry_delay)

    def timer_fired(self, timer_id: int) -> Optional[str]:
        """What the timer ``timer_id`` was for: :data:`RETRY` (retry the failed reset),
        :data:`JOIN_CLOSED` (the window for joiners closed), None (not one of the resets')."""
        if timer_id == self.join_timer:
            self.join_timer = None
            return JOIN_CLOSED
        if timer_id != self.retry_timer:
            return None
        self.retry_timer = None
        return RETRY

    def run_ended(self, why: str) -> None:
        """The run ends: no retry, no joining; who asked is answered that no reset comes."""
        self.retry_timer = self.join_timer = None
        tokens, self._tokens = tuple(self._tokens), []
        self.answer(tokens, False, f"no reset: the run ends ({why})")
