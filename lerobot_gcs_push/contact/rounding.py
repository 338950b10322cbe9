"""Rounding: paths sampled from the relaxation's flows, each path's restriction solved as a small
nonlinear program (SNOPT, warm-started from the relaxation's values), the best kept.

The restriction is also the baseline's program (`solve_restriction` with a heuristic guess): the only
difference between the two is where the mode sequence and the initial guess come from.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from lerobot_gcs_push.contact.face_contact import NlpFaceContact, StepForms
from lerobot_gcs_push.contact.graph import ContactGraph
from lerobot_gcs_push.contact.model import PushModel
from lerobot_gcs_push.contact.non_collision import NlpNonCollision, Region
from lerobot_gcs_push.contact.relaxation import RelaxationResult, pose_vector
from lerobot_gcs_push.planning.flow_walk import walk


@dataclass(frozen=True)
class Path:
    """A mode sequence: free, contact, free, contact, ... (graph indices), ending in a contact."""

    frees: tuple[int, ...]
    contacts: tuple[int, ...]


@dataclass
class Restriction:
    success: bool
    cost: float
    path: Path
    contacts: list[dict]
    frees: list[np.ndarray]
    solve_time_s: float


def sample_paths(graph: ContactGraph, res: RelaxationResult, count: int, rng: np.random.Generator) -> list[Path]:
    """The greedy path (largest flow at each branch) first, then paths drawn with probability
    proportional to flow, without repeats."""
    out: list[Path] = []
    tries = 0
    while len(out) < count and tries < 4 * count:
        p = _walk(graph, res, None if not out and tries == 0 else rng)
        tries += 1
        if p is not None and p not in out:
            out.append(p)
    return out


def ranked_paths(graph: ContactGraph, res: RelaxationResult, allow) -> list[Path]:
    """Every path of the graph from an allowed start, the ones carrying most relaxed flow first: the
    rounding's last resort when the sampled paths' restrictions all fail."""
    out: list[tuple[float, Path]] = []

    def extend(frees, contacts, score):
        c = contacts[-1]
        out.append((score + res.target_flow[c], Path(tuple(frees), tuple(contacts))))
        for f in graph.out_of(c):
            n = graph.successor(f)
            extend(frees + [f], contacts + [n], score + res.free_flow[f] + res.contact_flow[n])

    for f in graph.starts():
        if allow[graph.frees[f].source]:
            n = graph.successor(f)
            extend([f], [n], res.free_flow[f] + res.contact_flow[n])
    out.sort(key=lambda t: -t[0])
    return [p for _, p in out]


def _walk(graph: ContactGraph, res: RelaxationResult, rng) -> Path | None:
    """`flow_walk.walk` over the contact graph: the start's edges are the free modes out of it, a contact
    vertex's are the free modes out of it and then its edge to the target."""

    def out(v):
        if v == "start":
            return [(f, graph.successor(f), res.free_flow[f]) for f in graph.starts()]
        edges = [(f, graph.successor(f), res.free_flow[f]) for f in graph.out_of(v)]
        return [*edges, ("end", "target", res.target_flow[v])]

    edges = walk(out, "start", "target", rng)
    if edges is None:
        return None
    frees = edges[:-1]
    return Path(tuple(frees), tuple(graph.successor(f) for f in frees))


def relaxation_guess(res: RelaxationResult, path: Path) -> tuple[list[dict], list[np.ndarray]]:
    """The relaxation's values along `path` (each vertex's divided by its flow): the restriction's initial
    guess for the contact modes and the free modes."""
    return (
        [res.contact_guess(c, via) for c, via in zip(path.contacts, path.frees)],
        [res.free_guess(f)["q"] for f in path.frees],
    )


def solve_restriction(
    model: PushModel,
    graph: ContactGraph,
    regions: list[Region],
    forms: dict[tuple[int, int], StepForms],
    path: Path,
    knots: int,
    per_region: int,
    start_pose,
    start_q,
    goal_pose,
    guess_contacts: list[dict],
    guess_frees: list[np.ndarray],
    window=None,
) -> Restriction:
    from pydrake.solvers import MathematicalProgram, SnoptSolver, SolverOptions

    t0 = time.perf_counter()
    prog = MathematicalProgram()
    cs = []
    for k, c in enumerate(path.contacts):
        v = graph.contacts[c]
        cs.append(NlpFaceContact(prog, model.faces[v.face], model, forms[v.face, v.piece], knots, f"c{k}", window))
    fs = [
        NlpNonCollision(prog, model, regions, graph.frees[f].route, per_region, f"f{k}")
        for k, f in enumerate(path.frees)
    ]
    start, goal = pose_vector(start_pose), pose_vector(goal_pose)
    for k, (fr, ct) in enumerate(zip(fs, cs)):
        first = np.asarray(start_q, float) if k == 0 else cs[k - 1].finger(True)
        _equal(prog, fr.q[0], first)
        _equal(prog, fr.q[-1], ct.finger(False))
        _equal(prog, ct.pose(False), start if k == 0 else cs[k - 1].pose(True))
    _equal(prog, cs[-1].pose(True), goal)
    for ct, g in zip(cs, guess_contacts):
        ct.set_guess(prog, g)
    for fr, g in zip(fs, guess_frees):
        fr.set_guess(prog, g)
    opts = SolverOptions()
    sid = SnoptSolver.id()
    opts.SetOption(sid, "Major feasibility tolerance", 1e-7)
    opts.SetOption(sid, "Major optimality tolerance", 1e-6)
    opts.SetOption(sid, "Major iterations limit", 500)
    result = SnoptSolver().Solve(prog, None, opts)
    dt = time.perf_counter() - t0
    ok = result.is_success()
    return Restriction(
        success=ok,
        cost=float(result.get_optimal_cost()) if ok else float("inf"),
        path=path,
        contacts=[ct.read(result) for ct in cs],
        frees=[fr.read(result) for fr in fs],
        solve_time_s=dt,
    )


def _equal(prog, a, b) -> None:
    for u, v in zip(a, b):
        prog.AddLinearEqualityConstraint(u - v, 0.0)


def round_relaxation(
    model,
    graph,
    regions,
    forms,
    res: RelaxationResult,
    knots,
    per_region,
    start_pose,
    start_q,
    goal_pose,
    count,
    rng,
    window=None,
) -> tuple[Restriction | None, int]:
    best, tried = None, 0
    for path in sample_paths(graph, res, count, rng):
        tried += 1
        r = solve_restriction(
            model,
            graph,
            regions,
            forms,
            path,
            knots,
            per_region,
            start_pose,
            start_q,
            goal_pose,
            *relaxation_guess(res, path),
            window,
        )
        if r.success and (best is None or r.cost < best.cost):
            best = r
    return best, tried


__all__ = ["Path", "Restriction", "relaxation_guess", "round_relaxation", "sample_paths", "solve_restriction"]
