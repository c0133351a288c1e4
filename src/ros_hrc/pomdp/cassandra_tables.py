"""One action's table of a Cassandra ``.pomdp`` file (T, O, or R without observations), as the
statements wrote it, in order (:mod:`ros_hrc.pomdp.cassandra_reader` fills them).

The statements are kept as layers and resolved at the end (:meth:`Layers.materialise`), so a
wildcard or ``identity`` on a large model never expands into a dense array.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple

import numpy as np
import scipy.sparse as sp


class Layers:
    """The statements that wrote one action's table (T, O, or R without observations).

    Kept as layers and resolved at the end, so a wildcard or ``identity`` on a large model
    never expands into a dense array: the newest of (whole table or row, column, cell) wins.
    ``seq`` is the statement's position in the file.
    """

    def __init__(self, n_rows: int, n_cols: int) -> None:
        self.n_rows, self.n_cols = n_rows, n_cols
        self.whole: Optional[tuple] = None            # (seq, kind, payload) for every row
        self.row_whole: Dict[int, tuple] = {}          # row -> (seq, kind, payload)
        self.cells: Dict[int, Dict[int, tuple]] = {}   # row -> col -> (seq, value)
        self.col_cells: Dict[int, tuple] = {}          # col -> (seq, value) in every row

    # kinds: whole: dense | identity | uniform | const | rows;  row: vec | uniform | const
    def set_all(self, seq: int, kind: str, payload) -> None:
        self.whole = (seq, kind, payload)
        self.row_whole.clear()
        self.cells.clear()
        self.col_cells.clear()

    def set_row(self, seq: int, row: Optional[int], kind: str, payload) -> None:
        if row is None:
            self.set_all(seq, {"vec": "rows"}.get(kind, kind), payload)
        else:
            self.row_whole[row] = (seq, kind, payload)
            self.cells.pop(row, None)

    def set_cell(self, seq: int, row: Optional[int], col: Optional[int], value: float) -> None:
        if col is None:
            self.set_row(seq, row, "const", value)
        elif row is None:
            self.col_cells[col] = (seq, value)
        else:
            self.cells.setdefault(row, {})[col] = (seq, value)

    def row_seq(self, row: int) -> Optional[int]:
        """The newest statement that wrote to ``row`` (for error messages)."""
        seqs = []
        whole = self.row_whole.get(row, self.whole)
        if whole is not None:
            seqs.append(whole[0])
        seqs.extend(s for s, _ in self.cells.get(row, {}).values())
        seqs.extend(s for s, _ in self.col_cells.values())
        return max(seqs) if seqs else None

    # -- resolution -----------------------------------------------------------------------
    def _whole_pattern(self) -> sp.csr_matrix:
        R, C = self.n_rows, self.n_cols
        if self.whole is None:
            return sp.csr_matrix((R, C))
        _, kind, payload = self.whole
        if kind == "dense":
            return sp.csr_matrix((payload != 0).astype(float))
        if kind == "identity":
            return sp.identity(R, format="csr")
        if kind == "const" and payload == 0:
            return sp.csr_matrix((R, C))
        if kind == "rows":
            used = sp.csr_matrix((payload != 0).astype(float)[None, :])
            return sp.csr_matrix(np.ones((R, 1))) @ used
        # uniform, nonzero const: every cell, built as CSR directly (no dense R x C array)
        return sp.csr_matrix((np.ones(R * C), np.tile(np.arange(C), R),
                              np.arange(R + 1, dtype=np.int64) * C), shape=(R, C))

    def max_nonzeros(self) -> int:
        """An upper bound of the table's non-zeros from the statements alone, so its size can
        be checked before it is built."""
        R, C = self.n_rows, self.n_cols
        total = 0
        if self.whole is not None:
            _, kind, payload = self.whole
            if kind == "dense":
                total = int(np.count_nonzero(payload))
            else:
                if kind == "identity":
                    per_row = 1
                elif kind == "rows":
                    per_row = int(np.count_nonzero(payload))
                elif kind == "const" and payload == 0:
                    per_row = 0
                else:                                  # uniform, nonzero const
                    per_row = C
                total = per_row * (R - len(self.row_whole))
        for _, kind, payload in self.row_whole.values():
            if kind == "vec":
                total += int(np.count_nonzero(payload))
            elif not (kind == "const" and payload == 0):
                total += C
        total += len(self.col_cells) * R + sum(len(c) for c in self.cells.values())
        return min(total, R * C)

    def cell_arrays(self) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Row, column, statement and value of every single-cell entry, as arrays."""
        rows: List[int] = []
        cols: List[int] = []
        seqs: List[int] = []
        vals: List[float] = []
        for r, cells in self.cells.items():
            for c, (seq, value) in cells.items():
                rows.append(r)
                cols.append(c)
                seqs.append(seq)
                vals.append(value)
        return (np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64),
                np.array(seqs, dtype=np.int64), np.array(vals, dtype=float))

    def pattern(self, cells) -> sp.csr_matrix:
        """Every cell that may be nonzero, as a CSR matrix of ones with sorted indices."""
        R, C = self.n_rows, self.n_cols
        P = self._whole_pattern()
        rows: List[np.ndarray] = [cells[0]]
        cols: List[np.ndarray] = [cells[1]]
        if self.row_whole:
            keep = np.ones(R)
            keep[list(self.row_whole)] = 0.0
            P = sp.diags(keep) @ P
            for r, (_, kind, payload) in self.row_whole.items():
                if kind == "vec":
                    c = np.flatnonzero(payload)
                elif kind == "const" and payload == 0:
                    c = np.empty(0, dtype=np.int64)
                else:
                    c = np.arange(C)
                rows.append(np.full(c.size, r))
                cols.append(c)
        if self.col_cells:
            c = np.fromiter(self.col_cells.keys(), dtype=np.int64, count=len(self.col_cells))
            rows.append(np.repeat(np.arange(R), c.size))
            cols.append(np.tile(c, R))
        r_all = np.concatenate(rows)
        if r_all.size:
            c_all = np.concatenate(cols)
            P = P + sp.csr_matrix((np.ones(r_all.size), (r_all, c_all)), shape=(R, C))
        P = sp.csr_matrix(P)
        P.eliminate_zeros()
        P.sum_duplicates()
        P.sort_indices()
        P.data[:] = 1.0
        return P

    def values_at(self, indptr: np.ndarray, cols: np.ndarray, cells) -> np.ndarray:
        """The table's values at the cells of a CSR structure (sorted column indices)."""
        R, C = self.n_rows, self.n_cols
        rows = np.repeat(np.arange(R), np.diff(indptr))
        vals = np.zeros(cols.size)
        seq_w = np.full(cols.size, -1)
        if self.whole is not None:
            seq, kind, payload = self.whole
            seq_w[:] = seq
            if kind == "dense":
                vals = payload[rows, cols].astype(float)
            elif kind == "identity":
                vals = (rows == cols).astype(float)
            elif kind == "uniform":
                vals[:] = 1.0 / C
            elif kind == "const":
                vals[:] = payload
            else:                                      # rows: one vector for every row
                vals = payload[cols].astype(float)
        for r, (seq, kind, payload) in self.row_whole.items():
            sl = slice(indptr[r], indptr[r + 1])
            seq_w[sl] = seq
            if kind == "vec":
                vals[sl] = payload[cols[sl]]
            elif kind == "uniform":
                vals[sl] = 1.0 / C
            else:
                vals[sl] = payload
        col_seq = np.full(C, -1)
        if self.col_cells:
            col_val = np.zeros(C)
            for c, (seq, value) in self.col_cells.items():
                col_seq[c], col_val[c] = seq, value
            newer = col_seq[cols] > seq_w
            vals[newer] = col_val[cols[newer]]
        cell_rows, cell_cols, cell_seqs, cell_vals = cells
        if cell_rows.size and cols.size:
            # A cell entry is newer than its row's whole-row entry (which clears it) and wins
            # unless a whole-column entry came later.
            keys = rows.astype(np.int64) * C + cols
            want = cell_rows * C + cell_cols
            pos = np.minimum(np.searchsorted(keys, want), keys.size - 1)
            ok = (keys[pos] == want) & (cell_seqs > col_seq[cell_cols])
            vals[pos[ok]] = cell_vals[ok]
        return vals

    def materialise(self, structure: Optional[sp.csr_matrix] = None) -> sp.csr_matrix:
        """The table as CSR: on its own nonzero pattern, or on ``structure``'s cells."""
        cells = self.cell_arrays()
        P = self.pattern(cells) if structure is None else structure
        vals = self.values_at(P.indptr, P.indices, cells)
        out = sp.csr_matrix((vals, P.indices.copy(), P.indptr.copy()),
                            shape=(self.n_rows, self.n_cols))
        out.eliminate_zeros()
        return out


@dataclass
class RewardStatement:
    """An ``R:`` statement: the action, states and observation it names (None for '*'), what it
    gives (one value, a row over the observations or a matrix over (s', o)), its position in
    the file (``seq``) and its line."""

    seq: int
    action: Optional[int]
    start: Optional[int]
    end: Optional[int]
    obs: Optional[int]
    kind: str            # value | row (over o) | matrix (s' x o)
    payload: object
    line: int = 0

    def applies_to(self, action: int) -> bool:
        return self.action is None or self.action == action

    def write(self, layer: "Layers", o: int = 0) -> None:
        """Put this statement's R(., ., ., o) into ``layer`` (one observation's S x S' table)."""
        if self.kind == "value":
            if self.obs is None or self.obs == o:
                layer.set_cell(self.seq, self.start, self.end, self.payload)
        elif self.kind == "row":
            layer.set_cell(self.seq, self.start, self.end, float(self.payload[o]))
        else:
            layer.set_row(self.seq, self.start, "vec", self.payload[:, o].copy())

    @property
    def depends_on_observation(self) -> bool:
        if self.kind == "value":
            return self.obs is not None
        if self.kind == "row":
            return bool(np.any(self.payload != self.payload[0]))
        return bool(np.any(self.payload != self.payload[:, :1]))
