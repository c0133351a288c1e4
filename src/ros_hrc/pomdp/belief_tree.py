"""The tree of beliefs HSVI's trials visit (SARSOP's tree of reachable beliefs) and the bounds
cached at its nodes (:mod:`ros_hrc.pomdp.hsvi`).

Each node keeps its successors of non-zero probability under every action and observation, and
both bounds at them and at itself, cached between visits. A cached value is brought up to date
with the points (vectors) added since (:meth:`~ros_hrc.pomdp.bounds.UpperBound.cached_values`,
:meth:`~ros_hrc.pomdp.bounds.LowerBound.cached`), not recomputed over all of them. A model
whose successors are too large to keep (``KEEP_SUCCESSORS``) has no tree and computes them at
each visit; nodes are kept while the tree's budget (``TREE_NUMBERS``) and the solver's memory
budget last.
"""
from __future__ import annotations

from typing import Callable, Optional, ValuesView

import numpy as np

from ros_hrc.pomdp.belief_set import belief_key
from ros_hrc.pomdp.bounds import LowerBound, LowerCached, UpperBound, UpperCached
from ros_hrc.pomdp.hsvi_tables import HsviTables

#: A trial keeps each step's successor beliefs (A·Z·S numbers) for the backups on its way back
#: while they are at most this many numbers; larger ones are computed again in the backup.
KEEP_SUCCESSORS = 1_000_000

#: Numbers (8 bytes each) the belief tree may keep: its nodes' successors (64 MB).
TREE_NUMBERS = 8_000_000


def keeps_successors(t: HsviTables) -> bool:
    """Whether a model of these tables keeps its nodes' successors (and has a tree)."""
    return t.A * t.Z * t.S <= KEEP_SUCCESSORS


class Node:
    """A belief of the trials' tree: its successors under every action and observation,
    computed once, and both bounds there and at itself, cached between visits.

    ``rows`` is the belief followed by its successors of non-zero probability, action by
    action (``succ[j]``, row 1 + j, is the successor under (a, z) = divmod(succ[j], Z), of
    probability ``p_succ[j]``; action a's are rows 1 + start[a] to 1 + start[a + 1]), the rows
    of both caches (``up``, ``lo``); ``children`` the nodes of the successors a trial went to,
    by row. A successor of probability zero counts in no bound at the node, so it is not kept.
    """

    __slots__ = ("b", "key", "rows", "rows_t", "rb", "up", "lo", "kept", "children",
                 "succ", "p_succ", "start", "p_matrix", "has_zero")

    def __init__(self, b: np.ndarray, key: Optional[bytes] = None) -> None:
        self.b = b
        self.key = key
        self.rows: Optional[np.ndarray] = None
        self.rows_t: Optional[np.ndarray] = None
        self.rb: Optional[np.ndarray] = None
        self.up: Optional[UpperCached] = None
        self.lo: Optional[LowerCached] = None
        self.kept = False
        self.children: dict = {}

    def drop_successors(self) -> None:
        """Forget the successors (computed again when needed), keeping the cached bounds."""
        self.rows = self.rows_t = self.p_matrix = None

    def q_upper(self) -> np.ndarray:
        """Upper-bound Q values at a refreshed node (:meth:`BeliefTree.refresh`), (A,)."""
        return self.rb + self.p_matrix @ self.up.vals[1:]


class BeliefTree:
    """The kept nodes by belief key, and what makes and refreshes nodes.

    ``room(vectors)`` says whether the solver's memory budget has room for that many more
    vectors of S numbers; a node costs ``node_vectors`` of them.
    """

    def __init__(self, t: HsviTables, lower: LowerBound, upper: UpperBound,
                 room: Callable[[int], bool]) -> None:
        self.t = t
        self.lower = lower
        self.upper = upper
        self.room = room
        self.keep_successors = keeps_successors(t)
        self.nodes: dict = {}
        # Numbers the tree may still keep: every node's successors and cached bounds while
        # they take at most TREE_NUMBERS (a small model's whole tree); none for a model whose
        # successors are too large to keep.
        self.budget = TREE_NUMBERS if self.keep_successors else 0
        # A node costs its successors (A·Z rows of S, twice: ``rows`` and ``rows_t``), an (A,
        # A·Z) matrix and a few A·Z arrays, in vectors of S.
        self.node_vectors = (2 * t.A * t.Z + -(-(6 + t.A) * t.A * t.Z // t.S) + 3)

    def __len__(self) -> int:
        return len(self.nodes)

    def values(self) -> ValuesView[Node]:
        """The kept nodes."""
        return self.nodes.values()

    def node(self, b: np.ndarray) -> Node:
        """The tree's node at belief b (made on the first visit). Nodes are kept while the
        tree's budget lasts; past it (and for models whose successors are too large to keep) a
        node lives for one trial and its successors are computed again."""
        key = belief_key(b) if self.budget > 0 else None
        node = self.nodes.get(key) if key is not None else None
        if node is not None:
            return node
        node = Node(b, key)
        if key is not None and self.room(self.node_vectors):
            self.nodes[key] = node
            node.kept = True
            self.budget -= 2 * self.t.A * self.t.Z * self.t.S
        return node

    def child(self, node: Node, row: int) -> Node:
        """The node of successor ``row`` of ``node`` (a row of ``node.rows``), remembered when
        both are kept (no belief key to compute on the next visit)."""
        child = node.children.get(row)
        if child is None:
            child = self.node(node.rows[row])
            if node.kept and child.kept:
                node.children[row] = child
        return child

    def refresh(self, node: Node) -> None:
        """Bring the node's cached bounds (at its belief and its successors) up to date,
        computing its successors first if they are not kept."""
        if node.rows is None:
            t = self.t
            p, B = t.successors(node.b)
            p_flat = p.ravel()
            succ = np.flatnonzero(p_flat > 0)
            node.rows = np.concatenate((node.b[None], B.reshape(-1, t.S)[succ]))
            node.rows_t = np.ascontiguousarray(node.rows.T)
            action = succ // t.Z
            if node.rb is None:
                node.succ, node.p_succ = succ, p_flat[succ]
                node.start = np.searchsorted(action, np.arange(t.A + 1))
                node.has_zero = (p <= 0).any(axis=1)
                node.rb = t.R @ node.b
            # Q = R·b + γ Σ_z p(z|b,a)·U(successor): one product with this (A, successors).
            node.p_matrix = np.zeros((t.A, succ.size))
            node.p_matrix[action, np.arange(succ.size)] = t.gamma * node.p_succ
        node.up = self.upper.cached_values(node.rows, node.up, node.rows_t)
        node.lo = self.lower.cached(node.rows, node.lo)
