"""A cvxpy program's conic data taken once, then handed to Clarabel directly, query after query.

cvxpy's per-solve work (applying parameters through its chain, building the solver's inputs, unpacking
the solution) costs more than Clarabel's solve on programs this small. The programs here are DPP, so
their conic data  min c.x + d  s.t.  A x + s = b, s in (zero, nonneg, second-order cones)  is affine in
the parameters: `ParametricConic` evaluates it once at theta = 0 and once per unit vector of theta, and
a query is a matrix-vector product. `Conic.fix` then removes variables with known values (the edges a
query forbids, or all edges off a path): the subproblem is the same program, only smaller.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import clarabel
import cvxpy as cp
import numpy as np
import scipy.sparse as sp
from cvxpy import settings as cvxpy_settings

FEAS_TOL = 1e-9  # a row left without variables must hold on its constant to this


class Infeasible(Exception):
    """Fixing variables left a constant row that does not hold."""


@dataclass
class ConicSolution:
    status: str  # Clarabel's: "Solved", "AlmostSolved", "PrimalInfeasible", ...
    value: float  # inf unless solved
    x: np.ndarray  # every variable of the program `fix` was called on (fixed ones at their values)
    solve_time_s: float

    @property
    def solved(self) -> bool:
        return self.status in ("Solved", "AlmostSolved")


@dataclass
class Conic:
    """min c.x + d s.t. A x + s = b, s in zero^nz x nonneg^nn x SOC(soc[0]) x SOC(soc[1]) ..."""

    A: sp.csc_matrix
    b: np.ndarray
    c: np.ndarray
    d: float
    zero: int
    nonneg: int
    soc: list[int]
    free: np.ndarray | None = None  # columns of the original program (None: this is it)
    fixed: np.ndarray | None = None  # the original program's x with the fixed values filled in

    def fix(self, values: np.ndarray, fixing: Fixing | None = None) -> Conic:
        """The program with the variables whose entry in `values` is not NaN fixed to it. `fixing`: the
        same variables' `Fixing`, computed once for programs of this sparsity pattern."""
        return (fixing or Fixing(self, ~np.isnan(values))).apply(self, values)

    def solve(self) -> ConicSolution:
        """Clarabel on this data, at tolerances 1e-7 (cvxpy passes its defaults, 1e-8). A new solver each
        time: reusing one through Clarabel's `update` saves its setup (a fifth of a relaxation's time),
        but where the relaxation's optimum is not unique its flows then differ from a fresh solve's (by
        up to 0.26 on 120 queries), and a plan would depend on what the planner solved before."""
        n = len(self.c)
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        # 1e-7 instead of Clarabel's 1e-8: plans 6 % faster, every reference cost unchanged to 1e-6.
        settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = 1e-7
        solver = clarabel.DefaultSolver(sp.csc_matrix((n, n)), self.c, self.A, self.b, self.cones(), settings)
        sol = solver.solve()
        status = str(sol.status)
        x = np.asarray(sol.x, float)
        full = x if self.free is None else _scatter(self.fixed, self.free, x)
        solved = status in ("Solved", "AlmostSolved")
        value = float(sol.obj_val) + self.d if solved else np.inf
        return ConicSolution(status, value, full, float(sol.solve_time))

    def cones(self) -> list:
        cones = [clarabel.ZeroConeT(self.zero)] if self.zero else []
        if self.nonneg:
            cones.append(clarabel.NonnegativeConeT(self.nonneg))
        return cones + [clarabel.SecondOrderConeT(k) for k in self.soc]


class Fixing:
    """Which rows and matrix entries survive fixing the variables in `fixed` (a mask over x), worked
    out from a program's sparsity pattern alone, so that it serves every program with that pattern
    (every query, for one set of dropped edges or one path): applying it is a gather of A's entries.
    Rows left without variables are dropped, after `apply` checks their constants against the cone
    (raising `Infeasible`); a second-order cone keeps its rows while any of them has a variable."""

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
        )


def _scatter(base: np.ndarray, where: np.ndarray, values: np.ndarray) -> np.ndarray:
    out = base.copy()
    out[where] = values
    return out


class ParametricConic:
    """The conic data of a DPP cvxpy `problem` as an affine function of its `params` (stacked in that
    order into theta), and where each of `variables` sits in x. `solver` (Clarabel or SCIP, which read
    the same conic form) only decides which cvxpy chain produces it."""

    def __init__(
        self,
        problem: cp.Problem,
        params: list[cp.Parameter],
        variables: dict[str, cp.Variable],
        solver: str = cp.CLARABEL,
    ):
        data, _, _ = problem.get_problem_data(solver, ignore_dpp=False)
        self.boolean = np.zeros(data["param_prob"].x.size, bool)  # binary variables, as a mask over x
        self.boolean[list(data.get(cvxpy_settings.BOOL_IDX, []))] = True
        prog, dims = data["param_prob"], data["dims"]
        if dims.exp or dims.psd or dims.p3d or prog.P is not None:
            raise ValueError("only zero, nonnegative and second-order cones with a linear objective")
        self.zero, self.nonneg, self.soc = int(dims.zero), int(dims.nonneg), [int(k) for k in dims.soc]
        self.columns = {
            name: slice(prog.var_id_to_col[v.id], prog.var_id_to_col[v.id] + v.size) for name, v in variables.items()
        }
        self.sizes = [p.size for p in params]
        probes = [np.zeros(sum(self.sizes))] + list(np.eye(sum(self.sizes)))
        c, d, A, b = zip(*(prog.apply_parameters(self._values(params, t), keep_zeros=True) for t in probes))
        self.shape = A[0].shape
        # One sparsity pattern for every theta: the union of the probes', in CSC order.
        coo = [a.tocoo() for a in A]
        keys = [a.col.astype(np.int64) * self.shape[0] + a.row for a in coo]
        pattern = np.unique(np.concatenate(keys))
        vals = np.zeros((len(pattern), len(probes)))
        for j, (k, a) in enumerate(zip(keys, coo)):
            np.add.at(vals[:, j], np.searchsorted(pattern, k), a.data)
        self.indices = (pattern % self.shape[0]).astype(np.int32)
        self.indptr = np.searchsorted(pattern // self.shape[0], np.arange(self.shape[1] + 1)).astype(np.int32)
        # Clarabel's convention is cvxpy's with A negated (ConicSolver.apply).
        self.A_map = _affine(-vals)
        self.b_map = _affine(np.stack(b, axis=1))
        self.c_map = _affine(np.stack(c, axis=1))
        self.d_map = _affine(np.array(d, float)[None])[0]

    _ARRAYS = ("boolean", "indices", "indptr", "A_map", "b_map", "c_map", "d_map")

    def save(self, path: Path) -> None:
        """Write to `path` (.npz) atomically: processes that load it meanwhile see the old file or this."""
        meta = {
            "zero": self.zero,
            "nonneg": self.nonneg,
            "soc": self.soc,
            "shape": list(self.shape),
            "sizes": self.sizes,
            "columns": {k: [v.start, v.stop] for k, v in self.columns.items()},
        }
        tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
        with open(tmp, "wb") as f:
            np.savez(f, meta=np.array(json.dumps(meta)), **{k: getattr(self, k) for k in self._ARRAYS})
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: Path) -> ParametricConic:
        out = cls.__new__(cls)
        with np.load(path) as f:
            for k in cls._ARRAYS:
                setattr(out, k, f[k])
            meta = json.loads(str(f["meta"]))
        out.zero, out.nonneg, out.soc, out.sizes = meta["zero"], meta["nonneg"], meta["soc"], meta["sizes"]
        out.shape = tuple(meta["shape"])
        out.columns = {k: slice(*v) for k, v in meta["columns"].items()}
        return out

    @staticmethod
    def _values(params, theta) -> dict:
        out, i = {}, 0
        for p in params:
            out[p.id] = theta[i : i + p.size].reshape(p.shape, order="F") if p.shape else theta[i]
            i += p.size
        return out

    def at(self, theta: np.ndarray) -> Conic:
        t = np.concatenate([[1.0], np.asarray(theta, float)])
        A = sp.csc_matrix((self.A_map @ t, self.indices, self.indptr), shape=self.shape)
        return Conic(A, self.b_map @ t, self.c_map @ t, float(self.d_map @ t), self.zero, self.nonneg, self.soc)


def _affine(probes: np.ndarray) -> np.ndarray:
    """Columns [f(0), f(e_1), ...] -> [f(0), f(e_1) - f(0), ...]: f(theta) = M @ [1, theta]."""
    out = probes.copy()
    out[:, 1:] -= probes[:, :1]
    return out
