"""The package's one exception tree.

    HrcError
    ├── ModelFormatError     a model file is malformed: carries the file and the line or element
    ├── ModelError           a model is inconsistent (probabilities, sizes, discount)
    ├── SolverError          a solver or planner could not do what was asked
    │   └── ZeroProbabilityObservation   Bayes' rule met an observation the belief gives probability 0
    ├── SimulationError      the world could not carry out an action or query
    ├── StackEnding          a part of the stack ends with the run (the launch stops): the end, not a fault
    └── LinkError            the websocket link failed
        └── ProtocolError    a message is malformed, unknown or too large
"""
import difflib
from typing import Iterable, Optional


def did_you_mean(name: object, known: Iterable[str]) -> str:
    """``did you mean <the nearest known name>?`` (difflib's nearest), or "" when no known
    name is close: the one hint of every line that refuses a mistyped name (a launch
    argument, a model, a library policy)."""
    near = difflib.get_close_matches(str(name), list(known), n=1)
    return f"did you mean {near[0]}?" if near else ""


class HrcError(Exception):
    """Base of every error raised on purpose by ros_hrc."""


class ModelFormatError(HrcError):
    """A model file cannot be read: names the file, the line or XML element, and what is wrong."""

    def __init__(self, path: str, where: Optional[str], what: str) -> None:
        self.path = path
        self.where = where
        self.what = what
        location = f"{path}:{where}" if where else path
        super().__init__(f"{location}: {what}")


class ModelError(HrcError):
    """A model's tables are inconsistent (do not sum to one, wrong sizes, bad discount)."""


class SolverError(HrcError):
    """A solver or planner failed."""


class ZeroProbabilityObservation(SolverError):
    """The observation has probability zero under the belief and action: Bayes' rule is undefined.

    Planners catch it, fall back to a documented belief and report the event.
    """

    def __init__(self, action: int, observation: int, detail: str = "") -> None:
        self.action = action
        self.observation = observation
        extra = f" ({detail})" if detail else ""
        super().__init__(f"observation {observation} has probability 0 after action {action}{extra}")


class SimulationError(HrcError):
    """The simulated world could not carry out a request."""


#: How the world's services say that the world ends with the run (the window was closed, or
#: the launch stops), in the service error they answer: hrc_human reads it as the end.
WORLD_ENDING = "the world is shutting down"


class StackEnding(HrcError):
    """A part of the stack ends because the run does (Ctrl-C, Esc in the window, the launch
    stopping): what was asked of it will not be done, and that is the end of the run, not a
    fault to report or to recover from by a reset."""


class LinkError(HrcError):
    """A websocket link failed (connect, send or receive)."""


class ProtocolError(LinkError):
    """A message is malformed, of an unknown type, or too large."""
