"""Where the coordinator's parts put what they emit (Sans-I/O): the effects in the order they
were emitted, and the calls made and not answered yet. One counter numbers both the calls
and the timers, so an id names one thing whichever part made it."""
from __future__ import annotations

import itertools
from typing import Any, Dict, List, Optional

from ros_hrc.loop.effects import Call, Effect, Note, Timer


class Outbox:
    """The effects emitted so far (taken by :meth:`take`) and the calls still out."""

    def __init__(self) -> None:
        self._ids = itertools.count(1)
        self._effects: List[Effect] = []
        #: Calls made and not answered yet, by id.
        self.outstanding: Dict[int, Call] = {}

    def take(self) -> List[Effect]:
        """The effects emitted since the last take, in order."""
        out, self._effects = self._effects, []
        return out

    def emit(self, effect: Effect) -> None:
        self._effects.append(effect)

    def note(self, level: str, text: str) -> None:
        self.emit(Note(level, text))

    def call(self, kind: type, epoch: Optional[int], step: Optional[int], **fields: Any) -> Call:
        """Make a call of ``kind`` in ``epoch`` (for step ``step``; None: no step's): it is
        outstanding until it is answered (:meth:`answered`)."""
        call = kind(id=next(self._ids), epoch=epoch, step=step, **fields)
        self.outstanding[call.id] = call
        self.emit(call)
        return call

    def answered(self, call_id: int) -> Optional[Call]:
        """The call ``call_id`` came back: no longer outstanding (None: unknown, or answered
        already)."""
        return self.outstanding.pop(call_id, None)

    def timer(self, seconds: float) -> int:
        """Ask for ``timer_fired`` after ``seconds``: the timer's id."""
        timer = next(self._ids)
        self.emit(Timer(timer, seconds))
        return timer
