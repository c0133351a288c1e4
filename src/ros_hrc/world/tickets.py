"""The actions asked of the world: a ticket per request, each agent's queue, who goes first.

A caller submits an action and gets a :class:`Ticket` to wait on. Between two steps the
world's loop takes the requests in the order they came (:meth:`ActionQueues.take`): a reset or
a cancel takes effect at once, interrupting the agent's motion and emptying its queue; any
other action queues on the agent's :class:`Channel` behind its current one. The agents have
one *driver* (the loop), who never waits behind other callers: its actions go first, and
while one is under way or waiting, another caller's request for that agent is refused at once
(the rule is :meth:`~.scene.World.submit`'s). Everything here runs under the world's lock.
"""
from __future__ import annotations

import threading
from collections import deque
from dataclasses import replace
from typing import Deque, Dict, Iterator, List, Mapping, Optional

from ..errors import SimulationError
from .body import ArticulatedBody, Motion
from .outcome import Outcome

#: Requests that take effect at once and interrupt the agent's motion and queue.
INTERRUPTING = {("human", "reset"), ("robot", "reset"), ("robot", "cancel_action"), ("world", "reset")}


class Ticket:
    """A submitted action: wait for it to get its :class:`Outcome`.

    ``caller`` names who asked (for messages); ``driver``: the agents' driver asked (the
    loop), whose actions go first (see :meth:`World.submit`)."""

    def __init__(self, agent: str, action: str, caller: str = "", driver: bool = False) -> None:
        self.agent = agent
        self.action = action
        self.caller = caller
        self.driver = driver
        self.submitted_at: Optional[float] = None  # simulated time it was asked for
        self.started_at: Optional[float] = None   # simulated time the motion began
        self.outcome: Optional[Outcome] = None
        self.error: Optional[SimulationError] = None   # raised by wait(): the world failed
        self.refused = False                      # answered at once: the agent was busy
        self.preempted: List[str] = []            # other callers' actions this one cut short
        self._done = threading.Event()

    @property
    def name(self) -> str:
        """``agent/action``, as in the service names."""
        return f"{self.agent}/{self.action}"

    def asked_by(self) -> str:
        """``agent/action`` and who asked, for messages."""
        return self.name + (f" (asked by {self.caller})" if self.caller else "")

    def done(self) -> bool:
        """True once the action is over (finished, failed or interrupted)."""
        return self._done.is_set()

    def wait(self, timeout: Optional[float] = None) -> Outcome:
        """Block until the action is over and return its outcome (``timeout`` in wall seconds)."""
        if not self._done.wait(timeout):
            raise SimulationError(f"{self.name} did not finish within {timeout:.0f} s of wall-clock time "
                                  "(is the world's stepping loop running?)")
        if self.error is not None:
            raise self.error
        return self.outcome

    def finish(self, outcome: Outcome, now: float) -> None:
        """Record the outcome (with its simulated duration) and wake the waiters."""
        started = self.started_at if self.started_at is not None else now
        if self.preempted:   # say why the agent did not start from where the step left it
            outcome = replace(outcome, message=outcome.message + "; it first interrupted "
                              + ", ".join(self.preempted))
        self.outcome = replace(outcome, duration=now - started)
        self._done.set()

    def refuse(self, message: str, now: float) -> None:
        """Answer at once that the action will not run (the agent is busy for its driver)."""
        self.refused = True
        self.finish(Outcome(False, message), now)

    def fail(self, error: SimulationError, now: float) -> None:
        """End the action because the world cannot go on: the waiters get ``error``."""
        self.error = error
        self.finish(Outcome(False, f"{self.name} abandoned: {error}"), now)


class Channel:
    """One agent's current motion and the actions queued behind it."""

    def __init__(self, body: ArticulatedBody) -> None:
        self.body = body
        self.motion: Optional[Motion] = None
        self.ticket: Optional[Ticket] = None
        self.queue: Deque[Ticket] = deque()
        #: The action under way was answered as it started (:meth:`answer_early`): its
        #: motion goes on, but it no longer keeps the world's clock running.
        self.answered = False

    def start_next(self, now: float) -> None:
        """Put the first queued action under way: its motion is made, not advanced yet."""
        self.ticket = self.queue.popleft()
        self.ticket.started_at = now
        self.motion = getattr(self.body, self.ticket.action)()
        self.body.moving = True

    def answer_early(self, outcome: Outcome, now: float) -> None:
        """Answer the action under way now, with ``outcome``; its motion goes on (a cancel or
        a reset still stops it, another action waits for it)."""
        self.ticket.finish(outcome, now)
        self.answered = True

    def end(self, outcome: Outcome, now: float) -> Outcome:
        """The action under way is over with ``outcome``: the agent is free. Returns the
        outcome (for an action answered early, its caller has had another)."""
        if not self.answered:
            self.ticket.finish(outcome, now)
        self.motion, self.ticket, self.answered = None, None, False
        self.body.moving = False   # its joints stay where the last step put them
        return outcome

    def cut_short(self, message: str, now: float) -> None:
        """Stop the action under way where it is; it fails with ``message``."""
        if self.motion is not None:
            self.motion.close()
        self.end(Outcome(False, message), now)

    def cancel_queued(self, message: str, now: float, keep_drivers: bool = False) -> None:
        """Cancel the queued actions (with ``keep_drivers``, all but the driver's): each fails
        with ``message``."""
        kept: Deque[Ticket] = deque()
        while self.queue:
            queued = self.queue.popleft()
            if keep_drivers and queued.driver:
                kept.append(queued)
            else:
                queued.finish(Outcome(False, message), now)
        self.queue = kept


class ActionQueues:
    """The requests submitted since the loop last took them, and each agent's channel."""

    def __init__(self, bodies: Mapping[str, ArticulatedBody]) -> None:
        self.requests: Deque[Ticket] = deque()
        self.channels: Dict[str, Channel] = {name: Channel(body) for name, body in bodies.items()}

    def submit(self, ticket: Ticket, now: float) -> bool:
        """Take ``ticket`` for the loop, or refuse it at once while a driver's request holds
        its agent (see :meth:`driven`); True if taken."""
        ticket.submitted_at = now
        busy = None if ticket.driver else self.driven(ticket.agent)
        if busy is not None:
            doing = "resetting" if busy.agent == "world" else f"doing {busy.action}"
            ticket.refuse(f"busy: the {busy.agent} is {doing} for "
                          f"{busy.caller or 'its driver'}, which drives it; call again "
                          "when that is done", now)
            return False
        self.requests.append(ticket)
        return True

    def driven(self, agent: str) -> Optional[Ticket]:
        """The driver's request that holds ``agent`` (any agent for "world"): under way,
        queued or just submitted; None if none does."""
        agents = tuple(self.channels) if agent == "world" else (agent,)
        for ticket in self.requests:
            if ticket.driver and (agent == "world" or ticket.agent in (agent, "world")):
                return ticket
        for name in agents:
            channel = self.channels[name]
            if channel.ticket is not None and channel.ticket.driver:
                return channel.ticket
            for ticket in channel.queue:
                if ticket.driver:
                    return ticket
        return None

    def take(self, now: float) -> Iterator[Ticket]:
        """Take the requests in the order they came: queue each action behind its agent's
        (a driver's goes first: :meth:`preempt`), and yield each reset or cancel
        (:data:`INTERRUPTING`) for the world to carry out before the next request is taken."""
        while self.requests:
            ticket = self.requests.popleft()
            if (ticket.agent, ticket.action) in INTERRUPTING:
                yield ticket
                continue
            channel = self.channels[ticket.agent]
            if ticket.driver:
                self.preempt(channel, ticket, now)
            channel.queue.append(ticket)

    def interrupt(self, agent: str, by: str, now: float) -> Optional[str]:
        """Stop ``agent``'s motion and drop its queue (for ``agent/by``, a reset or a cancel);
        return the interrupted action's name."""
        channel = self.channels[agent]
        interrupted = None
        if channel.motion is not None:
            interrupted = channel.ticket.action
            channel.cut_short(f"{channel.ticket.name} interrupted by {agent}/{by} after "
                              f"{now - channel.ticket.started_at:.1f} s", now)
        channel.cancel_queued(f"cancelled by {agent}/{by} before it started", now)
        return interrupted

    def preempt(self, channel: Channel, by: Ticket, now: float) -> None:
        """The driver's ``by`` goes first: another caller's action under way on ``channel``
        is interrupted, those queued are cancelled (the driver's own stay in order)."""
        running = channel.ticket
        if running is not None and not running.driver:
            channel.cut_short(f"{running.name} interrupted by {by.asked_by()} after "
                              f"{now - running.started_at:.1f} s", now)
            by.preempted.append(running.asked_by())
        channel.cancel_queued(f"cancelled by {by.asked_by()} before it started", now, keep_drivers=True)

    def pending(self) -> List[Ticket]:
        """Take every request, running action and queued action out of the world."""
        pending = list(self.requests)
        self.requests.clear()
        for channel in self.channels.values():
            if channel.ticket is not None:
                pending.append(channel.ticket)
            pending.extend(channel.queue)
            channel.queue.clear()
            channel.motion, channel.ticket, channel.answered = None, None, False
        return pending

    def busy(self) -> bool:
        """True while a request waits or an agent has an action under way (not answered
        early: :meth:`Channel.answer_early`) or queued."""
        return bool(self.requests) or any((ch.motion is not None and not ch.answered) or ch.queue
                                          for ch in self.channels.values())
