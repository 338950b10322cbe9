"""Planner benchmark: our GCS relaxation and MICP against Drake's GraphOfConvexSets, side by side.

    from benchmarks.planner_bench import run
    stats = run(n=40, seed=0)   # a flat dict of floats; prints nothing

One-time costs (a fresh planner: the graph and the relaxation's conic data; the MICP's conic data) are
reported apart from per-query times; nothing compiles per query (tests/test_box_gcs_conic.py).
Per query, the three solvers run in the same loop,
in an order that rotates from one query to the next, so machine noise hits all of them alike:

* relaxation: `GcsPlanner.plan(method="relaxation")` (convex relaxation + rounding, Clarabel);
* micp: `GcsPlanner.plan(method="micp")` (SCIP, then the chosen path's restriction);
* drake: one `GraphOfConvexSets.SolveShortestPath` call (Clarabel, convex relaxation, up to 10 rounded
  paths), built per query outside the timed call (the build time is reported separately);
* drake_exact: Drake's convex restriction of every allowed simple path (the exact optimum by
  enumeration; build excluded), for scale.

The plan CLI as a user runs it: `gcs-push plan --initial_conditions=FILE --jsonl=true` on 30 other
initial conditions, in a subprocess; the median of the plans' own `solve_time_s` and the process's wall
time (imports included).

Quality: how often the relaxation's rounded plan is within 1% of the MICP optimum, the relaxation's
lower-bound gap, Drake's agreement with the MICP, and the plan's execution time (`Plan.duration()` with
default `Speeds`) next to the 112 s the paper reports.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from lerobot_gcs_push.box_gcs import GcsPlanner
from lerobot_gcs_push.planning import Speeds
from lerobot_gcs_push.scene import Scene, sample_initial_conditions

# The Drake oracle lives with the tests, which are no package (`tests.drake_oracle` would resolve to the
# top-level `tests` package that draccus installs), so it is imported as the tests import it.
TESTS_DIR = str(Path(__file__).resolve().parents[1] / "tests")

PAPER_DURATION_S = 112.0
METHODS = ("relaxation", "micp", "drake", "drake_exact")


def _p95(x) -> float:
    return float(np.percentile(x, 95))


def run(n: int = 40, seed: int = 0) -> dict:
    if TESTS_DIR not in sys.path:
        sys.path.insert(0, TESTS_DIR)
    from drake_oracle import build_drake_gcs, drake_options, solve_drake_gcs, solve_with_drake

    scene = Scene()
    t0 = time.perf_counter()
    planner = GcsPlanner(scene, method="relaxation", compile_now=False)
    graph_build_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    GcsPlanner(scene)  # what every user of the planner pays once: ready to plan
    construct_s = time.perf_counter() - t0
    warm_up_s = planner.warm_up()
    t0 = time.perf_counter()
    planner.micp  # noqa: B018 - built on first access
    micp_build_s = time.perf_counter() - t0
    options = drake_options(max_rounded_paths=10)

    times = {m: [] for m in METHODS}
    drake_build = []
    relax_cost, relax_lb, micp_cost, drake_cost, durations, relax_durations = [], [], [], [], [], []
    relax_solver, exact_cost = [], []
    for k, ic in enumerate(sample_initial_conditions(scene, n, seed=seed)):
        q = planner.query(ic.box, ic.finger)
        if q is None:  # box already at the goal: nothing to plan
            continue
        src, goal, allowed, extra = q.src, q.goal, q.allowed, q.extra_cost
        plans, drake = {}, None
        for j in range(len(METHODS)):
            m = METHODS[(k + j) % len(METHODS)]
            if m == "drake":
                tb = time.perf_counter()
                dg = build_drake_gcs(planner.graph, src, goal, allowed)
                drake_build.append(time.perf_counter() - tb)
                drake = solve_drake_gcs(dg, options)
                times[m].append(drake.solve_time_s)
            elif m == "drake_exact":
                exact = solve_with_drake(planner.graph, src, goal, allowed, relaxation=False)
                times[m].append(exact.solve_time_s)
                exact_cost.append(exact.cost + extra)
            else:
                plans[m] = planner.plan(ic.box, ic.finger, method=m)
                times[m].append(plans[m].solve_time_s)
        r, mi = plans["relaxation"], plans["micp"]
        relax_cost.append(r.cost)
        relax_lb.append(r.lower_bound)
        relax_solver.append(r.extra.get("relaxation_time_s", np.nan))
        micp_cost.append(mi.cost)
        drake_cost.append(drake.cost + extra)
        durations.append(mi.duration(Speeds()))
        relax_durations.append(r.duration(Speeds()))

    relax_cost, relax_lb = np.array(relax_cost), np.array(relax_lb)
    micp_cost, drake_cost = np.array(micp_cost), np.array(drake_cost)
    drake_rel = (drake_cost - micp_cost) / micp_cost
    exact_rel = (np.array(exact_cost) - micp_cost) / micp_cost
    out = {
        "n": float(len(micp_cost)),
        "seed": float(seed),
        "graph_build_s": graph_build_s,
        "fresh_planner_s": construct_s,
        "warm_up_s": float(warm_up_s),
        "micp_build_s": micp_build_s,
    }
    for m in METHODS:
        out[f"{m}_median_s"] = float(np.median(times[m]))
        out[f"{m}_p95_s"] = _p95(times[m])
    out.update(
        {
            "relaxation_program_median_s": float(np.nanmedian(relax_solver)),
            "drake_over_relaxation_ratio": float(np.median(times["drake"]) / np.median(times["relaxation"])),
            "drake_build_median_s": float(np.median(drake_build)),
            "relaxation_within_1pct_frac": float(np.mean(relax_cost <= 1.01 * micp_cost)),
            "relaxation_within_1pct_count": float(np.sum(relax_cost <= 1.01 * micp_cost)),
            "relaxation_cost_rel_gap_median": float(np.median((relax_cost - micp_cost) / micp_cost)),
            "relaxation_cost_rel_gap_max": float(np.max((relax_cost - micp_cost) / micp_cost)),
            "lower_bound_rel_gap_median": float(np.median((micp_cost - relax_lb) / micp_cost)),
            "lower_bound_rel_gap_max": float(np.max((micp_cost - relax_lb) / micp_cost)),
            "drake_within_1pct_frac": float(np.mean(drake_cost <= 1.01 * micp_cost)),
            "drake_rel_diff_max_abs": float(np.max(np.abs(drake_rel))),
            "drake_below_micp_count": float(np.sum(drake_rel < -1e-6)),
            "drake_exact_rel_diff_max_abs": float(np.max(np.abs(exact_rel))),
            "drake_exact_below_micp_count": float(np.sum(exact_rel < -1e-6)),
            "micp_cost_median_m": float(np.median(micp_cost)),
            "plan_duration_median_s": float(np.median(durations)),
            "plan_duration_p95_s": _p95(durations),
            "relaxation_plan_duration_median_s": float(np.median(relax_durations)),
            "paper_duration_s": PAPER_DURATION_S,
        }
    )
    out.update(cli_plan(scene, n=30, seed=seed + 1))
    return out


def cli_plan(scene: Scene, n: int, seed: int) -> dict:
    """`gcs-push plan` on `n` initial conditions that the rest of the benchmark does not use."""
    ics = [{"box": list(ic.box), "finger": list(ic.finger)} for ic in sample_initial_conditions(scene, n, seed=seed)]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "ics.json"
        path.write_text(json.dumps(ics))
        exe = Path(sys.executable).with_name("gcs-push")
        t0 = time.perf_counter()
        cmd = [str(exe), "plan", f"--initial_conditions={path}", "--jsonl=true"]
        res = subprocess.run(cmd, capture_output=True, text=True, check=True)
        wall = time.perf_counter() - t0
    plans = [json.loads(line) for line in res.stdout.splitlines() if line.startswith("{")]
    per_plan = [p["solve_time_s"] for p in plans]
    return {
        "cli_plans": float(len(plans)),
        "cli_plan_median_s": float(np.median(per_plan)),
        "cli_plan_p95_s": _p95(per_plan),
        "cli_wall_s": wall,
    }


if __name__ == "__main__":  # pragma: no cover - convenience only
    import argparse
    import json

    ap = argparse.ArgumentParser(description="Planner benchmark (see benchmarks/planner_bench.py).")
    ap.add_argument("--n", type=int, default=40, help="initial conditions (queries)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    print(json.dumps(run(args.n, args.seed), indent=2))
