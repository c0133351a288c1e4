"""Memory budgets: what reading, solving or simulating a model will need, estimated from its sizes
and non-zeros *before* anything large is allocated, and a one-line refusal when that is more
than the limit.

Every estimate is meant to be an upper bound of the peak the step adds (the arrays it keeps plus
its largest temporaries), not an exact figure; the interpreter and the libraries (about 100 MB)
are not counted. ``hrc_pomdp`` passes ``--memory-limit`` (default :data:`DEFAULT_MEMORY_LIMIT`)
to the readers and solvers; library calls pass ``memory_limit=None`` (no check) unless they
ask for one.
"""
from __future__ import annotations

import math
import re
from typing import Iterable, Optional

from ros_hrc.errors import HrcError

MiB = 1 << 20
GiB = 1 << 30

#: The budget ``hrc_pomdp`` uses when ``--memory-limit`` is not given.
DEFAULT_MEMORY_LIMIT = 4 * GiB

#: Bytes of one stored non-zero of a CSR table: a float64 value and a column index (int64 when
#: scipy needs it), rounded up.
BYTES_PER_NONZERO = 16

#: A table being built (patterns, sorted copies, a Kronecker product's index arrays) peaks at
#: about this many bytes per non-zero of the result, while it is the only one being built.
BUILD_BYTES_PER_NONZERO = 64

#: Bytes a name (state, action, observation) costs: the string, its list slot and its dict entry.
BYTES_PER_NAME = 160

#: A parsed file holds every token (a Cassandra word, a POMDPX element or number) as a Python
#: object: measured 41-44 bytes per byte of a .pomdp file, 17 per byte of a .pomdpx file; a
#: file of one-character tokens costs more, hence the margin.
PARSE_BYTES_PER_FILE_BYTE = 50

_UNITS = {"": MiB, "k": 1 << 10, "m": MiB, "g": GiB, "t": 1 << 40}


class MemoryLimitError(HrcError):
    """A step would need more memory than the limit: names the file, the step, the estimate."""

    def __init__(self, source: str, what: str, needed: float, limit: int) -> None:
        self.source = source
        self.what = what
        self.needed = needed
        self.limit = limit
        super().__init__(f"{source}: {what} needs about {format_bytes(needed)}, more than the "
                         f"memory limit of {format_bytes(limit)}")


def require(needed: float, limit: Optional[int], source: str, what: str) -> None:
    """Raise MemoryLimitError when ``needed`` bytes exceed ``limit`` (None: no limit)."""
    if limit is not None and needed > limit:
        raise MemoryLimitError(source, what, needed, limit)


def format_bytes(n: float) -> str:
    """``512 MiB``, ``1.5 GiB``, ``37 TiB``: two or three significant digits."""
    for unit, size in (("TiB", 1 << 40), ("GiB", GiB), ("MiB", MiB), ("KiB", 1 << 10)):
        if n >= size:
            value = n / size
            return f"{value:.3g} {unit}" if value < 1000 else f"{value:.0f} {unit}"
    return f"{int(n)} bytes"


def parse_size(text: str) -> int:
    """A memory size: a number with an optional unit K, M, G or T (KiB .. TiB; a trailing
    ``B``/``iB`` is allowed), megabytes (MiB) when there is none. ValueError when it is not one."""
    match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([kKmMgGtT]?)(?:i?[bB])?\s*",
                         text)
    if not match:
        raise ValueError(f"not a size: {text!r} (e.g. 512M, 4G)")
    value = float(match.group(1)) * _UNITS[match.group(2).lower()]
    if not math.isfinite(value):
        raise ValueError(f"not a finite size: {text!r}")
    return int(value)


def csr_bytes(nonzeros: int, rows: int) -> int:
    """What a CSR table of ``nonzeros`` entries and ``rows`` rows keeps."""
    return BYTES_PER_NONZERO * int(nonzeros) + 8 * (int(rows) + 1)


def tables_bytes(nonzeros: Iterable[int], rows: int) -> int:
    """Building and keeping CSR tables of these sizes (each ``rows`` rows), one at a time: all
    of them kept, plus the largest one's construction peak."""
    sizes = [int(n) for n in nonzeros]
    if not sizes:
        return 0
    return sum(csr_bytes(n, rows) for n in sizes) + BUILD_BYTES_PER_NONZERO * max(sizes)


#: What each action costs besides its tables' rows and non-zeros: three CSR objects (about
#: 800 bytes each, measured) and the reader's per-action bookkeeping.
BYTES_PER_ACTION = 5000


def model_overhead(states: int, actions: int, observations: int = 0) -> int:
    """What a model keeps besides its tables' non-zeros: names, the row pointers and objects of
    three tables per action, the initial belief, the observed key and R(s, a)."""
    return (BYTES_PER_NAME * (states + actions + observations)
            + actions * (3 * 8 * (states + 1) + BYTES_PER_ACTION) + 24 * states
            + 8 * actions * states)


def model_bytes(model) -> int:
    """What a loaded model keeps: its tables, names and belief (numpy's real sizes)."""
    total = 0
    for table in (model.T, model.O, model.R):
        for m in table:
            total += m.data.nbytes + m.indices.nbytes + m.indptr.nbytes + 200
    names = model.n_states + model.n_actions + model.n_observations
    # The names, the initial belief and observed key, and the cached R(s, a).
    return total + BYTES_PER_NAME * names + 16 * model.n_states \
        + 8 * model.n_actions * model.n_states
