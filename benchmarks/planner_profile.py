"""Where a plan's time goes, stage by stage, and what the MICP's settings do, one by one.

    python -m benchmarks.planner_profile [--n 40] [--micp_n 20]

Relaxation + rounding, per query (medians over the queries, milliseconds): building the query, setting
theta in the conic data (`ParametricConic.at`), dropping the forbidden edges (`Conic.fix`), Clarabel on
the relaxation, path sampling (rounding), the candidates' restrictions (fixing each path, then one
stacked Clarabel call), tracing the plan. Beside them, in the same loop, what the planner did before
(cvxpy's `solve` on the compiled program, and a compiled cvxpy restriction per path, compile excluded)
so the ratios come from one run. (Tried and dropped: the candidates' restrictions stacked into one
block-diagonal Clarabel call, 15.3 ms against 14.3 ms one by one, 40 queries x 3, interleaved.)

MICP: building SCIP's model from the conic data against SCIP's search, cvxpy's SCIP interface on the
same program, and SCIP settings one at a time (each: median, p95, and how many optima differ from the
default's; a setting that changes an optimum is wrong, however fast).
"""

from __future__ import annotations

import time

import numpy as np

from lerobot_gcs_push.box_gcs import GcsPlanner
from lerobot_gcs_push.box_gcs.restriction import RestrictionCache
from lerobot_gcs_push.box_gcs.rounding import candidate_paths
from lerobot_gcs_push.box_gcs.trace import trace
from lerobot_gcs_push.conic.solve import solve
from lerobot_gcs_push.scene import Scene, sample_initial_conditions

STAGES = ("query", "theta", "drop_edges", "clarabel_relaxation", "rounding", "restrictions", "trace")
# (name, ScipMicp.solve keyword arguments); "start" and "cutoff" come from the rounded plan.
MICP_VARIANTS = [
    ("default", {}),
    ("start: rounded path as a partial solution", {"start": True}),
    ("cutoff: rounded cost + 1e-4 as objective limit", {"cutoff": True}),
    ("separating off", {"params": {"separating/maxrounds": 0, "separating/maxroundsroot": 0}}),
    ("nonlinear: assume convex", {"params": {"constraints/nonlinear/assumeconvex": True}}),
    ("heuristics: rens off", {"params": {"heuristics/rens/freq": -1}}),
    ("presolving off", {"params": {"presolving/maxrounds": 0}}),
]


def _ms(x) -> float:
    return float(np.median(x) * 1e3)


def _seed_rng(planner, q):
    return np.random.default_rng([planner.seed, *np.frombuffer(np.r_[q.src, q.goal].tobytes(), np.uint32)])


def profile_relaxation(planner: GcsPlanner, ics) -> dict:
    conic, graph = planner.conic, planner.graph
    prog = planner.program("relaxation")
    cvxpy_restrictions = RestrictionCache(graph)
    stages = {k: [] for k in (*STAGES, "total", "cvxpy_relaxation", "cvxpy_restrictions")}
    candidates = []
    for ic in ics:
        t = [time.perf_counter()]
        q = planner.query(ic.box, ic.finger)
        t.append(time.perf_counter())
        data = conic.at(q.src, q.goal, q.allowed)
        t.append(time.perf_counter())
        key = ("relaxation", tuple(np.flatnonzero(q.allowed <= 0)))
        values = conic.cols.fixed(key[1], {})
        dropped = data.fix(values, conic.fixing(data, key, values))
        t.append(time.perf_counter())
        sol = solve(dropped)
        t.append(time.perf_counter())
        flows = np.clip(sol.x[conic.cols.y], 0, 1)
        paths = candidate_paths(graph, flows, _seed_rng(planner, q), planner.rounding_trials)
        t.append(time.perf_counter())
        best = min((conic.restrict(data, p, q.src, q.goal) for p in paths), key=lambda s: s.rank())
        t.append(time.perf_counter())
        trace(planner.scene, graph, best.vertices, best.points, np.array(ic.box), q.src[2:])
        t.append(time.perf_counter())
        for k, name in enumerate(STAGES):
            stages[name].append(t[k + 1] - t[k])
        stages["total"].append(t[-1] - t[0])
        candidates.append(len(paths))
        prog.set_query(q.src, q.goal, q.allowed)
        t0 = time.perf_counter()
        prog.solve()
        stages["cvxpy_relaxation"].append(time.perf_counter() - t0)
        for p in paths:  # compile outside the timing: the cached state of the old planner
            cvxpy_restrictions.solve(p, q.src, q.goal)
        t0 = time.perf_counter()
        for p in paths:
            cvxpy_restrictions.solve(p, q.src, q.goal)
        stages["cvxpy_restrictions"].append(time.perf_counter() - t0)
    out = {f"{k}_median_ms": _ms(v) for k, v in stages.items()}
    out["total_p95_ms"] = float(np.percentile(stages["total"], 95) * 1e3)
    out["candidates_median"] = float(np.median(candidates))
    return out


def profile_micp(planner: GcsPlanner, ics) -> dict:
    micp, conic = planner.micp, planner.conic
    prog = planner.program("micp")
    names = ["cvxpy SCIP interface"] + [name for name, _ in MICP_VARIANTS]
    times = {n: [] for n in names}
    values = {n: [] for n in names}
    build = []
    for k, ic in enumerate(ics):
        q = planner.query(ic.box, ic.finger)
        relaxed = conic.relax(q.src, q.goal, q.allowed)
        paths = candidate_paths(planner.graph, relaxed.flows.flows, _seed_rng(planner, q), planner.rounding_trials)
        rounded = min((conic.restrict(relaxed.conic, p, q.src, q.goal) for p in paths), key=lambda s: s.rank())
        for j in range(len(names)):  # rotating order: load hits every variant alike
            name = names[(k + j) % len(names)]
            t0 = time.perf_counter()
            if name == "cvxpy SCIP interface":
                prog.set_query(q.src, q.goal, q.allowed)
                value = prog.solve().value
            else:
                kw = dict(dict(MICP_VARIANTS)[name])
                if kw.pop("start", False):
                    kw["start"] = rounded.edges
                if kw.pop("cutoff", False):
                    kw["cutoff"] = rounded.cost * (1 + 1e-4) + 1e-6
                try:
                    value = micp.solve(q.src, q.goal, q.allowed, **kw).value
                except Exception:  # a setting that breaks the solve counts as a wrong optimum
                    value = np.nan
                if name == "default":
                    build.append(micp.build_time_s)
            times[name].append(time.perf_counter() - t0)
            values[name].append(value)
    ref = np.array(values["default"])
    out = {"micp_model_build_median_ms": _ms(build)}
    for n in names:
        v = np.array(values[n])
        out[f"{n}: median_s"] = float(np.median(times[n]))
        out[f"{n}: p95_s"] = float(np.percentile(times[n], 95))
        out[f"{n}: optima_differing"] = float(np.sum(~(np.abs(v - ref) <= 1e-4 * np.maximum(1, ref))))
    return out


def run(n: int = 40, micp_n: int = 20, seed: int = 0) -> dict:
    scene = Scene()
    t0 = time.perf_counter()
    planner = GcsPlanner(scene)
    out = {"construct_s": time.perf_counter() - t0}
    t0 = time.perf_counter()
    planner.micp  # noqa: B018 - built on first access
    out["construct_micp_s"] = time.perf_counter() - t0
    ics = sample_initial_conditions(scene, n, seed=seed)
    out |= profile_relaxation(planner, ics)
    out |= profile_micp(planner, ics[:micp_n])
    return out


if __name__ == "__main__":  # pragma: no cover - a report
    import argparse
    import os

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=40, help="initial conditions for relaxation + rounding")
    ap.add_argument("--micp_n", type=int, default=20, help="of those, how many for the MICP settings")
    args = ap.parse_args()
    res = run(args.n, args.micp_n)
    for k, v in res.items():
        print(f"  {k:60s} {v:10.4g}")
    print(f"(load average at the end: {os.getloadavg()[0]:.1f})")
