"""What the package's ROS-free commands share about their command line."""
from __future__ import annotations

import sys
from typing import List, Optional, Sequence


def own_arguments(argv: Optional[Sequence[str]] = None) -> List[str]:
    """The command line (``sys.argv[1:]`` by default) without the ``__name:=`` / ``__log:=``
    arguments roslaunch appends to every node it starts: they are not ours to parse, and
    these commands must not import rospy (whose ``myargv`` does the same) to drop them."""
    return [a for a in (sys.argv[1:] if argv is None else argv) if not a.startswith("__")]
