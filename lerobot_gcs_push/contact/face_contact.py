"""A sticking face-contact mode: its constraints as quadratic forms, their semidefinite relaxation, and
the same constraints as a nonlinear program.

One knot step k couples the monomials of z_k = [1, lam_k, c_k, s_k, fn_k, ft_k, c_k+1, s_k+1, lam_k+1]
(lam: where on the face the finger touches; fn, ft: the body-frame displacement along -n and t; (c, s):
the heading on SO(2)) and the linear positions x_k, x_k+1, y_k, y_k+1. Sticking does not hold lam still:
the finger is a sphere that translates only, so it holds the slider's material point under it, and as the
slider turns by dtheta that point moves along the face by -finger_radius * dtheta (the finger rolls on
the face without turning). Fed a sim finger's path, the model follows the sim to 2 mm over 1.8 rad of
turning; with lam held still it was 18 cm off (experiments/rotation/README.md). Every constraint is
written once, here, as coefficients on those monomials (`StepForms`); the relaxation reads them against
a moment block M_k ~ z_k z_k^T, the nonlinear program against z_k itself. Only that reading differs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import combinations

import cvxpy as cp
import numpy as np

from lerobot_gcs_push.contact.model import Face, PushModel, cross

ONE, LAM, C0, S0, FN, FT, C1, S1, LAM1 = range(9)
BLOCK = 9
# Adjacent blocks share [1, lam, c, s] of their common knot: block k's (ONE, LAM1, C1, S1) is block k+1's
# (ONE, LAM, C0, S0).
SHARED_TAIL = [ONE, LAM1, C1, S1]
SHARED_HEAD = [ONE, LAM, C0, S0]
POSE_HEAD = [ONE, C0, S0]
POSE_TAIL = [ONE, C1, S1]
# rad per knot step: rules out flips and bounds the discretisation's error against the continuous model
# (sin(dtheta) for dtheta and the midpoint rotation; the planner defaults to 0.2, see planner.py).
MAX_STEP_ROTATION = 0.35


def _form(monomials: dict[tuple[int, int], float]) -> np.ndarray:
    """A symmetric BLOCK x BLOCK Q with <Q, z z^T> = sum coef * z_i z_j."""
    q = np.zeros((BLOCK, BLOCK))
    for (i, j), c in monomials.items():
        if i == j:
            q[i, i] += c
        else:
            q[i, j] += c / 2
            q[j, i] += c / 2
    return q


def _lin(g: dict[int, float]) -> np.ndarray:
    v = np.zeros(BLOCK)
    for i, c in g.items():
        v[i] += c
    return v


@dataclass
class StepForms:
    """The constraints of one knot step. Equalities: <Q, zz^T> + L . [x0, x1, y0, y1] = 0; inequalities
    <Q, zz^T> >= 0; `redundant` inequalities (RLT products) hold for every feasible z and only tighten
    the relaxation; the cost <Q_cost, zz^T>."""

    eq_q: np.ndarray  # (m, BLOCK, BLOCK)
    eq_l: np.ndarray  # (m, 4)
    ineq_q: np.ndarray  # (p, BLOCK, BLOCK)
    redundant_q: np.ndarray  # (r, BLOCK, BLOCK)
    cost_q: np.ndarray  # (BLOCK, BLOCK)
    linear: list[np.ndarray] = field(default_factory=list)  # valid first-order inequalities g . z >= 0
    lam_range: tuple[float, float] = (0.0, 1.0)


def step_forms(
    face: Face,
    model: PushModel,
    rot_weight: float,
    rlt: bool = True,
    lam_range: tuple[float, float] = (0.0, 1.0),
    max_step: float = MAX_STEP_ROTATION,
) -> StepForms:
    n, t, a, e, k = face.n, face.t, face.a, face.e, model.kappa
    eqs: list[tuple[dict, list[float]]] = []
    # Midpoint translation: x1 - x0 = (R_k + R_k+1)/2 d, d = -fn n + ft t in the slider frame.
    mx, my = {}, {}
    for c, s in ((C0, S0), (C1, S1)):
        mx[(c, FN)], mx[(c, FT)], mx[(s, FN)], mx[(s, FT)] = n[0] / 2, -t[0] / 2, -n[1] / 2, t[1] / 2
        my[(s, FN)], my[(s, FT)], my[(c, FN)], my[(c, FT)] = n[0] / 2, -t[0] / 2, n[1] / 2, -t[1] / 2
    eqs.append((mx, [-1.0, 1.0, 0.0, 0.0]))
    eqs.append((my, [0.0, 0.0, -1.0, 1.0]))
    # Rotation: sin(theta_k+1 - theta_k) = kappa * p x d, p = a + e (lam_k + lam_k+1) / 2 the step's
    # midpoint contact (e x t = 0).
    eqs.append(
        (
            {
                (C0, S1): 1.0,
                (S0, C1): -1.0,
                (ONE, FN): -k * cross(a, -n),
                (ONE, FT): -k * cross(a, t),
                (LAM, FN): -k * cross(e, -n) / 2,
                (LAM1, FN): -k * cross(e, -n) / 2,
            },
            [0.0] * 4,
        )
    )
    # Rolling: lam_k+1 = lam_k - (finger_radius / |e|) sin(theta_k+1 - theta_k).
    roll = model.rolling_radius / float(np.linalg.norm(e))
    eqs.append(({(ONE, LAM1): 1.0, (ONE, LAM): -1.0, (C0, S1): roll, (S0, C1): -roll}, [0.0] * 4))
    for c, s in ((C0, S0), (C1, S1)):
        eqs.append(({(c, c): 1.0, (s, s): 1.0, (ONE, ONE): -1.0}, [0.0] * 4))
    step = {(C0, C1): 1.0, (S0, S1): 1.0, (ONE, ONE): -math.cos(max_step)}
    # First-order inequalities: the friction cone, lam on the face, (c, s) in [-1, 1]^2.
    contact = [
        _lin({LAM: 1.0, ONE: -lam_range[0]}),
        _lin({ONE: lam_range[1], LAM: -1.0}),
        _lin({FN: 1.0}),
        _lin({FN: model.mu, FT: -1.0}),
        _lin({FN: model.mu, FT: 1.0}),
    ]
    trig = [_lin({ONE: 1.0, i: sgn}) for i in (C0, S0, C1, S1) for sgn in (1.0, -1.0)]
    # The step's last lam is the next step's first (and bounded, with its products, there); the last
    # step's needs its own bounds.
    ends = [_lin({LAM1: 1.0, ONE: -lam_range[0]}), _lin({ONE: lam_range[1], LAM1: -1.0})]
    ineqs = [_form(step)] + [_form({(ONE, i): g[i] for i in range(BLOCK) if g[i]}) for g in contact + ends]
    redundant = []
    if rlt:
        # Products of pairs of valid linear inequalities (RLT): the slack of the plain relaxation sits in
        # lam x fn (the torque arm), which these bound from both sides.
        for g, h in list(combinations(contact, 2)) + [(g, h) for g in trig for h in contact]:
            redundant.append(np.outer(g, h) / 2 + np.outer(h, g) / 2)
    chord_with = contact + trig  # the chord cut's RLT partners (see ArcParameters)
    cost = _form({(FN, FN): 1.0, (FT, FT): 1.0, (ONE, ONE): 2 * rot_weight, (C0, C1): -2 * rot_weight})
    cost += _form({(S0, S1): -2 * rot_weight})
    return StepForms(
        eq_q=np.array([_form(m) for m, _ in eqs]),
        eq_l=np.array([lin for _, lin in eqs]),
        ineq_q=np.array(ineqs),
        redundant_q=np.array(redundant).reshape(-1, BLOCK, BLOCK),
        cost_q=cost,
        linear=chord_with,
        lam_range=lam_range,
    )


def finger_body(face: Face, model: PushModel, lam):
    """The finger's centre in the slider frame while touching `face` at lam (linear in lam)."""
    base = face.a + model.finger_radius * face.n
    # Element by element: numpy's float-array times a symbolic scalar warns on object dtypes.
    return np.array([float(base[i]) + lam * float(face.e[i]) for i in range(2)])


# ---------------------------------------------------------------------------------------------------------
# The relaxation: one perspective copy (scale phi) of the mode, its moment blocks and linear positions.


class ArcParameters:
    """A chord cut u . (c, s) >= ch on one knot's heading, as cvxpy Parameters (set per query). Scalar
    parameters: indexing a vector parameter made cvxpy's compile of the T's graph several times slower."""

    def __init__(self):
        self.ux, self.uy, self.ch = cp.Parameter(), cp.Parameter(), cp.Parameter()

    def set(self, window) -> None:
        """A HeadingWindow, or None for no cut (u . (c, s) >= -1 holds on the whole unit disk)."""
        u, ch = (np.array([1.0, 0.0]), -1.0) if window is None else (window.u, window.cos_half)
        self.ux.value, self.uy.value, self.ch.value = float(u[0]), float(u[1]), float(ch)

    def row(self, m, c: int, s: int):
        """The moments of (u . (c, s) - ch) times each entry of z."""
        return self.ux * m[c, :] + self.uy * m[s, :] - self.ch * m[ONE, :]

    def of(self, cs, one):
        """u . cs - ch * one, for first moments cs of (c, s) and the moment `one` of 1."""
        return self.ux * cs[0] + self.uy * cs[1] - self.ch * one


class RelaxedFaceContact:
    """`cuts[k]`: the chord cuts of step k, each a pair (cut of knot k, cut of knot k + 1); each cut is
    multiplied by the step's valid linear inequalities (RLT), and the two cuts by each other."""

    def __init__(
        self,
        face: Face,
        model: PushModel,
        forms: StepForms,
        knots: int,
        phi,
        cuts: list[list[tuple[ArcParameters, ArcParameters]]] | None = None,
    ):
        self.face, self.model, self.knots, self.phi = face, model, knots, phi
        steps = knots - 1
        self.blocks = [cp.Variable((BLOCK, BLOCK), symmetric=True) for _ in range(steps)]
        self.x = cp.Variable(knots)
        self.y = cp.Variable(knots)
        self.cut_rows = []  # (variable, the moments it stands for): a lifted point sets one from the other
        cons = []
        reach = model.reach
        cons += [self.x <= reach * phi, self.x >= -reach * phi, self.y <= reach * phi, self.y >= -reach * phi]
        eq_a = forms.eq_q.reshape(len(forms.eq_q), -1)
        in_a = np.concatenate([forms.ineq_q, forms.redundant_q]).reshape(-1, BLOCK * BLOCK)
        cost = 0
        for k, m in enumerate(self.blocks):
            v = cp.vec(m, order="F")
            pos = cp.hstack([self.x[k], self.x[k + 1], self.y[k], self.y[k + 1]])
            cons += [m >> 0, m[ONE, ONE] == phi, eq_a @ v + forms.eq_l @ pos == 0, in_a @ v >= 0]
            cost = cost + cp.sum(cp.multiply(forms.cost_q, m))
            g = np.array(forms.linear)
            for first, second in cuts[k] if cuts else ():
                # Each cut's row of moments as a variable of its own, so that its products with the valid
                # bounds, and with the other knot's cut, carry no parameters: cvxpy compiles them fast.
                rows = []
                for arc, (c, s) in ((first, (C0, S0)), (second, (C1, S1))):
                    row = cp.Variable(BLOCK)
                    self.cut_rows.append((row, arc.row(m, c, s)))
                    cons += [row == self.cut_rows[-1][1], row[ONE] >= 0, g @ row >= 0]
                    rows.append(row)
                # (u0 . cs_k - ch0)(u1 . cs_k+1 - ch1) >= 0: both knots inside their windows.
                cons.append(second.of(rows[0][[C1, S1]], rows[0][ONE]) >= 0)
            if k:
                prev = self.blocks[k - 1]
                cons.append(prev[np.ix_(SHARED_TAIL, SHARED_TAIL)] == m[np.ix_(SHARED_HEAD, SHARED_HEAD)])
        self.constraints = cons
        self.cost = cost

    # The interface to neighbouring vertices, each a perspective (phi-scaled) quantity.
    def pose(self, end: bool):
        m, k = (self.blocks[-1], -1) if end else (self.blocks[0], 0)
        c, s = (C1, S1) if end else (C0, S0)
        return cp.hstack([self.x[k], self.y[k], m[ONE, c], m[ONE, s]])

    def pose_moments(self, end: bool):
        m = self.blocks[-1] if end else self.blocks[0]
        idx = POSE_TAIL if end else POSE_HEAD
        return m[np.ix_(idx, idx)]

    def lam(self, end: bool):
        return self.blocks[-1][ONE, LAM1] if end else self.blocks[0][ONE, LAM]

    def finger(self, end: bool):
        """The finger's centre (slider frame, perspective) as the mode begins or ends."""
        f = self.face
        return self.phi * (f.a + self.model.finger_radius * f.n) + self.lam(end) * f.e

    def values(self, phi_value: float) -> dict:
        """The copy's values divided by its flow: an initial guess for the nonlinear program."""
        w = max(phi_value, 1e-9)
        c = [b.value[ONE, C0] / w for b in self.blocks] + [self.blocks[-1].value[ONE, C1] / w]
        s = [b.value[ONE, S0] / w for b in self.blocks] + [self.blocks[-1].value[ONE, S1] / w]
        return {
            "lam": np.array([b.value[ONE, LAM] / w for b in self.blocks] + [self.blocks[-1].value[ONE, LAM1] / w]),
            "c": np.array(c),
            "s": np.array(s),
            "fn": np.array([b.value[ONE, FN] / w for b in self.blocks]),
            "ft": np.array([b.value[ONE, FT] / w for b in self.blocks]),
            "x": self.x.value / w,
            "y": self.y.value / w,
        }


# ---------------------------------------------------------------------------------------------------------
# The nonlinear program: the same forms read against the decision variables (pydrake, lazily imported).


class NlpFaceContact:
    def __init__(self, prog, face: Face, model: PushModel, forms: StepForms, knots: int, tag: str, window=None):
        self.face, self.model, self.knots, self.lam_range = face, model, knots, forms.lam_range
        self.lam = prog.NewContinuousVariables(knots, f"{tag}_lam")
        self.c = prog.NewContinuousVariables(knots, f"{tag}_c")
        self.s = prog.NewContinuousVariables(knots, f"{tag}_s")
        self.fn = prog.NewContinuousVariables(knots - 1, f"{tag}_fn")
        self.ft = prog.NewContinuousVariables(knots - 1, f"{tag}_ft")
        self.x = prog.NewContinuousVariables(knots, f"{tag}_x")
        self.y = prog.NewContinuousVariables(knots, f"{tag}_y")
        prog.AddBoundingBoxConstraint(*forms.lam_range, self.lam)  # every knot's
        prog.AddBoundingBoxConstraint(-model.reach, model.reach, self.x)
        prog.AddBoundingBoxConstraint(-model.reach, model.reach, self.y)
        prog.AddBoundingBoxConstraint(-1.0, 1.0, self.c)
        prog.AddBoundingBoxConstraint(-1.0, 1.0, self.s)
        prog.AddBoundingBoxConstraint(0.0, np.inf, self.fn)
        if window is not None:
            u = window.u
            for k in range(knots):
                prog.AddLinearConstraint(u[0] * self.c[k] + u[1] * self.s[k] >= window.cos_half)
        self.cost = 0
        for k in range(knots - 1):
            z = [1.0, self.lam[k], self.c[k], self.s[k], self.fn[k], self.ft[k], self.c[k + 1], self.s[k + 1]]
            z = np.array(z + [self.lam[k + 1]])
            pos = np.array([self.x[k], self.x[k + 1], self.y[k], self.y[k + 1]])
            for q, lin in zip(forms.eq_q, forms.eq_l):
                prog.AddConstraint(_quadratic(q, z) + _dot(lin, pos) == 0)
            for q in forms.ineq_q:
                prog.AddConstraint(_quadratic(q, z) >= 0)
            self.cost = self.cost + _quadratic(forms.cost_q, z)
        prog.AddCost(self.cost)

    def pose(self, end: bool):
        k = -1 if end else 0
        return [self.x[k], self.y[k], self.c[k], self.s[k]]

    def finger(self, end: bool):
        return finger_body(self.face, self.model, self.lam[-1 if end else 0])

    def set_guess(self, prog, guess: dict) -> None:
        c, s = np.asarray(guess["c"], float), np.asarray(guess["s"], float)
        norm = np.maximum(np.hypot(c, s), 1e-9)  # the relaxation's headings lie inside the unit disk
        prog.SetInitialGuess(self.c, c / norm)
        prog.SetInitialGuess(self.s, s / norm)
        lam = np.broadcast_to(np.asarray(guess["lam"], float), (self.knots,))  # a baseline's guess is one lam
        prog.SetInitialGuess(self.lam, np.clip(lam, *self.lam_range))
        prog.SetInitialGuess(self.fn, np.maximum(guess["fn"], 0.0))
        prog.SetInitialGuess(self.ft, guess["ft"])
        prog.SetInitialGuess(self.x, guess["x"])
        prog.SetInitialGuess(self.y, guess["y"])

    def read(self, result) -> dict:
        return {
            "face": self.face.index,
            "lam": result.GetSolution(self.lam),
            "c": result.GetSolution(self.c),
            "s": result.GetSolution(self.s),
            "fn": result.GetSolution(self.fn),
            "ft": result.GetSolution(self.ft),
            "x": result.GetSolution(self.x),
            "y": result.GetSolution(self.y),
        }


def _quadratic(q: np.ndarray, z) -> object:
    """z^T Q z over Q's nonzero entries (z[0] is the constant 1)."""
    out = 0
    for i, j in zip(*np.nonzero(np.triu(q))):
        coef = q[i, j] if i == j else 2 * q[i, j]
        out = out + coef * (z[i] * z[j] if i and j else z[i] if j == 0 else z[j] if i == 0 else 1.0)
    return out


def _dot(v: np.ndarray, x) -> object:
    out = 0
    for i in np.nonzero(v)[0]:
        out = out + v[i] * x[i]
    return out
