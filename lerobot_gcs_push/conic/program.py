"""Conic data as Clarabel reads it, min c.x + d  s.t.  A x + s = b, s in K, and the same program with some
variables fixed (`Conic.fix`): the edges a query forbids, or all edges off a path, dropped before the
solve, so that the subproblem is the same program, only smaller. `solve.solve` solves either."""

from __future__ import annotations

from dataclasses import dataclass, field

import clarabel
import numpy as np
import scipy.sparse as sp

FEAS_TOL = 1e-9  # a row left without variables must hold on its constant to this


class Infeasible(Exception):
    """Fixing variables left a constant row that does not hold."""


@dataclass
class Conic:
    """min c.x + d s.t. A x + s = b, s in zero^nz x nonneg^nn x SOC(soc[0]) x ... x PSD(psd[0]) x ...
    (a PSD cone's rows: the upper triangle of an n x n matrix, column by column, off-diagonals times
    sqrt 2, as cvxpy writes them for Clarabel)."""

    A: sp.csc_matrix
    b: np.ndarray
    c: np.ndarray
    d: float
    zero: int
    nonneg: int
    soc: list[int]
    free: np.ndarray | None = None  # columns of the original program (None: this is it)
    fixed: np.ndarray | None = None  # the original program's x with the fixed values filled in
    psd: list[int] = field(default_factory=list)

    def fix(self, values: np.ndarray, fixing: Fixing | None = None) -> Conic:
        """The program with the variables whose entry in `values` is not NaN fixed to it. `fixing`: the
        same variables' `Fixing`, computed once for programs of this sparsity pattern."""
        return (fixing or Fixing(self, ~np.isnan(values))).apply(self, values)

    def full(self, x: np.ndarray) -> np.ndarray:
        """The original program's x from this one's (the fixed variables at their values)."""
        return x if self.free is None else _scatter(self.fixed, self.free, x)

    def cones(self) -> list:
        cones = [clarabel.ZeroConeT(self.zero)] if self.zero else []
        if self.nonneg:
            cones.append(clarabel.NonnegativeConeT(self.nonneg))
        return (
            cones + [clarabel.SecondOrderConeT(k) for k in self.soc] + [clarabel.PSDTriangleConeT(k) for k in self.psd]
        )


class Fixing:
    """Which rows and matrix entries survive fixing the variables in `fixed` (a mask over x), worked
    out from a program's sparsity pattern alone, so that it serves every program with that pattern
    (every query, for one set of dropped edges or one path): applying it is a gather of A's entries.
    Rows left without variables are dropped, after `apply` checks their constants against the cone
    (raising `Infeasible`); a second-order cone keeps its rows while any of them has a variable, a PSD
    cone always."""

    def __init__(self, pattern: Conic, fixed: np.ndarray):
        A, m = pattern.A, pattern.A.shape[0]
        self.free = np.flatnonzero(~fixed)
        entry_col = np.repeat(np.arange(A.shape[1]), np.diff(A.indptr))
        kept = ~fixed[entry_col]
        used = np.bincount(A.indices[kept], minlength=m) > 0
        zero, nonneg = np.arange(pattern.zero), pattern.zero + np.arange(pattern.nonneg)
        self.empty_zero, self.empty_nonneg = zero[~used[zero]], nonneg[~used[nonneg]]
        rows, self.soc, self.empty_soc = [zero[used[zero]], nonneg[used[nonneg]]], [], []
        start = pattern.zero + pattern.nonneg
        for k in pattern.soc:
            cone = np.arange(start, start + k)
            start += k
            if used[cone].any():
                rows.append(cone)
                self.soc.append(k)
            else:
                self.empty_soc.append(cone)
        rows.append(np.arange(start, m))  # the PSD cones, kept whole
        self.psd = list(pattern.psd)
        self.rows = np.concatenate(rows).astype(int)
        self.zero, self.nonneg = len(rows[0]), len(rows[1])
        # Rows keep their order, so the surviving entries are already in CSC order.
        new_row = np.full(m, -1)
        new_row[self.rows] = np.arange(len(self.rows))
        self.gather = np.flatnonzero(kept & (new_row[A.indices] >= 0))
        self.indices = new_row[A.indices[self.gather]].astype(np.int32)
        counts = np.bincount(entry_col[self.gather], minlength=A.shape[1])[self.free]
        self.indptr = np.r_[0, np.cumsum(counts)].astype(np.int32)
        self.shape = (len(self.rows), len(self.free))

    def apply(self, conic: Conic, values: np.ndarray) -> Conic:
        v = np.where(np.isnan(values), 0.0, values)
        b = conic.b - conic.A @ v
        bad = np.any(np.abs(b[self.empty_zero]) > FEAS_TOL) or np.any(b[self.empty_nonneg] < -FEAS_TOL)
        if bad or any(b[c[0]] < np.linalg.norm(b[c[1:]]) - FEAS_TOL for c in self.empty_soc):
            raise Infeasible
        base_free = np.arange(len(conic.c)) if conic.free is None else conic.free
        base_fixed = values if conic.fixed is None else _scatter(conic.fixed, conic.free, values)
        return Conic(
            A=sp.csc_matrix((conic.A.data[self.gather], self.indices, self.indptr), shape=self.shape),
            b=b[self.rows],
            c=conic.c[self.free],
            d=conic.d + float(conic.c @ v),
            zero=self.zero,
            nonneg=self.nonneg,
            soc=self.soc,
            free=base_free[self.free],
            fixed=base_fixed,
            psd=self.psd,
        )


def _scatter(base: np.ndarray, where: np.ndarray, values: np.ndarray) -> np.ndarray:
    out = base.copy()
    out[where] = values
    return out
