"""`gcs-push`: plan, generate, evaluate, demo. Argument parsing only; the work lives in the modules."""

from __future__ import annotations

import argparse
import json
import os
import sys
import warnings

from lerobot_gcs_push.scene import SAMPLERS, Scene, load_initial_conditions

os.environ.setdefault("HF_HUB_OFFLINE", "1")  # nothing here may reach the network unless asked to


def _pair(name):
    def parse(values):
        return [float(v) for v in values]
    return parse


def cmd_plan(args) -> int:
    from lerobot_gcs_push.planner import GcsPlanner, SolverError
    from lerobot_gcs_push.scene import Scene

    if args.initial_conditions:
        if args.box or args.finger:
            raise SystemExit("error: give either --initial-conditions or --box/--finger, not both")
        queries = load_initial_conditions(args.initial_conditions)
    else:
        if not (args.box and args.finger):
            raise SystemExit("error: --box X Y and --finger X Y are required (or --initial-conditions FILE)")
        queries = [{"box": args.box, "finger": args.finger}]
    planner = GcsPlanner(Scene(), method=args.method)
    for q in queries:
        try:
            plan = planner.plan(q["box"], q["finger"], goal=args.goal, method=args.method)
        except ValueError as err:
            raise SystemExit(f"error: {err}") from None
        except SolverError as err:
            raise SystemExit(f"solver error: {err}") from None
        if args.json:
            print(json.dumps(plan.to_json()), flush=True)
        else:
            print(f"cost {plan.cost:.4f} m (lower bound {plan.lower_bound:.4f}), {plan.num_pushes} push(es), "
                  f"solved in {plan.solve_time_s * 1e3:.1f} ms with {plan.method}")
            print("modes: " + " -> ".join(plan.modes or ["(box already at the goal)"]))
            print(f"box ends at {plan.box_final.round(4).tolist()}, execution takes {plan.duration():.1f} s")
    return 0


def cmd_generate(args) -> int:
    from lerobot_gcs_push.dataset import GenerateConfig, generate

    try:
        cfg = GenerateConfig(episodes=args.episodes, repo_id=args.repo_id, root=args.root, seed=args.seed,
                             workers=args.workers, expert=args.expert, method=args.method, sampler=args.sampler,
                             disturbances=args.disturbances, overwrite=args.overwrite, resume=args.resume,
                             frames=args.frames,
                             push_to_hub=args.push_to_hub,
                             backend=args.backend, ray_address=args.ray_address, shard_size=args.shard_size)
        report = generate(cfg)
    except (ValueError, FileExistsError, RuntimeError) as err:
        raise SystemExit(f"error: {err}") from None
    print(f"wrote {report.episodes} demonstrations ({report.frames} frames) to {report.root} in "
          f"{report.wall_time_s:.1f} s ({report.episodes_per_min:.1f} per minute); "
          f"{report.failures} failed rollout(s) of {report.attempts} were left out")
    return 0


def cmd_evaluate(args) -> int:
    from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate

    try:
        cfg = EvaluateConfig(policies=args.policy, initial_conditions=args.initial_conditions,
                             num_initial_conditions=args.num_initial_conditions, seed=args.seed, runs=args.runs,
                             sampler=args.sampler, large_regret_m=args.large_regret_m,
                             disturbances=args.disturbances, output_dir=args.output_dir, device=args.device,
                             workers=args.workers, timeout_s=args.timeout_s, dataset=args.dataset,
                             videos=args.videos, overwrite=args.overwrite,
                             backend=args.backend, ray_address=args.ray_address)
        summary = evaluate(cfg)
    except (ValueError, FileNotFoundError, FileExistsError) as err:
        raise SystemExit(f"error: {err}") from None
    print(summary["tables_md"])
    print(f"records, tables and figures in {args.output_dir}")
    return 0


def cmd_collect(args) -> int:
    from lerobot_gcs_push.active import CollectConfig, collect

    cfg = CollectConfig(rollouts=args.rollouts, repo_id=args.repo_id, root=args.root,
                        large_regret_m=args.large_regret_m, failed_regret_m=args.failed_regret_m,
                        keep_fraction=args.keep_fraction,
                        max_per_run=args.max_per_run, seed=args.seed, workers=args.workers,
                        overwrite=args.overwrite, resume=args.resume)
    report, states = collect(cfg)
    print(f"labelled {report.episodes} of {len(states)} branch states ({report.frames} frames) into {report.root} "
          f"in {report.wall_time_s:.1f} s; {report.failures} expert rollout(s) failed and were left out")
    return 0


def cmd_demo(args) -> int:
    """The main job: demonstrations, the GCS experts under the paper's protocol, and the shipped policy
    beside GCS on a few initial conditions, with a side-by-side video."""
    from pathlib import Path

    from lerobot_gcs_push.dataset import GenerateConfig, dataset_root, generate
    from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate, variant_label, video_path
    from lerobot_gcs_push.figures import side_by_side

    gen = GenerateConfig(episodes=args.episodes, repo_id=args.repo_id, workers=args.workers,
                         resume=not args.overwrite, overwrite=args.overwrite)
    root = dataset_root(gen)
    if root.exists() and not args.overwrite:
        print(f"dataset already at {root} (pass --overwrite to regenerate)")
    else:
        report = generate(gen)
        print(f"wrote {report.episodes} demonstrations ({report.frames} frames) to {report.root} in "
              f"{report.wall_time_s:.1f} s")
    out = Path(args.output_dir)
    experts = evaluate(EvaluateConfig(policies=["gcs-open-loop", "gcs-closed-loop"],
                                      num_initial_conditions=args.num_initial_conditions, runs=args.runs,
                                      disturbances=True, output_dir=str(out / "experts"), workers=args.workers,
                                      dataset=args.repo_id))
    print(experts["tables_md"])
    policy_dir = out / "policy"
    if args.policy:
        cfg = EvaluateConfig(policies=["gcs-open-loop", args.policy], num_initial_conditions=args.policy_ics,
                             runs=1, output_dir=str(policy_dir), workers=args.workers, timeout_s=60.0,
                             videos=args.policy_ics)
        print(evaluate(cfg)["tables_md"])
        labels = [variant_label(p, False) for p in cfg.policies]
        for i in range(args.policy_ics):
            clips = [video_path(policy_dir, label, i) for label in labels]
            side_by_side(clips, ["GCS", "diffusion policy"], policy_dir / f"side_by_side_ic{i:03d}.mp4",
                         gif=policy_dir / f"side_by_side_ic{i:03d}.gif" if i == 0 else None)
    print(f"\ndataset:        {root}")
    print(f"GCS experts:    {out / 'experts'}/tables.md and figures beside it")
    if args.policy:
        print(f"learned policy: {policy_dir}/tables.md; watch {policy_dir}/side_by_side_ic000.mp4")
    print("train a policy on the dataset (CPU preset):\n"
          "  .venv/bin/lerobot-train --config_path=configs/policy/diffusion_cpu.json")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="gcs-push", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)

    pl = sub.add_parser("plan", help="plan one push task (or a file of them) with GCS")
    pl.add_argument("--box", nargs=2, type=float, metavar=("X", "Y"))
    pl.add_argument("--finger", nargs=2, type=float, metavar=("X", "Y"))
    pl.add_argument("--goal", nargs=2, type=float, metavar=("X", "Y"))
    pl.add_argument("--initial-conditions", metavar="FILE.json")
    pl.add_argument("--method", choices=["relaxation", "micp"], default="relaxation")
    pl.add_argument("--json", action="store_true", help="one JSON object per line")
    pl.set_defaults(func=cmd_plan)

    g = sub.add_parser("generate", help="write GCS demonstrations as a LeRobotDataset")
    g.add_argument("--episodes", type=int, default=100)
    g.add_argument("--repo-id", default="local/gcs_push_box")
    g.add_argument("--root", default=None, help="default: $HF_LEROBOT_HOME/<repo-id>")
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--workers", type=int, default=2)
    g.add_argument("--expert", choices=["open-loop", "closed-loop"], default="open-loop")
    g.add_argument("--method", choices=["relaxation", "micp"], default="relaxation")
    g.add_argument("--sampler", choices=list(SAMPLERS), default="sobol")
    g.add_argument("--disturbances", action="store_true")
    g.add_argument("--frames", type=int, default=None, help="stop once this many frames are written")
    mode = g.add_mutually_exclusive_group()
    mode.add_argument("--overwrite", action="store_true")
    mode.add_argument("--resume", action="store_true")
    g.add_argument("--push-to-hub", action="store_true")
    _backend_options(g)
    g.add_argument("--shard-size", type=int, default=10,
                   help="initial conditions per job, at most; each job writes one shard, merged at the end")
    g.set_defaults(func=cmd_generate)

    e = sub.add_parser("evaluate", help="the paper's evaluation protocol for any set of policies")
    e.add_argument("--policy", action="append", required=True,
                   help="gcs-open-loop, gcs-closed-loop, or a LeRobot pretrained_model directory (repeat)")
    e.add_argument("--initial-conditions", metavar="FILE.json")
    e.add_argument("--num-initial-conditions", type=int, default=20)
    e.add_argument("--seed", type=int, default=1000)
    e.add_argument("--sampler", choices=list(SAMPLERS), default="uniform",
                   help="initial conditions: uniform (the paper's), sobol, or hard (configurations a cloned "
                        "policy gets wrong)")
    e.add_argument("--large-regret-m", type=float, default=0.5,
                   help="a chunk whose regret exceeds this counts as a mistake")
    e.add_argument("--runs", type=int, default=5)
    e.add_argument("--disturbances", action="store_true")
    e.add_argument("--output-dir", required=True)
    e.add_argument("--device", default="cpu")
    e.add_argument("--workers", type=int, default=1)
    e.add_argument("--timeout-s", type=float, default=Scene.timeout_s)
    e.add_argument("--dataset", default=None, help="repo id (or path) of the training dataset, for Fig. 4")
    e.add_argument("--videos", type=int, default=2, help="rollout videos per policy")
    e.add_argument("--overwrite", action="store_true")
    _backend_options(e)
    e.set_defaults(func=cmd_evaluate)

    c = sub.add_parser("collect", help="active data: label the states a policy visited with the GCS expert")
    c.add_argument("--rollouts", action="append", required=True, metavar="DIR",
                   help="a `gcs-push evaluate` output folder of the policy (repeat)")
    c.add_argument("--repo-id", default="local/gcs_push_active")
    c.add_argument("--root", default=None, help="default: $HF_LEROBOT_HOME/<repo-id>")
    c.add_argument("--large-regret-m", type=float, default=0.5, help="branch from chunks above this regret")
    c.add_argument("--failed-regret-m", type=float, default=0.25, help="the same, in a failed rollout")
    c.add_argument("--keep-fraction", type=float, default=0.05, help="fraction of the other chunk starts kept")
    c.add_argument("--max-per-run", type=int, default=12, help="branch states per rollout at most")
    c.add_argument("--seed", type=int, default=0)
    c.add_argument("--workers", type=int, default=2)
    cm = c.add_mutually_exclusive_group()
    cm.add_argument("--overwrite", action="store_true")
    cm.add_argument("--resume", action="store_true")
    c.set_defaults(func=cmd_collect)

    d = sub.add_parser("demo", help="the main job on its defaults")
    d.add_argument("--episodes", type=int, default=100)
    d.add_argument("--repo-id", default="local/gcs_push_box")
    d.add_argument("--workers", type=int, default=2)
    d.add_argument("--num-initial-conditions", type=int, default=20)
    d.add_argument("--runs", type=int, default=5)
    d.add_argument("--output-dir", default="outputs/demo")
    d.add_argument("--policy", default="policies/diffusion_cpu",
                   help="a LeRobot pretrained_model directory to show beside GCS ('' to skip)")
    d.add_argument("--policy-ics", type=int, default=3, help="initial conditions for the policy beside GCS")
    d.add_argument("--overwrite", action="store_true")
    d.set_defaults(func=cmd_demo)
    return p


def _backend_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--backend", choices=["process", "ray"], default="process",
                   help="worker processes on this machine, or Ray actors (--workers of them) on a Ray cluster")
    p.add_argument("--ray-address", default=None,
                   help="with --backend ray: 'auto' or HOST:PORT joins a running cluster; default: start Ray here")


def main(argv=None) -> int:
    warnings.filterwarnings("ignore", message=".*GcsPushBox-v0 not registered.*")
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError, FileExistsError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
