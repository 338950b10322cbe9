"""The quasi-static pushing model of a rotating slider, derived once from a `Scene`.

Units: a contact step's "force" is the slider's body-frame displacement over the step (v = f / b times
the step's duration), so the time step drops out and displacements stay O(1) inside the solver. The
rotation over a step is then kappa * (p x d) with kappa = b / b_theta = 1 / (c r_max)^2: the
ellipsoidal limit surface of the scene's damped joints (Scene.rot_damping).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lerobot_gcs_push.scene import Scene


def cross(u, v) -> float:
    return float(u[0] * v[1] - u[1] * v[0])


@dataclass(frozen=True)
class Face:
    index: int
    a: np.ndarray  # start vertex (slider frame)
    e: np.ndarray  # b - a: the contact point is a + lam * e, lam in [0, 1]
    n: np.ndarray  # outward unit normal
    t: np.ndarray  # unit tangent, along e
    # Where the finger may touch: a concave (reflex) end of the face keeps the finger a radius away, or it
    # would overlap the neighbouring face (the T's stem sides and bar undersides).
    lam_lo: float = 0.0
    lam_hi: float = 1.0

    @property
    def offset(self) -> float:
        """n . q on the face's line."""
        return float(self.n @ self.a)


@dataclass(frozen=True)
class PushModel:
    faces: tuple[Face, ...]
    kappa: float  # 1/m^2: rotation per unit torque-arm displacement
    mu: float
    finger_radius: float
    r_max: float
    symmetry: int  # the shape maps onto itself under rotations by 2 pi / symmetry
    convex: bool
    goal: tuple[float, float, float]
    reach: float  # slider centres stay within |x|, |y| <= reach
    finger_reach: float  # finger centre within this distance (inf-norm) of the slider centre, slider frame
    # A sticking contact moves along the face by -rolling_radius * dtheta (face_contact.py): the finger's
    # radius, or 0 for the model that holds the contact still (ContactPlanner(rolling=False)).
    rolling_radius: float = 0.0

    @classmethod
    def from_scene(cls, scene: Scene) -> PushModel:
        shape = scene.shape
        faces = []
        raw = shape.faces()
        edges = [np.asarray(b - a, float) for a, b, _ in raw]
        r = scene.finger_radius
        for i, (a, _, n) in enumerate(raw):
            e, length = edges[i], float(np.linalg.norm(edges[i]))
            concave_start = cross(edges[i - 1], e) < 0
            concave_end = cross(e, edges[(i + 1) % len(edges)]) < 0
            lo, hi = (r / length if concave_start else 0.0), (1 - r / length if concave_end else 1.0)
            faces.append(Face(i, np.asarray(a, float), e, np.asarray(n, float), e / length, lo, hi))
        b, b_theta = scene.box_damping, scene.rot_damping
        # The square is the only symmetric shape today; derived here, not a Scene field (see the report).
        symmetry = 4 if shape.name == "box" else 1
        convex = len(shape.parts) == 1
        return cls(
            faces=tuple(faces),
            kappa=b / b_theta,
            mu=scene.finger_box_friction,
            finger_radius=scene.finger_radius,
            r_max=shape.r_max,
            symmetry=symmetry,
            convex=convex,
            goal=(float(scene.goal[0]), float(scene.goal[1]), float(scene.goal_heading)),
            reach=scene.box_reach,
            finger_reach=2 * scene.finger_limit,  # any commanded finger, seen from any slider centre
            rolling_radius=scene.finger_radius,
        )

    def goal_heading_near(self, heading: float) -> float:
        """The goal heading among the shape's symmetric copies nearest to `heading`: a symmetric slider at
        goal + 2 pi k / symmetry covers the goal exactly, so no plan should turn further."""
        step = 2 * math.pi / self.symmetry
        g = self.goal[2]
        return g + step * round((heading - g) / step)


@dataclass(frozen=True)
class HeadingWindow:
    """Headings within half_width of mid: on the unit circle, exactly the half-plane u . (c, s) >= cos(h)
    (u the mid heading's direction), a linear cut that keeps the relaxation's headings off the disk's
    centre. Planning inside a window is a restriction of the problem: the certified bound is over the
    plans whose heading stays inside it."""

    mid: float
    half_width: float

    @classmethod
    def around(cls, start: float, goal: float, margin: float) -> HeadingWindow:
        half = abs(goal - start) / 2 + margin
        if not half < math.pi / 2:
            raise ValueError(f"a heading window of half-width {half:.3f} rad is no half-plane")
        return cls((start + goal) / 2, half)

    @property
    def u(self) -> np.ndarray:
        return np.array([math.cos(self.mid), math.sin(self.mid)])

    @property
    def cos_half(self) -> float:
        return math.cos(self.half_width)


# Widens every reachable window: keeps the cut valid against rounding in the angles it is computed from.
_REACH_SLACK = 1e-6


def reachable_windows(start: float, goal: float, steps: int, max_step: float) -> list[HeadingWindow | None]:
    """Where knot j of every plan can be, for j = 0..steps: a plan takes `steps` knot steps, each turning at
    most `max_step`, from the start heading to the goal heading, so knot j lies within j * max_step of the
    start and (steps - j) * max_step of the goal. Unlike a HeadingWindow around the start-to-goal arc this
    is no restriction: every plan's headings satisfy it, so the bound stays a bound of the whole problem.

    On the circle the two arcs meet in one arc unless they are long enough to meet again behind
    (steps * max_step >= 2 pi - |goal - start|); then knot j gets the shorter of the two arcs, which holds
    the meeting too. None where that arc is the whole circle."""
    goal = start + math.remainder(goal - start, 2 * math.pi)
    single = steps * max_step < 2 * math.pi - abs(goal - start)
    out = []
    for j in range(steps + 1):
        a, b = j * max_step, (steps - j) * max_step
        if single:
            lo, hi = max(start - a, goal - b), min(start + a, goal + b)
            mid, half = (lo + hi) / 2, max(hi - lo, 0.0) / 2
        else:
            mid, half = (start, a) if a <= b else (goal, b)
        half += _REACH_SLACK
        out.append(HeadingWindow(mid, half) if half < math.pi else None)
    return out
