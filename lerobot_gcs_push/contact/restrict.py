"""A `ContactPlanner`'s nonlinear programs: the rounding of its relaxation's flows into path restrictions with
their retries (`round_paths`), the baseline's one path (`baseline_plan`), the straight-line guess SNOPT starts
from, and the `Plan` a solved restriction gives. `planner` is the `ContactPlanner` (not imported here: it
imports this module); its settings are read at each call."""

from __future__ import annotations

import time

import numpy as np

from lerobot_gcs_push.contact.face_contact import finger_body
from lerobot_gcs_push.contact.graph import START
from lerobot_gcs_push.contact.non_collision import knots_of
from lerobot_gcs_push.contact.relaxation import RelaxationResult
from lerobot_gcs_push.contact.rounding import Path, Restriction, ranked_paths, round_relaxation, solve_restriction
from lerobot_gcs_push.contact.trace import trace
from lerobot_gcs_push.planning import Plan, PlanningError


def round_paths(planner, res: RelaxationResult, pose, q, goal, allow, window) -> tuple[Restriction | None, int, bool]:
    """(the best restriction solved or None, how many were tried, whether the fallback ran): the paths
    sampled from the relaxation's flows, then the retries from the straight-line guess."""
    best, tried = round_relaxation(
        planner.model,
        planner.graph,
        planner.regions,
        planner.rounding_forms,
        res,
        planner.knots,
        planner.per_region,
        pose,
        q,
        goal,
        planner.candidates,
        np.random.default_rng(planner.seed),
        window,
    )
    fallback = best is None
    # SNOPT from the straight-line guess finds another local optimum of the same path: tried on the best
    # sampled path (then on the paths of most flow) when line_guesses > 0. Off by default: on the bench's
    # 20 rotating-box starts, run side by side twice, it lowered the median gap 0.0874 -> 0.0851 for 55-65
    # ms of rounding (+20-28 % a plan). If every sampled path failed (the relaxation's values can mislead
    # SNOPT at the motion cone's edge), the paths of most flow from that guess, until one solves.
    if fallback:
        retry = ranked_paths(planner.graph, res, allow)[: planner.fallback_paths]
    elif planner.line_guesses > 1:  # every path enumerated only when more than the best is asked for
        ranked = ranked_paths(planner.graph, res, allow)
        retry = ([best.path] + [p for p in ranked if p != best.path])[: planner.line_guesses]
    else:
        retry = [best.path][: planner.line_guesses]  # [] when off
    for path in retry:
        r = planner._restrict(path, pose, q, goal, window)
        tried += 1
        if r.success and (best is None or r.cost < best.cost):
            best = r
        if fallback and best is not None:
            break
    return best, tried, fallback


def baseline_plan(planner, slider_pose, finger) -> Plan:
    """`ContactPlanner.baseline`: one push per layer from the face that looks away from the goal, reached by
    the shortest route, SNOPT from a straight-line guess."""
    pose, q, goal, allow = planner.query(slider_pose, finger)
    t0 = time.perf_counter()
    c, s = np.cos(pose[2]), np.sin(pose[2])
    u = goal[:2] - pose[:2]
    u = np.array([c * u[0] + s * u[1], -s * u[0] + c * u[1]])
    face = int(np.argmax([-(f.n @ u) for f in planner.model.faces]))
    graph = planner.baseline_graph
    options = [k for k, v in enumerate(graph.frees) if v.layer == START and allow[v.source] and v.target == face]
    start_free = min(options, key=lambda k: len(graph.frees[k].route))
    again = [
        min(
            (k for k, v in enumerate(graph.frees) if v.layer == layer and v.source == face and v.target == face),
            key=lambda k: len(graph.frees[k].route),
        )
        for layer in range(planner.layers - 1)
    ]
    path = Path((start_free, *again), tuple(graph.contact_index(layer, face) for layer in range(planner.layers)))
    r = planner._restrict(path, pose, q, goal, planner.window(pose, goal), graph, planner.baseline_forms)
    dt = time.perf_counter() - t0
    if not r.success:
        raise PlanningError("the baseline's SNOPT run found no feasible plan")
    return plan_of(planner, "baseline", r, pose, goal, None, dt, 1, {}, graph)


def restrict(planner, path: Path, pose, q, goal, window, graph=None, forms=None, guess=None) -> Restriction:
    """The path's restriction, SNOPT from `guess` (contact modes' values, free modes' points: the
    straight-line guess by default), on the planner's graph by default."""
    graph = graph or planner.graph
    guess_c, guess_q = guess or straight_line_guess(planner, graph, path, pose, q, goal)
    return solve_restriction(
        planner.model,
        graph,
        planner.regions,
        forms or planner.rounding_forms,
        path,
        planner.knots,
        planner.per_region,
        pose,
        q,
        goal,
        guess_c,
        guess_q,
        window,
    )


def straight_line_guess(planner, graph, path: Path, pose, q, goal):
    """Poses interpolated from start to goal over the path's contact knots, each push mid-face, the
    finger straight from where it is to the next contact point (penetrating, if it must: SNOPT fixes it)."""
    model, knots = planner.model, planner.knots
    n_c = len(path.contacts)
    w = np.linspace(0.0, 1.0, n_c * (knots - 1) + 1)
    traj = np.array([pose[i] + w * (goal[i] - pose[i]) for i in range(3)]).T
    contacts, frees, finger = [], [], np.asarray(q, float)
    for m, (fi, ci) in enumerate(zip(path.frees, path.contacts)):
        face = model.faces[graph.contacts[ci].face]
        seg = traj[m * (knots - 1) : (m + 1) * (knots - 1) + 1]
        fn, ft = [], []
        for k in range(knots - 1):
            dw = seg[k + 1, :2] - seg[k, :2]
            ck, sk = np.cos(seg[k, 2]), np.sin(seg[k, 2])
            db = np.array([ck * dw[0] + sk * dw[1], -sk * dw[0] + ck * dw[1]])
            fn.append(-(face.n @ db))
            ft.append(face.t @ db)
        contacts.append(
            {
                "lam": 0.5,
                "c": np.cos(seg[:, 2]),
                "s": np.sin(seg[:, 2]),
                "fn": np.array(fn),
                "ft": np.array(ft),
                "x": seg[:, 0],
                "y": seg[:, 1],
            }
        )
        n_q = knots_of(graph.frees[fi].route, planner.per_region)
        end = finger_body(face, model, 0.5)
        frees.append(finger[None, :] + np.linspace(0, 1, n_q)[:, None] * (end - finger)[None, :])
        finger = end
    return contacts, frees


def plan_of(planner, method, r: Restriction, pose, goal, bound, dt, tried, extra, graph=None) -> Plan:
    """The `Plan` of a solved restriction (`trace`), on the planner's graph by default."""
    poses, fingers, kinds, modes, pushes = trace(planner.model, graph or planner.graph, r, pose)
    return Plan(
        method=method,
        cost=r.cost,
        lower_bound=bound,
        solve_time_s=dt,
        modes=modes,
        slider_poses=poses,
        finger_path=fingers,
        segment_kinds=kinds,
        goal=goal,
        pushes=pushes,
        free_knots=list(r.frees),
        candidates=tried,
        extra=extra,
    )
