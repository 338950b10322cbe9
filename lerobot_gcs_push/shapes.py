"""Slider shapes as data: the planar outline of what the finger pushes, in the slider's own frame.

A shape is a union of convex polygons with disjoint interiors (the T is not convex; its bar and stem
are), with the frame's origin at the centre of mass, since the quasi-static limit surface is written
about it: the area centroid for a uniform slider; gym-pusht's T puts its centre of gravity at the plain
mean of its two boxes' centroids instead (`pivot="parts"`). The planner reads faces and convex parts
from here, the sim builds its collision geometry from the parts, and the env scores coverage with
`coverage`; none repeats a dimension.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np


@dataclass(frozen=True)
class SliderShape:
    name: str
    # Convex polygons, vertices counter-clockwise, in metres, about the shape's pivot.
    parts: tuple[tuple[tuple[float, float], ...], ...]
    # The union's outline, counter-clockwise: its edges are the faces a finger can push on.
    outline: tuple[tuple[float, float], ...]
    # The frame's origin, the centre of mass: "centroid" (of the area) or "parts" (the plain mean of the
    # convex parts' centroids, gym-pusht's T's centre of gravity).
    pivot: str = "centroid"

    def __post_init__(self) -> None:
        for i, part in enumerate(self.parts):
            if _signed_area(np.asarray(part)) <= 0:
                raise ValueError(f"{self.name}: part {i} must be counter-clockwise with positive area")
        if _signed_area(np.asarray(self.outline)) <= 0:
            raise ValueError(f"{self.name}: the outline must be counter-clockwise")
        if abs(self.area - abs(_signed_area(np.asarray(self.outline)))) > 1e-9:
            raise ValueError(f"{self.name}: the parts' areas do not add up to the outline's")
        if self.pivot not in PIVOTS:
            raise ValueError(f"{self.name}: unknown pivot {self.pivot!r}: choose one of {PIVOTS}")
        origin = self.centroid if self.pivot == "centroid" else _parts_mean(self.parts)
        if np.linalg.norm(origin) > 1e-9:
            raise ValueError(f"{self.name}: the frame's origin must be the {self.pivot}'s, got {origin}")

    @cached_property
    def area(self) -> float:
        return float(sum(_signed_area(np.asarray(p)) for p in self.parts))

    @cached_property
    def centroid(self) -> np.ndarray:
        return sum(_signed_area(np.asarray(p)) * _polygon_centroid(np.asarray(p)) for p in self.parts) / self.area

    @cached_property
    def r_max(self) -> float:
        """The farthest outline point from the pivot (the limit surface's torque scale)."""
        return float(np.max(np.linalg.norm(np.asarray(self.outline), axis=1)))

    @cached_property
    def polar_moment(self) -> float:
        """Integral of |r|^2 over the area (per unit density): the rotational inertia's shape factor."""
        return float(sum(_polar_moment(np.asarray(p)) for p in self.parts))

    def faces(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Each outline edge as (start, end, outward unit normal), counter-clockwise."""
        v = np.asarray(self.outline, float)
        out = []
        for a, b in zip(v, np.roll(v, -1, axis=0)):
            d = b - a
            out.append((a, b, np.array([d[1], -d[0]]) / np.linalg.norm(d)))
        return out

    def world_parts(self, pose) -> list[np.ndarray]:
        """The convex parts placed at pose = (x, y, heading)."""
        x, y, th = (float(v) for v in pose)
        rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
        return [np.asarray(p, float) @ rot.T + (x, y) for p in self.parts]

    def world_outline(self, pose) -> np.ndarray:
        x, y, th = (float(v) for v in pose)
        rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
        return np.asarray(self.outline, float) @ rot.T + (x, y)

    def coverage(self, pose, goal_pose) -> float:
        """Area of the slider at `pose` inside the goal outline, over the shape's area (gym-pusht's rule).
        Exact: the parts' interiors are disjoint, so the overlap is the sum over pairs of convex parts."""
        a, b = self.world_parts(pose), self.world_parts(goal_pose)
        return float(sum(_convex_intersection_area(p, q) for p in a for q in b) / self.area)

    def signed_distance(self, pose, point) -> float:
        """Signed distance from a point to the slider at `pose` (negative inside)."""
        x, y, th = (float(v) for v in pose)
        c, s = math.cos(th), math.sin(th)
        d = np.asarray(point, float) - (x, y)
        local = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
        v = np.asarray(self.outline, float)
        edges = np.roll(v, -1, axis=0) - v
        t = np.clip(np.einsum("ij,ij->i", local - v, edges) / np.einsum("ij,ij->i", edges, edges), 0.0, 1.0)
        dist = float(np.min(np.linalg.norm(local - (v + t[:, None] * edges), axis=1)))
        return -dist if _inside(self.parts, local) else dist


def square(size: float) -> SliderShape:
    h = size / 2
    corners = ((-h, -h), (h, -h), (h, h), (-h, h))
    return SliderShape("box", (corners,), corners)


def tee(bar_length: float, pivot: str = "centroid") -> SliderShape:
    """gym-pusht's T in proportion: the bar is bar_length x bar_length/4, the stem bar_length/4 wide and
    3/4 bar_length long, hanging from the bar's middle. `pivot` places the frame's origin (SliderShape)."""
    w, L = bar_length / 4, bar_length
    # Built with the stem's foot at y = 0, then shifted so the pivot is the origin.
    bar = np.array([(-L / 2, L - w), (L / 2, L - w), (L / 2, L), (-L / 2, L)])
    stem = np.array([(-w / 2, 0.0), (w / 2, 0.0), (w / 2, L - w), (-w / 2, L - w)])
    outline = np.array(
        [
            (-w / 2, 0.0),
            (w / 2, 0.0),
            (w / 2, L - w),
            (L / 2, L - w),
            (L / 2, L),
            (-L / 2, L),
            (-L / 2, L - w),
            (-w / 2, L - w),
        ]
    )
    areas = np.array([_signed_area(bar), _signed_area(stem)])
    if pivot == "parts":
        c = (_polygon_centroid(bar) + _polygon_centroid(stem)) / 2
    else:
        c = (areas[0] * _polygon_centroid(bar) + areas[1] * _polygon_centroid(stem)) / areas.sum()

    def shifted(poly):
        return tuple((float(x), float(y)) for x, y in poly - c)

    return SliderShape("tee", (shifted(bar), shifted(stem)), shifted(outline), pivot)


PIVOTS = ("centroid", "parts")


def _parts_mean(parts) -> np.ndarray:
    return sum(_polygon_centroid(np.asarray(p)) for p in parts) / len(parts)


def _signed_area(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    return float(0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _polygon_centroid(p: np.ndarray) -> np.ndarray:
    x, y = p[:, 0], p[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    a = 0.5 * cross.sum()
    return np.array([np.sum((x + np.roll(x, -1)) * cross), np.sum((y + np.roll(y, -1)) * cross)]) / (6 * a)


def _polar_moment(p: np.ndarray) -> float:
    x, y = p[:, 0], p[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    ixx = np.sum(cross * (y * y + y * yn + yn * yn)) / 12
    iyy = np.sum(cross * (x * x + x * xn + xn * xn)) / 12
    return float(ixx + iyy)


def _inside(parts, point) -> bool:
    for part in parts:
        v = np.asarray(part, float)
        e = np.roll(v, -1, axis=0) - v
        r = point - v
        if np.all(e[:, 0] * r[:, 1] - e[:, 1] * r[:, 0] >= -1e-12):
            return True
    return False


def _convex_intersection_area(p: np.ndarray, q: np.ndarray) -> float:
    """Sutherland-Hodgman: clip convex p by each edge of convex q (both counter-clockwise)."""
    out = list(p)
    for a, b in zip(q, np.roll(q, -1, axis=0)):
        if not out:
            return 0.0
        e = b - a
        side = [e[0] * (v[1] - a[1]) - e[1] * (v[0] - a[0]) for v in out]
        clipped = []
        for i, v in enumerate(out):
            j = (i + 1) % len(out)
            if side[i] >= 0:
                clipped.append(v)
            if (side[i] >= 0) != (side[j] >= 0):
                t = side[i] / (side[i] - side[j])
                clipped.append(v + t * (out[j] - v))
        out = clipped
    return abs(_signed_area(np.asarray(out))) if len(out) >= 3 else 0.0
