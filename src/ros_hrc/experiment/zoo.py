"""The human zoo: the human models of the study, split into a fit set and a held-out set.

Every name is a scenario of ``models/human/`` (``<name>.pomdpx``); models/README.md ("The
human zoo") says what each human does alone and why it is in the zoo. The robot model is fitted
and the reactive baseline tuned on :data:`ZOO_FIT` only; :data:`ZOO_HELD_OUT` is used only to
evaluate. Each set spans the kinds: humans who succeed alone almost always, some of the time
and never, and humans who warn the robot off. The four held-out kinds the issue names (a
deliberator who succeeds alone, a persistent failer who warns, one who looks away first, one
who tires late) are held out. No ROS.
"""
from __future__ import annotations

from typing import Tuple

#: Fit the robot model and tune the reactive baseline on these (alone, 15 steps: humanModel,
#: distracted, walker, slow_steady and early_warner ~always succeed; confident_novice ~4 in 5;
#: beginner and tired never; early_warner warns).
ZOO_FIT: Tuple[str, ...] = ("humanModel", "distracted", "walker", "slow_steady", "early_warner",
                            "confident_novice", "beginner", "tired")

#: Evaluate only on these (alone: expert, deliberator, looks_away_first ~always; tires_late
#: ~9 in 10; drops_and_waits 4 in 5; persistent_failer ~1 in 2 and warns; evaluating never).
ZOO_HELD_OUT: Tuple[str, ...] = ("expert", "deliberator", "looks_away_first", "tires_late",
                                 "drops_and_waits", "persistent_failer", "evaluating")

#: The whole zoo, fit set first.
ZOO: Tuple[str, ...] = ZOO_FIT + ZOO_HELD_OUT

#: Human models of models/human/ that are not in the zoo, and why.
NOT_IN_ZOO = {"humanModel_completed": "a variant of humanModel (our completion of the "
                                      "manual), kept to reproduce Figure 3.9"}


def zoo_argument(which: str = "all") -> str:
    """The zoo (``all``), its fit set (``fit``) or held-out set (``held_out``) as the
    comma-separated list ``--human-models`` takes."""
    sets = {"all": ZOO, "fit": ZOO_FIT, "held_out": ZOO_HELD_OUT}
    if which not in sets:
        raise ValueError(f"unknown zoo set {which!r}: {', '.join(sets)}")
    return ",".join(sets[which])
