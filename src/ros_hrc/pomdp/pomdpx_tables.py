"""POMDPX's variables and conditional tables (:mod:`ros_hrc.pomdp.pomdpx_reader` reads them),
and the row-wise Kronecker product that makes the flat tables of their factors.

A conditional table is dense (:class:`DenseTable`) up to a size and sparse beyond
(:class:`SparseTable`); both take the entries of a ``<Parameter>`` in order (later ones
override earlier ones) and give the rows, sums and cells the reader needs.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np
import scipy.sparse as sp


@dataclass
class Variable:
    """A declared variable: its name, role, index among the variables of its kind and values."""

    name: str
    role: str                 # prev | curr | obs | action | reward
    index: int                # which state / observation variable
    values: List[str]
    lookup: Dict[str, int] = field(default_factory=dict)

    @property
    def size(self) -> int:
        return len(self.values)


class DenseTable:
    """A conditional table as a numpy array (axes: parents, then the variable)."""

    def __init__(self, shape: Tuple[int, ...]) -> None:
        self.shape = shape
        self.data = np.zeros(shape)
        self._csr: Optional[sp.csr_matrix] = None

    def assign(self, selection: List[Optional[int]], values: np.ndarray) -> None:
        """Write ``values`` at the cells ``selection`` picks (an index per axis, None: all)."""
        index = tuple(slice(None) if s is None else s for s in selection)
        self.data[index] = values
        self._csr = None

    def finish(self) -> None:
        """Called once every entry is assigned (nothing to do for a dense table)."""

    def last_axis_sums(self) -> np.ndarray:
        """The sum over the variable's values for each parent configuration."""
        return self.data.reshape(-1, self.shape[-1]).sum(axis=1)

    def rows(self, configs: np.ndarray) -> sp.csr_matrix:
        """The rows (over the variable's values) of these parent configurations."""
        # Rows picked from the table as CSR: picked from the dense table they would make an
        # (S, values) array, 100 MB for 50,000 states of a 250-valued variable.
        if self._csr is None:
            self._csr = sp.csr_matrix(self.data.reshape(-1, self.shape[-1]))
        return self._csr[configs]

    def row_nonzeros(self) -> np.ndarray:
        """Non-zeros of each parent configuration's row."""
        return np.count_nonzero(self.data.reshape(-1, self.shape[-1]), axis=1)

    def gather(self, flat: np.ndarray) -> np.ndarray:
        """The cells at these flat (row-major) indices."""
        return self.data.ravel()[flat]


class SparseTable:
    """A conditional table too large to be dense: the cells entries wrote, last write wins."""

    def __init__(self, shape: Tuple[int, ...]) -> None:
        self.shape = shape
        self.strides = np.array([int(np.prod(shape[k + 1:])) for k in range(len(shape))],
                                dtype=np.int64)
        self.parts: List[Tuple[np.ndarray, np.ndarray]] = []
        self.flat = np.empty(0, dtype=np.int64)
        self.vals = np.empty(0)

    def assign(self, selection: List[Optional[int]], values: np.ndarray) -> None:
        free = [k for k, s in enumerate(selection) if s is None]
        flat = np.int64(sum(int(s) * int(self.strides[k]) for k, s in enumerate(selection)
                            if s is not None))
        grids = np.zeros([self.shape[k] for k in free], dtype=np.int64) + flat
        for pos, k in enumerate(free):
            shape = [1] * len(free)
            shape[pos] = self.shape[k]
            axis = np.arange(self.shape[k], dtype=np.int64) * self.strides[k]
            grids = grids + axis.reshape(shape)
        values = np.broadcast_to(values, grids.shape)
        self.parts.append((grids.ravel(), np.array(values, dtype=float).ravel()))

    def finish(self) -> None:
        if not self.parts:
            return
        flat = np.concatenate([p[0] for p in self.parts])[::-1]
        vals = np.concatenate([p[1] for p in self.parts])[::-1]
        self.flat, first = np.unique(flat, return_index=True)   # first in reverse = last written
        self.vals = vals[first]
        self.parts = []

    def last_axis_sums(self) -> np.ndarray:
        n_cfg = int(np.prod(self.shape[:-1]))
        return np.bincount(self.flat // self.shape[-1], weights=self.vals, minlength=n_cfg)

    def row_nonzeros(self) -> np.ndarray:
        """Non-zeros of each parent configuration's row."""
        n_cfg = int(np.prod(self.shape[:-1]))
        return np.bincount(self.flat // self.shape[-1], weights=self.vals != 0,
                           minlength=n_cfg).astype(np.int64)

    def rows(self, configs: np.ndarray) -> sp.csr_matrix:
        n = self.shape[-1]
        starts = np.searchsorted(self.flat, configs.astype(np.int64) * n)
        ends = np.searchsorted(self.flat, (configs.astype(np.int64) + 1) * n)
        counts = ends - starts
        indptr = np.concatenate([[0], np.cumsum(counts)])
        offsets = np.arange(indptr[-1]) - np.repeat(indptr[:-1], counts)
        pos = np.repeat(starts, counts) + offsets
        return sp.csr_matrix((self.vals[pos], self.flat[pos] % n, indptr),
                             shape=(configs.size, n))

    def gather(self, flat: np.ndarray) -> np.ndarray:
        pos = np.searchsorted(self.flat, flat)
        pos = np.minimum(pos, max(self.flat.size - 1, 0))
        out = np.zeros(flat.size)
        if self.flat.size:
            hit = self.flat[pos] == flat
            out[hit] = self.vals[pos[hit]]
        return out


@dataclass
class Factor:
    """One <CondProb> or <Func>: its variable, parents and table."""
    var: Optional[Variable]       # None for a reward <Func>
    parents: List[Variable]
    table: object
    line: Optional[int]
    label: str

    @property
    def axes(self) -> List[Variable]:
        return self.parents + ([self.var] if self.var is not None else [])


def rowwise_kron(A: sp.csr_matrix, B: sp.csr_matrix) -> sp.csr_matrix:
    """Row-wise Kronecker product: ``C[s, i * n + j] = A[s, i] * B[s, j]`` (sparse, no loops).

    For factored transitions: if row s of A is P(x'|s) and of B is P(y'|s), row s of C is the
    joint P(x', y'|s) with x the more significant variable.
    """
    A = sp.csr_matrix(A)
    B = sp.csr_matrix(B)
    A.eliminate_zeros()
    B.eliminate_zeros()
    A.sort_indices()
    B.sort_indices()
    S, n = A.shape[0], B.shape[1]
    na, nb = np.diff(A.indptr), np.diff(B.indptr)
    row_of_a = np.repeat(np.arange(S), na)
    reps = nb[row_of_a]
    a_pos = np.repeat(np.arange(A.nnz), reps)
    group_start = np.repeat(np.cumsum(reps) - reps, reps)
    b_pos = np.repeat(B.indptr[row_of_a], reps) + (np.arange(int(reps.sum())) - group_start)
    data = A.data[a_pos] * B.data[b_pos]
    cols = A.indices[a_pos].astype(np.int64) * n + B.indices[b_pos]
    indptr = np.concatenate([[0], np.cumsum(na * nb)])
    out = sp.csr_matrix((data, cols, indptr), shape=(S, A.shape[1] * n))
    out.eliminate_zeros()
    return out
