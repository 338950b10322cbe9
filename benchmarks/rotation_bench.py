"""Rotating-slider benchmark: the contact planner's relaxation + rounding against the baseline NLP.

    python -m benchmarks.rotation_bench [--n 20] [--seed 0] [--slider box]
    from benchmarks.rotation_bench import run; stats = run(n=20)   # a flat dict of floats

Random starts: slider position uniform over |x|, |y| <= Scene.box_init_half_width, heading uniform in
[-pi, pi), finger uniform over |x|, |y| <= Scene.finger_init_half_width, redrawn until it lies in a
free-space piece around the slider; goal the scene's (goal, goal_heading). Per start, in an order that
alternates from one start to the next so machine noise hits both alike:

* relaxation: `ContactPlanner.plan` (Clarabel on the graph relaxation, SNOPT on sampled paths); its time
  is the whole query, its gap (cost - bound) / cost is certified by the relaxation's bound;
* baseline: `ContactPlanner.baseline` (SNOPT from a straight-line guess over one heuristic push).

Then each start's episode in the env (no disturbances, 60 s), by the envs' expert: closed-loop (replanning
when the slider strays from the plan, contact/expert.py) and open-loop (the first plan, executed); success
is the env's, 95 % coverage of the goal outline.

The one-time build and compile of the relaxation is reported apart (warm_up_s).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

os.environ.setdefault("HF_HUB_OFFLINE", "1")

from lerobot_gcs_push.contact import ContactPlanner
from lerobot_gcs_push.planning import PlanningError  # noqa: E402
from lerobot_gcs_push.registration import SCENES, SE2_ENV_ID, TEE_ENV_ID  # noqa: E402
from lerobot_gcs_push.scene import Scene  # noqa: E402

ENV_IDS = {"box": SE2_ENV_ID, "tee": TEE_ENV_ID}


def random_starts(planner: ContactPlanner, n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    scene = planner.scene
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        lim = scene.box_init_half_width
        pose = np.array([rng.uniform(-lim, lim), rng.uniform(-lim, lim), rng.uniform(-np.pi, np.pi)])
        while True:
            finger = rng.uniform(-scene.finger_init_half_width, scene.finger_init_half_width, size=2)
            try:
                planner.query(pose, finger)
                break
            except ValueError:
                continue
        out.append((pose, finger))
    return out


def verify(scene: Scene, plan, rolling_radius: float) -> bool:
    """Independent checks of a plan: the continuous quasi-static model re-integrated from its pushes ends
    within 3 cm / 0.03 rad of the plan's end; the finger touches the slider along pushes and clears it
    (sampled) along free segments; the friction cone holds."""
    kappa = scene.box_damping / scene.rot_damping
    faces, shape, r = scene.shape.faces(), scene.shape, scene.finger_radius
    pose = np.array(plan.slider_poses[0], float)
    for push in plan.pushes:
        a, b, n = faces[push["face"]]
        if np.any(np.abs(push["ft"]) > scene.finger_box_friction * push["fn"] + 1e-6):
            return False
        lam = float(push["lam"][0])
        for fn, ft in zip(push["fn"], push["ft"]):
            # The contact point rolls back along the face by r dtheta as the slider turns.
            pose, lam = _sticking_step(pose, lam, a, b, n, fn, ft, kappa, rolling_radius, 200)
        if abs(lam - push["lam"][-1]) * np.linalg.norm(b - a) > 0.03:
            return False
    end = plan.slider_final
    if np.linalg.norm(pose[:2] - end[:2]) > 0.03 or abs(pose[2] - end[2]) > 0.03:
        return False
    poses, fingers = plan.slider_poses, plan.finger_path
    for k, kind in enumerate(plan.segment_kinds):
        if kind == "push":
            if abs(shape.signed_distance(poses[k + 1], fingers[k + 1]) - r) > 1e-4:
                return False
        else:
            for w in np.linspace(0, 1, 15):
                if shape.signed_distance(poses[k], (1 - w) * fingers[k] + w * fingers[k + 1]) < r - 1e-6:
                    return False
    return True


def _sticking_step(pose, lam, a, b, n, fn, ft, kappa, r, sub):
    """One plan step of the continuous quasi-static model: the body-frame displacement d = -fn n + ft t
    at a constant rate over the step (RK2 on `sub` sub-steps), the contact point a + lam (b - a)."""
    e = b - a
    length = float(np.linalg.norm(e))
    d = -fn * n + ft * e / length
    for _ in range(sub):
        p = a + lam * e
        w = kappa * (p[0] * d[1] - p[1] * d[0])
        pm = a + (lam - 0.5 * r / length * w / sub) * e  # the midpoint's contact
        wm = kappa * (pm[0] * d[1] - pm[1] * d[0])
        th = pose[2] + 0.5 * wm / sub
        rot = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        pose = pose + np.array([*(rot @ d) / sub, wm / sub])
        lam -= r / length * wm / sub
    return pose, lam


def _p95(x) -> float:
    return float(np.percentile(x, 95)) if len(x) else float("nan")


def _med(x) -> float:
    return float(np.median(x)) if len(x) else float("nan")


def execute(env_id: str, planner: ContactPlanner, starts, mode: str) -> dict:
    """Episodes of the envs' expert from `starts` in the env (60 s, no disturbances)."""
    import gymnasium as gym

    import lerobot_gcs_push  # noqa: F401  (registers the envs)
    from lerobot_gcs_push.episodes.rollout import rollout
    from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert

    env = gym.make(env_id, max_sim_time_s=60.0, image_size=(32, 32)).unwrapped  # the camera is not scored
    expert = make_expert(env.scene, env.fps, ExpertConfig(mode=mode), planner)
    ok, replans, sim_time, over_plan = 0, [], [], []
    for k, (pose, finger) in enumerate(starts):
        try:
            res = rollout(env, expert, pose[:2], finger, seed=k, heading=float(pose[2]))
        except PlanningError:
            continue
        ok += res["success"]
        replans.append(res["replans"])
        if res["success"]:
            sim_time.append(res["sim_time_s"])
            over_plan.append(res["sim_time_s"] / expert.plan.duration(expert.speeds))
    env.close()
    return {
        f"{mode}_success_frac": ok / len(starts),
        f"{mode}_replans_median": _med(replans),
        f"{mode}_sim_time_median_s": _med(sim_time),
        f"{mode}_sim_time_over_first_plan_median": _med(over_plan),  # the first plan's commanded duration
    }


def run(
    n: int = 20,
    seed: int = 0,
    slider: str = "box",
    episodes: bool = True,
    episode_starts: int | None = None,
    **planner_kw,
) -> dict:
    """`episode_starts`: run the episodes from the first that many starts only (all by default): the T's
    closed-loop episodes replan a dozen times each, about a minute apiece on this machine."""
    scene = SCENES[ENV_IDS[slider]]
    t0 = time.perf_counter()
    planner = ContactPlanner(scene, **planner_kw)
    warm_up_s = planner.warm_up() + (time.perf_counter() - t0)
    times, relax_times, round_times, gaps, costs, base_costs, base_times, ratio = [], [], [], [], [], [], [], []
    rounded = base_ok = verified = uncertified = 0
    starts = random_starts(planner, n, seed)
    for k, (pose, finger) in enumerate(starts):
        plan = base = None
        for method in ("relaxation", "baseline") if k % 2 == 0 else ("baseline", "relaxation"):
            try:
                if method == "relaxation":
                    plan = planner.plan(pose, finger)
                else:
                    base = planner.baseline(pose, finger)
            except PlanningError:
                pass
        if plan is not None:
            rounded += 1
            verified += verify(scene, plan, planner.model.rolling_radius)
            times.append(plan.solve_time_s)
            relax_times.append(plan.extra["relaxation_s"])
            round_times.append(plan.extra["rounding_s"])
            if plan.certified:
                gaps.append(plan.gap)
            else:  # the relaxation's dual residual too large to vouch for a bound: no gap to report
                uncertified += 1
            costs.append(plan.cost)
        if base is not None:
            base_ok += 1
            base_costs.append(base.cost)
            base_times.append(base.solve_time_s)
            if plan is not None:
                ratio.append(base.cost / plan.cost)
    sim = {}
    if episodes:
        for mode in ("closed-loop", "open-loop"):
            sim |= execute(ENV_IDS[slider], planner, starts[:episode_starts], mode)
        sim["episode_starts"] = float(len(starts[:episode_starts]))
    return {
        "n": float(n),
        "load_avg_1min": os.getloadavg()[0],  # 2 cores shared: timings scale with this
        "warm_up_s": warm_up_s,
        "plan_median_s": _med(times),
        "plan_p95_s": _p95(times),
        "relaxation_median_s": _med(relax_times),
        "rounding_median_s": _med(round_times),
        "gap_median": _med(gaps),
        "gap_p95": _p95(gaps),
        "gap_max": float(np.max(gaps)) if gaps else float("nan"),
        "uncertified_frac": uncertified / n,  # plans without a certified bound (left out of the gaps)
        "rounding_success_frac": rounded / n,
        "verified_frac": verified / n,  # plans passing `verify` (dynamics, contact, clearance, friction)
        "cost_median": _med(costs),
        "baseline_success_frac": base_ok / n,
        "baseline_median_s": _med(base_times),
        "baseline_cost_median": _med(base_costs),
        "baseline_over_plan_cost_median": _med(ratio),
        "knots": float(planner.knots),
        **sim,
    }


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--slider", default="box", choices=("box", "tee"))
    ap.add_argument("--layers", type=int, default=None, help="default: the planner's (box 2, T 3)")
    ap.add_argument("--knots", type=int, default=None, help="default: enough to turn the slider to its goal")
    ap.add_argument("--pieces", type=int, default=1, help="contact-location intervals per face")
    ap.add_argument("--window-margin", type=float, default=None, help="heading window (rad) and its chord cut")
    ap.add_argument("--edge-copies", action="store_true", help="one contact copy per entering edge (last layer)")
    ap.add_argument("--max-step-rotation", type=float, default=0.2, help="rad per knot step")
    ap.add_argument("--no-rlt", action="store_true")
    ap.add_argument("--no-knot-windows", action="store_true", help="without each knot's reachable-heading cut")
    ap.add_argument("--no-episodes", action="store_true", help="plans only, no episodes in the env")
    ap.add_argument("--episode-starts", type=int, default=None, help="episodes from the first K starts only")
    ap.add_argument("--no-rolling", action="store_true", help="hold the sticking contact still (the old model)")
    args = ap.parse_args(argv)
    stats = run(
        args.n,
        args.seed,
        args.slider,
        not args.no_episodes,
        args.episode_starts,
        layers=args.layers,
        knots=args.knots,
        rlt=not args.no_rlt,
        pieces=args.pieces,
        window_margin=args.window_margin,
        edge_copies=args.edge_copies,
        max_step_rotation=args.max_step_rotation,
        knot_windows=not args.no_knot_windows,
        rolling=not args.no_rolling,
    )
    for k, v in stats.items():
        print(f"{k:32s} {v:.4g}")
    return stats


if __name__ == "__main__":
    main()
