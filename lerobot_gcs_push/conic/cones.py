"""The cone K = zero x nonneg x second-order x PSD of a `Conic` and its dual K* (K is self-dual but for the
zero cone, whose dual is the free cone): projections onto them, and a point's residuals measured by them."""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from lerobot_gcs_push.conic.program import Conic


def project(conic: Conic, v: np.ndarray, dual: bool) -> np.ndarray:
    """v projected onto K* (`dual`) or K: the zero cone's rows kept (K*) or set to 0 (K), nonnegative
    entries clipped, each second-order cone's block and each PSD block (the upper triangle column by
    column, off-diagonals times sqrt 2) projected exactly; cones of one size at once."""
    v = np.array(v, float)
    if not dual:
        v[: conic.zero] = 0.0
    i = conic.zero
    v[i : i + conic.nonneg] = np.maximum(v[i : i + conic.nonneg], 0.0)
    i += conic.nonneg
    cones = [("soc", k, k) for k in conic.soc] + [("psd", n, n * (n + 1) // 2) for n in conic.psd]
    starts = i + np.concatenate([[0], np.cumsum([length for _, _, length in cones])[:-1]]).astype(int)
    for cone in set(cones):
        at = np.array([s for s, c in zip(starts, cones) if c == cone], int)
        kind, n, length = cone
        idx = at[:, None] + np.arange(length)[None, :]
        v[idx] = _project_soc(v[idx]) if kind == "soc" else _project_psd(v[idx], n)
    return v


def project_dual(conic: Conic, z: np.ndarray) -> np.ndarray:
    """z projected onto the dual cone K*."""
    return project(conic, z, dual=True)


def dual_residual(conic: Conic, zp: np.ndarray) -> tuple[np.ndarray, float]:
    """(r, |r|_inf / max(1, |c|_inf)) with r = A'zp + c: how far zp (in K*) is from dual feasibility."""
    r = conic.c + conic.A.T @ zp
    scale = max(1.0, float(np.max(np.abs(conic.c), initial=0.0)))
    return r, float(np.max(np.abs(r), initial=0.0) / scale)


def primal_residual(conic: Conic, x: np.ndarray) -> float:
    """How far the slack s = b - A x lies outside K: |s - proj_K(s)|_inf / max(1, |b|_inf)."""
    s = conic.b - conic.A @ x
    scale = max(1.0, float(np.max(np.abs(conic.b), initial=0.0)))
    return float(np.max(np.abs(s - project(conic, s, dual=False)), initial=0.0) / scale)


def _project_soc(blocks: np.ndarray) -> np.ndarray:
    """Each row (t, v) onto {|v| <= t}: itself inside, the apex below the polar cone, else the boundary."""
    t, v = blocks[:, 0], blocks[:, 1:]
    norm = np.linalg.norm(v, axis=1)
    out = blocks.copy()
    outside = norm > t
    scale = np.maximum((t + norm) / 2, 0.0)
    out[outside, 0] = scale[outside]
    ratio = np.divide(scale, norm, out=np.zeros_like(norm), where=norm > 0)
    out[outside, 1:] = v[outside] * ratio[outside, None]
    return out


def _project_psd(blocks: np.ndarray, n: int) -> np.ndarray:
    """Each row (a packed n x n symmetric matrix) onto the PSD cone: negative eigenvalues set to 0."""
    rows, cols = _triangle(n)
    scale = np.where(rows != cols, np.sqrt(2), 1.0)
    m = np.zeros((len(blocks), n, n))
    m[:, rows, cols] = blocks / scale
    m[:, cols, rows] = blocks / scale
    w, u = np.linalg.eigh(m)
    bad = w[:, 0] < 0
    out = blocks.copy()
    if bad.any():
        fixed = np.einsum("bij,bj,bkj->bik", u[bad], np.maximum(w[bad], 0.0), u[bad])
        out[bad] = fixed[:, rows, cols] * scale
    return out


@functools.cache
def _triangle(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column of each entry of a packed n x n PSD cone: the upper triangle, column by column."""
    return tuple(np.array([(r, c) for c in range(n) for r in range(c + 1)]).T)
