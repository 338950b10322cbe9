"""Where the certified gap sits: the bound's and the plan's cost by term, and the relaxation's bound on
the plan's own path with the slider's poses between pushes fixed to the plan's (positions, headings,
both). A diagnostic for issue 32, not part of the package.

    python experiments/rotation/gap_sources.py [--slider box] [--n 8] [--seed 0]

Columns: the plan's cost; the gap (cost - bound) / cost of the whole graph's relaxation; of the
relaxation restricted to the plan's path (every other vertex's flow fixed at 0); and of that with the
intermediate poses' positions (xy), headings and their moments (cs), or both fixed to the plan's. Then
the bound's / the plan's cost in pushing (fn^2 + ft^2), turning (the chord term) and the finger's free
travel.
"""

from __future__ import annotations

import argparse

import numpy as np

from benchmarks.rotation_bench import random_starts
from lerobot_gcs_push.conic.certificate import of_solution
from lerobot_gcs_push.contact.face_contact import C0, C1, FN, FT, ONE, S0, S1
from lerobot_gcs_push.contact.planner import ContactPlanner
from lerobot_gcs_push.contact.rounding import round_relaxation
from lerobot_gcs_push.scene import Scene


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--slider", default="box")
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    p = ContactPlanner(Scene(rotates=True, slider=args.slider))
    rel = p.relaxation
    data = rel.data
    cols = {v.id: np.asarray(u) for v, u in zip(rel.variables, data.unpacked)}

    def put(vals, var, value, entries=None):
        idx = cols[var.id].ravel()
        value = np.broadcast_to(np.asarray(value, float), cols[var.id].shape).ravel()
        sel = np.arange(idx.size) if entries is None else np.asarray(entries)
        keep = idx[sel] < data.n  # entries cvxpy dropped are not in the program
        vals[idx[sel][keep]] = value[sel][keep]

    print("start  cost   graph  path   +xy    +cs    +both | push bound/plan  turn bound/plan  free bound/plan")
    for k, (pose0, finger) in enumerate(random_starts(p, args.n, args.seed)):
        pose, q, goal, allow = p.query(pose0, finger)
        window = p.window(pose, goal)
        res = rel.solve(pose, q, goal, allow, window)
        terms = _terms(p, rel, res)  # the restricted solves below leave the variables holding these values
        best, _ = round_relaxation(
            p.model, p.graph, p.regions, p.rounding_forms, res, p.knots, p.per_region, pose, q, goal,
            p.candidates, np.random.default_rng(0), window,
        )  # fmt: skip
        if best is None:
            print(f"{k:5d}  rounding failed")
            continue
        theta = np.concatenate([np.ravel(np.asarray(x.value, float), order="F") for x in rel.params])
        conic = data.at(theta)
        bounds = []
        for fixed in ((), ("xy",), ("cs",), ("xy", "cs")):
            vals = np.full(data.n, np.nan)
            on = np.zeros(len(p.graph.contacts))
            on[list(best.path.contacts)] = 1
            put(vals, rel.phi_c, on)
            last = np.zeros(len(p.graph.contacts))
            last[best.path.contacts[-1]] = 1
            put(vals, rel.phi_t, last)
            onf = np.zeros(len(p.graph.frees))
            onf[list(best.path.frees)] = 1
            put(vals, rel.phi_f, onf)
            for m, f in enumerate(best.path.frees[1:]):  # the free vertex after push m: the slider rests
                c = best.contacts[m]
                heading = np.array([c["c"][-1], c["s"][-1]])
                heading /= np.linalg.norm(heading)
                fr = rel.frees[f]
                if "xy" in fixed:
                    put(vals, fr.pose, [c["x"][-1], c["y"][-1], 0, 0], [0, 1])
                if "cs" in fixed:
                    put(vals, fr.pose, [0, 0, *heading], [2, 3])
                    v = np.r_[1.0, heading]
                    put(vals, fr.moments, np.outer(v, v))
            fixed_conic = conic.fix(vals)
            bounds.append(of_solution(fixed_conic, fixed_conic.solve()).bound)
        # An uncertified bound (None: conic.certificate refused the dual point) prints as nan.
        gaps = [(best.cost - b) / best.cost if b is not None else float("nan") for b in [res.bound, *bounds]]
        plan = _plan_terms(p, best)
        print(
            f"{k:5d} {best.cost:6.2f}  " + "  ".join(f"{g:5.3f}" for g in gaps)
            + " | " + "  ".join(f"{a:6.3f}/{b:6.3f}" for a, b in zip(terms, plan))
        )  # fmt: skip


def _terms(p, rel, res) -> tuple[float, float, float]:
    push = turn = free = 0.0
    for rc in rel.contacts:
        if rc is None:
            continue
        for m in rc.blocks:
            v = m.value
            push += v[FN, FN] + v[FT, FT]
            turn += 2 * p.rot_weight * (v[ONE, ONE] - v[C0, C1] - v[S0, S1])
    for f, fr in enumerate(rel.frees):
        if res.free_flow[f] > 1e-6:
            free += float(np.sum(np.diff(fr.q.value, axis=0) ** 2)) / res.free_flow[f]
    return push, turn, free


def _plan_terms(p, best) -> tuple[float, float, float]:
    push = sum(float(np.sum(c["fn"] ** 2 + c["ft"] ** 2)) for c in best.contacts)
    turn = sum(
        float(np.sum(2 * p.rot_weight * (1 - (c["c"][:-1] * c["c"][1:] + c["s"][:-1] * c["s"][1:]))))
        for c in best.contacts
    )
    free = sum(float(np.sum(np.diff(q, axis=0) ** 2)) for q in best.frees)
    return push, turn, free


if __name__ == "__main__":
    main()
