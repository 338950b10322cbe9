"""A cvxpy program's conic data taken once, then handed to Clarabel directly, query after query.

cvxpy's per-solve work (applying parameters through its chain, building the solver's inputs, unpacking
the solution) costs more than Clarabel's solve on programs this small, and its compile of the contact
planner's semidefinite programs takes a minute or more. The programs here are DPP, so their conic data
min c.x + d  s.t.  A x + s = b, s in (zero, nonneg, second-order, PSD cones)  is affine in the
parameters: `ParametricConic` evaluates it once at theta = 0 and once per unit vector of theta, keeps
the parts that move (sparse: most entries do not), and a query is a sparse matrix-vector product
(`at`, a `program.Conic`). cache.py keeps the data on disk.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import cvxpy as cp
import numpy as np
import scipy.sparse as sp
from cvxpy import settings as cvxpy_settings
from cvxpy.lin_ops.lin_op import CONSTANT_ID

from lerobot_gcs_push.conic.program import Conic


class ParametricConic:
    """The conic data of a DPP cvxpy `problem` as an affine function of its `params` (stacked in that
    order into theta), and where each of `variables` sits in x. `solver` (Clarabel or SCIP, which read
    the same conic form) only decides which cvxpy chain produces it. `unpack`: variables whose values
    are read back from x (`values`) although cvxpy reformulates them (a symmetric matrix is stored as
    its upper triangle): their entries as indices into x, found by unpacking x = 1, 2, ... through
    cvxpy's own chain once."""

    def __init__(
        self,
        problem: cp.Problem,
        params: list[cp.Parameter],
        variables: dict[str, cp.Variable],
        solver: str = cp.CLARABEL,
        unpack: list[cp.Variable] = (),
    ):
        if not problem.is_dpp():  # cvxpy would bake the parameters' values in: every query the same program
            raise ValueError("the program is not DPP: its conic data is not affine in its parameters")
        data, chain, inverse = problem.get_problem_data(solver, ignore_dpp=False)
        unknown = set(data["param_prob"].param_id_to_col) - {p.id for p in params} - {CONSTANT_ID}
        if unknown:  # a symmetric or diagonal Parameter is replaced by a reduced one: declare it plain
            raise ValueError("cvxpy reformulated some parameters (symmetric=True or diag=True?): declare them plain")
        self.boolean = np.zeros(data["param_prob"].x.size, bool)  # binary variables, as a mask over x
        self.boolean[list(data.get(cvxpy_settings.BOOL_IDX, []))] = True
        prog, dims = data["param_prob"], data["dims"]
        if dims.exp or dims.p3d or prog.P is not None:
            raise ValueError("only zero, nonnegative, second-order and PSD cones with a linear objective")
        self.zero, self.nonneg, self.soc = int(dims.zero), int(dims.nonneg), [int(k) for k in dims.soc]
        self.psd = [int(k) for k in dims.psd]
        self.columns = {
            name: slice(prog.var_id_to_col[v.id], prog.var_id_to_col[v.id] + v.size) for name, v in variables.items()
        }
        self.sizes = [p.size for p in params]
        p = sum(self.sizes)
        # One probe at a time (the contact planner's programs have ~100 parameters and ~10^5 entries):
        # the entries that differ from theta = 0, sparse.
        c0, d0, A0, b0 = prog.apply_parameters(self._values(params, np.zeros(p)), keep_zeros=True)
        self.shape = A0.shape
        keys0, vals0 = _entries(A0)
        dA, db, dc, dd = [], [], [], []
        for j in range(p):
            c, d, A, b = prog.apply_parameters(self._values(params, np.eye(1, p, j)[0]), keep_zeros=True)
            dA.append(_difference(keys0, vals0, *_entries(A)))
            db.append(_sparse_column(np.asarray(b, float) - b0))
            dc.append(_sparse_column(np.asarray(c, float) - c0))
            dd.append(float(d) - float(d0))
        # One sparsity pattern for every theta: theta = 0's and every probe's changes, in CSC order.
        pattern = np.unique(np.concatenate([keys0] + [k for k, _ in dA]))
        self.indices = (pattern % self.shape[0]).astype(np.int32)
        self.indptr = np.searchsorted(pattern // self.shape[0], np.arange(self.shape[1] + 1)).astype(np.int32)
        # Clarabel's convention is cvxpy's with A negated (ConicSolver.apply).
        self.A_map = _affine_map(
            len(pattern),
            [(np.searchsorted(pattern, keys0), -vals0)],
            [(np.searchsorted(pattern, k), -v) for k, v in dA],
        )
        self.b_map = _affine_map(self.shape[0], [_sparse_column(np.asarray(b0, float))], db)
        self.c_map = _affine_map(self.shape[1], [_sparse_column(np.asarray(c0, float))], dc)
        self.d_map = np.array([float(d0), *dd])
        self.unpacked = _unpacked(problem, chain, inverse, self.shape[1], list(unpack))

    _ARRAYS = ("boolean", "indices", "indptr", "d_map")
    _SPARSE = ("A_map", "b_map", "c_map")

    @property
    def n(self) -> int:
        """The number of the program's variables (x's length)."""
        return self.shape[1]

    def values(self, x: np.ndarray) -> list[np.ndarray]:
        """The `unpack` variables' values at x, in their order and shapes (entries cvxpy dropped: 0)."""
        padded = np.r_[x, 0.0]
        return [padded[idx] for idx in self.unpacked]

    def save(self, path: Path) -> None:
        """Write to `path` (.npz) atomically: processes that load it meanwhile see the old file or this."""
        meta = {
            "zero": self.zero,
            "nonneg": self.nonneg,
            "soc": self.soc,
            "psd": self.psd,
            "shape": list(self.shape),
            "sizes": self.sizes,
            "columns": {k: [v.start, v.stop] for k, v in self.columns.items()},
            "unpacked": [list(u.shape) for u in self.unpacked],
        }
        arrays = {k: getattr(self, k) for k in self._ARRAYS}
        for k in self._SPARSE:
            m = getattr(self, k)
            arrays.update({f"{k}_data": m.data, f"{k}_indices": m.indices, f"{k}_indptr": m.indptr})
            meta[f"{k}_shape"] = list(m.shape)
        if self.unpacked:
            arrays["unpacked"] = np.concatenate([u.ravel() for u in self.unpacked])
        with tempfile.NamedTemporaryFile(dir=path.parent, prefix=f"{path.name}.", suffix=".tmp", delete=False) as f:
            tmp = Path(f.name)
            try:
                np.savez(f, meta=np.array(json.dumps(meta)), **arrays)
            except BaseException:
                f.close()
                tmp.unlink(missing_ok=True)
                raise
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: Path) -> ParametricConic:
        out = cls.__new__(cls)
        with np.load(path) as f:
            meta = json.loads(str(f["meta"]))
            for k in cls._ARRAYS:
                setattr(out, k, f[k])
            for k in cls._SPARSE:
                parts = (f[f"{k}_data"], f[f"{k}_indices"], f[f"{k}_indptr"])
                setattr(out, k, sp.csr_matrix(parts, shape=tuple(meta[f"{k}_shape"])))
            flat = f["unpacked"] if meta["unpacked"] else np.zeros(0, int)
        out.zero, out.nonneg, out.soc, out.sizes = meta["zero"], meta["nonneg"], meta["soc"], meta["sizes"]
        out.psd = meta["psd"]
        out.shape = tuple(meta["shape"])
        out.columns = {k: slice(*v) for k, v in meta["columns"].items()}
        out.unpacked, i = [], 0
        for shape in meta["unpacked"]:
            size = int(np.prod(shape))
            out.unpacked.append(flat[i : i + size].reshape(shape))
            i += size
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
        return Conic(
            A, self.b_map @ t, self.c_map @ t, float(self.d_map @ t), self.zero, self.nonneg, self.soc, psd=self.psd
        )


def _entries(A) -> tuple[np.ndarray, np.ndarray]:
    """A sparse matrix's entries as (column-major keys, values), sorted by key."""
    coo = A.tocoo()
    keys = coo.col.astype(np.int64) * A.shape[0] + coo.row
    order = np.argsort(keys, kind="stable")
    return keys[order], np.asarray(coo.data, float)[order]


def _difference(keys0, vals0, keys, vals) -> tuple[np.ndarray, np.ndarray]:
    """The entries of (keys, vals) - (keys0, vals0) that are not zero."""
    if len(keys) == len(keys0) and np.array_equal(keys, keys0):
        diff, at = vals - vals0, keys0
    else:
        at = np.union1d(keys0, keys)
        diff = np.zeros(len(at))
        np.add.at(diff, np.searchsorted(at, keys), vals)
        np.add.at(diff, np.searchsorted(at, keys0), -vals0)
    nz = diff != 0
    return at[nz], diff[nz]


def _sparse_column(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    nz = np.flatnonzero(v)
    return nz, v[nz]


def _affine_map(rows: int, base: list[tuple], probes: list[tuple]) -> sp.csr_matrix:
    """[f(0), f(e_1) - f(0), ...] as a sparse (rows x 1 + len(probes)) matrix: f(theta) = M @ [1, theta]."""
    cols = base + probes
    r = np.concatenate([np.asarray(i, np.int64) for i, _ in cols])
    v = np.concatenate([np.asarray(x, float) for _, x in cols])
    c = np.concatenate([np.full(len(i), j) for j, (i, _) in enumerate(cols)])
    return sp.csr_matrix((v, (r, c)), shape=(rows, len(cols)))


class _Unit:
    """A solver result in Clarabel's shape whose x is 1, 2, ..., n: unpacked through cvxpy's chain, each
    variable's entries read off which entry of x they are."""

    def __init__(self, n: int):
        self.status, self.obj_val, self.solve_time, self.iterations = "Solved", 0.0, 0.0, 0
        self.x, self.z, self.s = np.arange(1.0, n + 1.0), None, None


def _unpacked(problem: cp.Problem, chain, inverse, n: int, variables: list) -> list[np.ndarray]:
    if not variables:
        return []
    saved = [v.value for v in problem.variables()]
    for inv in inverse:  # the solver's part reads the options of a solve that did not happen
        if hasattr(inv, "solver_options") and inv.solver_options is None:
            inv.solver_options = {}
    problem.unpack_results(_Unit(n), chain, inverse)
    out = []
    for v in variables:
        val = np.zeros(v.shape) if v.value is None else np.asarray(v.value, float)
        idx = np.rint(val).astype(np.int64) - 1
        if np.any(np.abs(val - (idx + 1)) > 1e-9) or np.any(idx < -1) or np.any(idx >= n):
            raise ValueError(f"{v.name()} is not a selection of the conic variables: cannot unpack it directly")
        idx[idx < 0] = n  # not in the program: reads the padding 0
        out.append(idx)
    for v, val in zip(problem.variables(), saved):
        v.value = val
    return out
