"""Where `PlanExpert` seeks a plan from a state (`find_plan`): to the goal; from a far finger's staging point;
to waypoints part of the way there; from points round the staging circle, the finger going round; and, near
the goal, a correction first (`fine_plan`). With the geometry of the finger's ways round the slider they take."""

from __future__ import annotations

import math
import time

import numpy as np

from lerobot_gcs_push.planning.interface import Planner, PlanningError
from lerobot_gcs_push.planning.plan import FREE, PUSH, RETREAT, Plan
from lerobot_gcs_push.scene import wrap_angle

# Shares of the way from the slider to its goal where a plan is sought when none reaches the goal. A T by
# gym-pusht's wall, half a turn from its goal (seed 2027's sixth start), had no plan to the goal, one
# halfway in 15 s and one a quarter of the way in 10 s.
WAYPOINTS = (0.5, 0.25)
# A finger far from the slider. Where no plan was found on gym-pusht (seed 4700's 33rd start, seeds 9763 and
# 9777: fingers 2.2-3.6 m from the T), SNOPT found every sampled path's restriction infeasible; from 1.6 m
# off the T, on any of six sides, seed 9777's T planned, and seed 9763's (2.9 rad from its goal) planned a
# quarter of the way, which from the finger's own place it had not. So where no plan is found from a far
# finger, the finger first goes straight at the slider, to this far beyond the reach of both (the slider's
# radius about its pivot plus the finger's), and the plans, to the goal and then to the waypoints, start there.
# `stage_first` plans from there first: on gym-pusht, where the agent starts anywhere, the first plan from the
# agent's own place failed on 5 of 12 resets (seeds 10340-10351: every sampled restriction infeasible, 21-25
# tried); on 24 more (seeds 10500-10523), alternated with the agent's own place first, it took 20 % less CPU
# (173.8 against 216.3 s, 58 plans against 70) and 9 % fewer frames (88.8 against 98.0 a start), all 24 both ways.
STAGE_MARGIN_M = 0.1
# Where no plan is found from a far finger's staging point, nor from its own place, nor to a waypoint, the
# staging point turned about the slider by these angles (rad), in turn: from the staging circle's other side
# the rounding meets other restrictions. Seed 11340's sixth start on gym-pusht (the T 2.8 rad from its goal,
# the agent just beyond the circle) planned from none of those; from the points 60, 180, 240 and 300 degrees
# round, it planned (120 degrees: not), and the agent never moved for 30 s without them.
RING_TURNS = tuple(np.deg2rad([60.0, -60.0, 120.0, -120.0, 180.0]))
# A plan detours when its slider goes farther from the goal than DETOUR_RATIO times, and DETOUR_MARGIN (m +
# rad x r_max) beyond, where it is now. Near the goal the rounding's plans from the finger's own place do: the
# Drake T's four failures of seed 5155 came within 0.1-0.3 of the goal and were pushed up to 2.5 away (from
# 0.12 off, every restriction that solved took the T 0.25-0.76 away). From points round the staging circle
# the same states planned without a detour, and cheaper (0.40 against 0.80, 0.25 against 3.83, 0.35 against
# 3.32): so a detouring plan is replaced by the first that does not, from the circle at the finger's own
# bearing and then turned by RING_TURNS. Far from the goal, plans wind out and back by less than the margins.
DETOUR_RATIO, DETOUR_MARGIN = 1.5, 0.2
# The finger goes round the circle in steps of at most this (rad): each chord comes no nearer the pivot than
# cos(step / 2) = 0.991 of the circle's radius, so it keeps clear of the slider by STAGE_MARGIN_M less 0.9 %
# of that radius (0.086 m on gym-pusht's T).
RING_STEP = np.deg2rad(15.0)
# A correction's finger goes to this far off its contact point along the face's normal (m) before the
# approach, and backs off this far after its push, so that the next correction's way starts clear of the slider.
FINE_STANDOFF_M, FINE_RETREAT_M = 0.15, 0.1


def find_plan(
    planner: Planner, slider, finger, *, stage_first: bool, replace_detours: bool, fine_within: float
) -> Plan:
    """A plan to the goal; where none is found, from the staging point the finger goes to first when it
    is far (`staging_point`), to the goal and then to waypoints part of the way there (the next replan
    goes on from one). With `stage_first`, a far finger's plan starts at the staging point first. Where
    none of those is found, from points round the staging circle (`RING_TURNS`), the finger going round.
    Within `fine_within` of the goal, a correction comes first (`fine_plan`). `PlanExpert`'s options."""
    goal = planner.goal_of(slider)
    if fine_within > 0 and planner.distance(slider, goal) < fine_within:
        plan = fine_plan(planner, slider, finger)
        if plan is not None:
            return plan
    staged = staging_point(planner.scene, slider, finger)
    if staged is not None:  # inside a free piece, as any start the planner takes
        staged = planner.plannable(slider, staged)[1]
    waypoints = [slider + share * (goal - slider) for share in WAYPOINTS]
    to_goal = [finger] if staged is None else [staged, finger] if stage_first else [finger, staged]
    tries = [(start, None) for start in to_goal] + [(finger if staged is None else staged, w) for w in waypoints]
    failure = None
    for start, target in tries:
        try:
            plan = planner.plan(slider, start, target)
        except PlanningError as err:
            failure = err
            continue
        if replace_detours and start is finger and target is None and detours(planner, slider, plan):
            # From the circle at the finger's own bearing (the finger going straight out), then round.
            centre = np.asarray(slider, float)[:2]
            radius = staging_radius(planner.scene)
            out = centre + (finger - centre) * radius / max(np.linalg.norm(finger - centre), 1e-9)
            turns = (0.0, *RING_TURNS)
            plan = plan_round(planner, slider, finger, out, turns, lambda p: not detours(planner, slider, p)) or plan
        return plan if start is finger else plan.preceded_by(finger)
    plan = None if staged is None else plan_round(planner, slider, finger, staged, RING_TURNS, accept=lambda p: True)
    if plan is None:
        raise failure
    return plan


def fine_plan(planner: Planner, slider, finger) -> Plan | None:
    """The first of the planner's corrections whose way there is clear: the finger goes to its
    standoff (`way`), in along the face's normal, pushes, and backs off. None where there is none.
    The planner is then an `interface.Corrects`: the slider kinds give a `fine_within` only to those."""
    scene = planner.scene
    slider, finger = np.asarray(slider, float), np.asarray(finger, float)
    t0 = time.perf_counter()
    for k in planner.corrections(slider):
        contact = k.fingers[0]
        out = k.normal_world(float(slider[2]))
        standoff = contact + FINE_STANDOFF_M * out
        path = way(scene, slider, finger, standoff, out)
        if path is None or not segment_clear(scene, slider, standoff, contact):
            continue
        end = k.fingers[-1] + FINE_RETREAT_M * k.normal_world(float(k.poses[-1][2]))
        fingers = np.vstack([path, contact, k.fingers[1:], end])
        rest = len(path) + 1
        poses = np.vstack([np.repeat(slider[None], rest, axis=0), k.poses[1:], k.poses[-1:]])
        kinds = [FREE] * len(path) + [PUSH] * (len(k.fingers) - 1) + [RETREAT]
        steps = np.diff(fingers, axis=0)
        return Plan(
            "fine",
            float(np.sum(steps * steps)),
            None,
            time.perf_counter() - t0,
            ["free", f"face_{k.face}", "free"],
            poses,
            fingers,
            kinds,
            planner.goal_of(slider),
            pushes=[{"face": k.face, "lam": k.lam, "normal": k.normal}],
            extra={"fine_error": k.error},
        )
    return None


def detours(planner: Planner, slider, plan: Plan) -> bool:
    """Whether the plan takes the slider farther from its goal than DETOUR_RATIO and DETOUR_MARGIN allow."""
    near = planner.distance(slider, plan.goal)
    farthest = max(planner.distance(pose, plan.goal) for pose in plan.slider_poses)
    return farthest > max(DETOUR_RATIO * near, near + DETOUR_MARGIN)


def plan_round(planner: Planner, slider, finger, on_circle, turns, accept) -> Plan | None:
    """The first plan `accept` takes from the staging circle: from the point `on_circle` turned by each of
    `turns` (rad) in turn, the finger going straight to `on_circle` (where that way is clear of the slider)
    and then round the circle; None if there is none."""
    finger = np.asarray(finger, float)
    if not all(clear(planner.scene, slider, finger + w * (on_circle - finger)) for w in np.linspace(0.0, 1.0, 25)):
        return None
    on_circle = planner.plannable(slider, on_circle)[1]
    for turn in turns:
        arc = ring_path(planner, slider, on_circle, turn)
        try:
            plan = planner.plan(slider, arc[-1])
        except PlanningError:
            continue
        if accept(plan):
            return plan.preceded_by(finger, *arc[:-1])
    return None


def ring_path(planner: Planner, slider, staged, turn: float) -> list[np.ndarray]:
    """The finger's way from the staging point round the staging circle by `turn` (rad): the staging
    point, the points between at most RING_STEP apart, and the end (made plannable)."""
    arc = _arc(np.asarray(slider, float)[:2], np.asarray(staged, float), turn)
    arc[-1] = planner.plannable(slider, arc[-1])[1]
    return arc


def staging_point(scene, slider, finger) -> np.ndarray | None:
    """The point on the line from the finger to the slider's centre STAGE_MARGIN_M beyond the reach of
    both (the slider's radius about its pivot plus the finger's), when the finger is farther than that;
    else None. The way there stays outside that circle, so it cannot touch the slider."""
    centre, finger = np.asarray(slider, float)[:2], np.asarray(finger, float)
    radius = staging_radius(scene)
    away = float(np.linalg.norm(finger - centre))
    return centre + (finger - centre) * (radius / away) if away > radius else None


def staging_radius(scene) -> float:
    """The staging circle's radius: the slider's reach about its pivot, the finger's, and STAGE_MARGIN_M."""
    return scene.shape.r_max + scene.finger_radius + STAGE_MARGIN_M


def way(scene, slider, finger, target, out) -> np.ndarray | None:
    """A way for the finger from `finger` to `target` clear of the slider: straight where that is
    clear, else out to the staging circle, round it, and in along `out` (the target's outward normal,
    whose ray meets the circle); None where no such way is clear."""
    if segment_clear(scene, slider, finger, target):
        return np.array([finger, target])
    centre, radius = slider[:2], staging_radius(scene)
    # Where the ray target + t out (t >= 0) meets the circle |p - centre| = radius.
    rel = target - centre
    b = float(rel @ out)
    t = -b + math.sqrt(max(b * b - (rel @ rel - radius**2), 0.0))
    inward = target + t * out
    away = finger - centre
    outward = centre + away * radius / max(float(np.linalg.norm(away)), 1e-9)
    if not (segment_clear(scene, slider, finger, outward) and segment_clear(scene, slider, inward, target)):
        return None
    turn = wrap_angle(math.atan2(*(inward - centre)[::-1]) - math.atan2(*(outward - centre)[::-1]))
    return np.array([finger, *_arc(centre, outward, turn), target])


def segment_clear(scene, slider, a, b) -> bool:
    return all(clear(scene, slider, a + w * (b - a)) for w in np.linspace(0.0, 1.0, 25))


def clear(scene, pose, point) -> bool:
    """Whether the finger at `point` is clear of the slider at `pose`."""
    return scene.shape.signed_distance(pose, point) >= scene.finger_radius - 1e-6


def _arc(centre: np.ndarray, start: np.ndarray, turn: float) -> list[np.ndarray]:
    """Points from `start` round `centre` by `turn` (rad), at most RING_STEP apart, both ends included."""
    d = start - centre
    steps = max(1, int(np.ceil(abs(turn) / RING_STEP)))
    out = []
    for a in np.linspace(0.0, turn, steps + 1):
        c, s = math.cos(a), math.sin(a)
        out.append(centre + np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]]))
    return out
