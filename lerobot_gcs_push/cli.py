"""`gcs-push COMMAND [--config_path=FILE] [--field=value ...]`: plan, generate, evaluate, collect, improve, demo.

Each command's options are the fields of its configuration dataclass (the same one the Python API
takes), parsed by draccus as LeRobot's own CLIs are: `--config_path` loads a JSON or YAML file and
`--field=value` overrides it; `gcs-push COMMAND --help` lists every field with its comment. This module
only maps commands to configs and prints reports; the work lives in the modules it imports.
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from lerobot_gcs_push.artifacts.shipped import shipped_path
from lerobot_gcs_push.episodes.workers import FanOut
from lerobot_gcs_push.evaluation import EvaluateConfig
from lerobot_gcs_push.generate import GenerateConfig
from lerobot_gcs_push.generate.config import OutputConfig
from lerobot_gcs_push.improve import ImproveConfig
from lerobot_gcs_push.improve.collect import CollectConfig
from lerobot_gcs_push.pusht.keypoint_training import TrainKeypointsConfig
from lerobot_gcs_push.scene import is_finite_number, load_initial_conditions
from lerobot_gcs_push.scene.options import StartsConfig
from lerobot_gcs_push.settings import flat_argv, flat_options

os.environ.setdefault("HF_HUB_OFFLINE", "1")  # nothing here may reach the network unless asked to


@flat_options
@dataclass
class PlanConfig:
    # Box centre [x, y] in metres (with `finger`; or give `initial_conditions`).
    box: tuple[float, float] | None = None
    # Finger centre [x, y] in metres.
    finger: tuple[float, float] | None = None
    # Goal [x, y] for the box centre; default: the scene's goal.
    goal: tuple[float, float] | None = None
    # The task and its starts: --env_id (GcsPushBox-v0, GCS over the box's modes, or a rotating slider,
    # GcsPushBoxSE2-v0 or GcsPushT-v0, planned through contact: lerobot_gcs_push/contact/, work in progress,
    # issue 32) and --initial_conditions (a JSON list of {"box": [x, y], "finger": [x, y]}, planned in file
    # order); `--starts.env_id` works too. Plan samples nothing and runs no env: no --sampler, --seed or
    # --disturbances.
    starts: StartsConfig = field(default_factory=StartsConfig)
    # relaxation (convex relaxation + rounding, ~10 ms) or micp (exact, SCIP): the planner's own, as the
    # expert's --method is its planner's.
    method: str = "relaxation"
    # Print one JSON object per plan (one per line) instead of a summary.
    jsonl: bool = False
    # The slider's heading in radians (rotating sliders; a file's entries carry their own "heading").
    heading: float = 0.0

    def __post_init__(self) -> None:
        from lerobot_gcs_push.box_gcs import check_method
        from lerobot_gcs_push.registration import SCENES

        starts, env_id = self.starts, self.starts.env_id
        unused = [
            name
            for name, given in (
                ("sampler", starts.sampler is not None),
                ("seed", starts.seed is not None),
                ("disturbances", starts.disturbances),
            )
            if given
        ]
        if unused:
            raise ValueError(
                f"plan samples no starts and runs no env: drop --{', --'.join(unused)} (give --box='[x, y]' and "
                "--finger='[x, y]', or --initial_conditions=FILE.json)"
            )
        check_method(self.method)
        if isinstance(self.heading, bool) or not is_finite_number(self.heading):
            raise ValueError(f"heading must be a finite number of radians, got {_plain(self.heading)!r}")
        self.heading = float(self.heading)
        kind = SCENES[env_id].kind
        if kind.refuses_heading(self.heading):
            raise ValueError(f"heading {self.heading} given, but {env_id}'s slider cannot rotate")
        if self.method not in kind.methods or (self.goal is not None and not kind.goals_anywhere):
            raise ValueError(f"{env_id} plans with the relaxation to the scene's goal pose only")
        if starts.initial_conditions and (self.box or self.finger):
            raise ValueError("give either initial_conditions or box/finger, not both")
        if not starts.initial_conditions and not (self.box and self.finger):
            raise ValueError("give --box='[x, y]' and --finger='[x, y]', or --initial_conditions=FILE.json")


@flat_options
@dataclass
class DemoConfig(FanOut):
    # The paper's whole protocol: 100 demonstrations and the experts on 20 initial conditions x 5 runs.
    # Off, a quick look at the whole pipeline (a few minutes on 2 cores, install included): 20 and 5 x 1.
    protocol: bool = False
    # GCS demonstrations to write (skipped when the dataset exists and overwrite is false); default by protocol.
    episodes: int | None = None
    # The dataset written, and what redoes it: --repo_id (default local/gcs_push_box, what the training preset
    # reads, with the protocol; local/gcs_push_box_quick without), --root, and --overwrite, which also redoes
    # both evaluations (`--output.repo_id` works too). No --resume: demo always continues what it finds.
    output: OutputConfig = field(default_factory=OutputConfig)
    # The experts' evaluation: initial conditions x runs, with and without disturbances; default by protocol.
    num_initial_conditions: int | None = None
    # Runs per initial condition; default by protocol.
    runs: int | None = None
    # Where the experts' and the policy's evaluations, videos and the side-by-side GIF go.
    output_dir: str = "outputs/demo"
    # A LeRobot pretrained_model directory to show beside GCS (empty: skip).
    policy: str = "policies/diffusion_cpu"
    # Initial conditions for the policy beside GCS (one run each, one side-by-side video each).
    policy_ics: int = 3
    # Torch device of the policy: cpu, cuda, cuda:N or mps.
    device: str = "cpu"

    def __post_init__(self) -> None:
        # Checked before the demonstrations are written, not minutes later when the step that needs it runs.
        from lerobot_gcs_push.evaluation import check_device, check_policy

        quick, full = (20, 5, 1, "local/gcs_push_box_quick"), (100, 20, 5, "local/gcs_push_box")
        defaults = full if self.protocol else quick
        for name, value in zip(("episodes", "num_initial_conditions", "runs"), defaults):
            if getattr(self, name) is None:
                setattr(self, name, value)
        self.output.fill(defaults[3])
        if self.output.resume:
            raise ValueError("demo continues its dataset and evaluations unless --overwrite=true: drop --resume")
        if min(self.episodes, self.num_initial_conditions, self.runs) < 1:
            raise ValueError("episodes, num_initial_conditions and runs must be >= 1")
        self.check_fan_out()
        if self.policy:
            check_policy(self.policy)
            if self.policy_ics < 1:
                raise ValueError(
                    f"policy_ics must be >= 1 (or skip the policy with --policy=''), got {self.policy_ics}"
                )
        check_device(self.device)


def run_plan(cfg: PlanConfig) -> None:
    from lerobot_gcs_push.planning import PlanningError
    from lerobot_gcs_push.planning.factory import make_planner, speeds_for
    from lerobot_gcs_push.registration import SCENES

    ics = cfg.starts.initial_conditions
    queries = load_initial_conditions(ics) if ics else [{"box": cfg.box, "finger": cfg.finger}]
    scene = SCENES[cfg.starts.env_id]
    for i, q in enumerate(queries):  # every entry checked before the first plan, each error naming its field
        what = f"{ics!r} entry {i}" if ics else "plan"
        heading = scene.kind.pose(scene.kind.slider(q["box"], q.get("heading", cfg.heading)))[2]
        scene.validate_state(q["box"], q["finger"], heading=heading, what=what, box_limit=scene.box_reach)
    planner = make_planner(scene, cfg.method)
    for q in queries:
        slider = scene.kind.slider(q["box"], q.get("heading", cfg.heading))
        try:
            plan = planner.plan(slider, q["finger"], cfg.goal)
        except PlanningError as err:  # one query's failure is a line of output, not the end of the file
            print(
                json.dumps({"slider": slider, "finger": q["finger"], "error": str(err)})
                if cfg.jsonl
                else f"no plan: {err}",
                flush=True,
            )
            continue
        if cfg.jsonl:
            print(json.dumps(plan.to_json()), flush=True)
            continue
        took = scene.kind.solve_time_text(plan.solve_time_s)
        print(f"cost {plan.cost:.4f} ({_bound_text(plan)}), {plan.num_pushes} push(es), solved in {took}")
        print("modes: " + " -> ".join(plan.modes or ["(already at the goal)"]))
        final = plan.slider_final.round(4).tolist()
        where = scene.kind.final_text(final)
        print(f"{where}, execution takes {plan.duration(speeds_for(scene)):.1f} s")


def _bound_text(plan) -> str:
    if plan.lower_bound is None:
        return "lower bound uncertified: the relaxation's dual residual was too large to vouch for it"
    return f"certified lower bound {plan.lower_bound:.4f}, gap {plan.gap_text()}, {plan.method}"


def _plain(value):
    """A numpy scalar as the Python number it holds (messages print 0.5, not np.float64(0.5))."""
    return value.item() if hasattr(value, "item") else value


def run_generate(cfg: GenerateConfig) -> None:
    from lerobot_gcs_push.generate import generate

    report = generate(cfg)
    if report.already_finished:
        print(f"already complete: {report.episodes} demonstrations ({report.frames} frames) in {report.root}")
        return
    print(
        f"wrote {report.episodes} demonstrations ({report.frames} frames) to {report.root} in "
        f"{report.wall_time_s:.1f} s ({report.episodes_per_min:.1f} per minute); "
        f"{report.failures} failed rollout(s) of {report.attempts} were left out"
    )


def run_evaluate(cfg: EvaluateConfig) -> None:
    from lerobot_gcs_push.evaluation import evaluate

    summary = evaluate(cfg)
    print(summary["tables_md"])
    print(f"records, tables and figures in {cfg.output_dir}")


def run_collect(cfg: CollectConfig) -> None:
    from lerobot_gcs_push.improve.collect import collect

    report, states = collect(cfg)
    if report.already_finished:
        print(f"already complete: {report.episodes} labelled branch states ({report.frames} frames) in {report.root}")
        return
    print(
        f"labelled {report.episodes} of {len(states)} branch states ({report.frames} frames) into {report.root} "
        f"in {report.wall_time_s:.1f} s; {report.failures} expert rollout(s) failed and were left out"
    )


def run_improve(cfg: ImproveConfig) -> None:
    from lerobot_gcs_push.improve import improve

    report = improve(cfg)
    for r in report.get("rounds", []):
        rollouts = ", ".join(
            f"{name} {s.get('without', 0):.2f} / {s.get('with', float('nan')):.2f} at {s['time_ratio']:.2f}x GCS"
            for name, s in r["rollouts"].items()
        )
        verdict = "targets met" if r.get("targets_met") else ("shipped" if r["shipped"] else "kept")
        print(f"round {r['round']} at {r['hours']:.2f} h: rollouts {rollouts} (without / with disturbances); {verdict}")
    print(f"to resume elsewhere, commit {cfg.state_dir} and {cfg.policy} and run the same command")


def run_demo(cfg: DemoConfig) -> None:
    """Demonstrations, the GCS experts under the paper's protocol, and the shipped policy beside GCS on
    a few initial conditions with side-by-side videos."""
    from pathlib import Path

    from lerobot_gcs_push.evaluation import changed_weights, evaluate, variant_label, video_path
    from lerobot_gcs_push.evaluation.videos import side_by_side
    from lerobot_gcs_push.generate import dataset_root

    overwrite = cfg.output.overwrite
    gen = GenerateConfig(
        episodes=cfg.episodes,
        output=replace(cfg.output, resume=not overwrite),
        **cfg.fan_out(),
    )
    root = dataset_root(gen)
    if root.exists() and not overwrite:
        print(f"dataset already at {root} (pass --overwrite=true to regenerate)")
    else:
        run_generate(gen)
    out = Path(cfg.output_dir)
    # Apart, so that the quick look and the whole protocol each resume their own runs.
    experts_dir = out / ("experts_protocol" if cfg.protocol else "experts")
    experts = evaluate(
        EvaluateConfig(
            policies=["gcs-open-loop", "gcs-closed-loop"],
            num_initial_conditions=cfg.num_initial_conditions,
            runs=cfg.runs,
            disturbances=True,
            output_dir=str(experts_dir),
            dataset=str(root) if cfg.output.root else cfg.output.repo_id,
            **cfg.fan_out(),
            overwrite=overwrite,
        )
    )
    print(experts["tables_md"])
    policy_dir = out / "policy"
    if cfg.policy:
        ev = EvaluateConfig(
            policies=["gcs-open-loop", cfg.policy],
            num_initial_conditions=cfg.policy_ics,
            runs=1,
            output_dir=str(policy_dir),
            timeout_s=60.0,
            **cfg.fan_out(),
            device=cfg.device,
            videos=cfg.policy_ics,
            overwrite=overwrite,
        )
        if not overwrite and changed_weights(ev, unrecorded_changed=True):
            print(f"{cfg.policy} changed since the last demo: its runs in {policy_dir} are made again")
            ev = replace(ev, overwrite=True)
        print(evaluate(ev)["tables_md"])
        labels = [variant_label(p, False) for p in ev.policies]
        for i in range(cfg.policy_ics):
            side_by_side(
                [video_path(policy_dir, label, i) for label in labels],
                ["GCS", "diffusion policy"],
                policy_dir / f"side_by_side_ic{i:03d}.mp4",
                gif=policy_dir / f"side_by_side_ic{i:03d}.gif" if i == 0 else None,
            )
    print(f"\ndataset:        {root}")
    print(f"GCS experts:    {experts_dir}/tables.md, figures beside it")
    if cfg.policy:
        print(f"learned policy: {policy_dir}/tables.md; watch {policy_dir}/side_by_side_ic000.mp4")
    print(
        "train a policy on the dataset (CPU preset):\n"
        f"  lerobot-train --config_path={shipped_path('configs/policy/diffusion_cpu.json')} "
        f"--dataset.repo_id={cfg.output.repo_id}" + (f" --dataset.root={root}" if cfg.output.root else "")
    )


def run_train(cfg: TrainKeypointsConfig) -> None:
    from lerobot_gcs_push.pusht.keypoint_training import train

    folder = train(cfg)
    print(f"saved {folder}; judge it with:")
    print(
        f"  lerobot-eval --policy.path={folder} --env.type=pusht --env.obs_type=environment_state_agent_pos "
        "--eval.n_episodes=100 --eval.batch_size=10 --eval.use_async_envs=false --policy.device=cpu"
    )


COMMANDS: dict[str, tuple[type, Callable, str]] = {
    "plan": (PlanConfig, run_plan, "plan one push task (or a file of them) with GCS"),
    "generate": (GenerateConfig, run_generate, "write GCS demonstrations as a LeRobotDataset (PushT: lerobot/pusht's)"),
    "evaluate": (EvaluateConfig, run_evaluate, "the paper's protocol, with regret, for any set of policies"),
    "collect": (CollectConfig, run_collect, "active data: label the states a policy visited with the expert"),
    "improve": (ImproveConfig, run_improve, "rounds of active data until the policy is robust (resumable)"),
    "train": (TrainKeypointsConfig, run_train, "a keypoint DiffusionPolicy for gym-pusht on a CPU, from replay lists"),
    "demo": (DemoConfig, run_demo, "the main job on its defaults"),
}


def _usage() -> str:
    lines = ["usage: gcs-push COMMAND [--config_path=FILE] [--field=value ...]", "", "commands:"]
    lines += [f"  {name:<10} {help_}" for name, (_, _, help_) in COMMANDS.items()]
    lines += ["", "gcs-push COMMAND --help lists the command's fields."]
    return "\n".join(lines)


def _root_cause(err: BaseException) -> BaseException:
    # `raise ... from None` marks a message written for the user: stop there, not at its inner error.
    while err.__cause__ is not None or (err.__context__ is not None and not err.__suppress_context__):
        err = err.__cause__ or err.__context__
    return err


def parse(command: str, args: list[str]):
    """The command's config from its flags (flat, `--seed=3`, or nested, `--starts.seed=3`), validated; a bad
    flag or value raises a ValueError (or FileNotFoundError) whose message names the field."""
    import draccus

    config_class = COMMANDS[command][0]
    # draccus wraps a config's own ValueError (from __post_init__) in a ParsingError: show the cause.
    try:
        return draccus.parse(config_class, args=flat_argv(config_class, args), prog=f"gcs-push {command}")
    except draccus.utils.DecodingError as err:  # names the field: "`runs`: Couldn't parse 'many' into an int"
        raise ValueError(str(err)) from None
    except draccus.utils.ParsingError as err:
        cause = _root_cause(err)
        raise (cause if isinstance(cause, (ValueError, FileNotFoundError)) else ValueError(str(cause))) from None


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in COMMANDS:
        asked = argv[:1] in (["-h"], ["--help"])
        print(_usage(), file=sys.stdout if asked else sys.stderr)
        if argv and not asked:
            print(f"\nerror: unknown command {argv[0]!r}", file=sys.stderr)
        return 0 if asked else 2
    try:
        cfg = parse(argv[0], argv[1:])
        COMMANDS[argv[0]][1](cfg)
    except (ValueError, FileNotFoundError, FileExistsError, RuntimeError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
