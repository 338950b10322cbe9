"""Active data: the GCS expert labels the states a learned policy visits (DAgger with an optimal expert).

A round is four resumable steps:

1. `gcs-push evaluate --policies='[POLICY]' --sampler=hard ...` rolls the policy out and scores every executed
   chunk against the GCS cost-to-go (`regret_chunks` in `runs.jsonl`);
2. `gcs-push collect --rollouts='[DIR]' ...` (this module) picks branch states along those rollouts (every
   chunk start of large regret, and a seeded fraction of the others; for a slider that turns, which has no
   cost-to-go, the chunk starts where coverage stalls, `stalls.py`) and runs the closed-loop GCS expert
   from each to the goal, recorded as a LeRobotDataset like any other (`dataset.generate`);
3. LeRobot merges it with earlier data (`lerobot-edit-dataset --operation.type=merge`);
4. `lerobot-train --policy.path=POLICY` fine-tunes on the merge.

The expert starts from the policy's own states, so the images it is recorded with are the ones the
policy will meet; its action chunks are what the policy should have done there.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from lerobot_gcs_push.box_gcs import plannable
from lerobot_gcs_push.episodes.workers import FanOut
from lerobot_gcs_push.evaluation import GCS_POLICIES, read_runs
from lerobot_gcs_push.evaluation.learned import PIXELS_OBS
from lerobot_gcs_push.files import atomic_path
from lerobot_gcs_push.generate import GenerateConfig, GenerateReport, dataset_root, generate
from lerobot_gcs_push.generate.config import OutputConfig
from lerobot_gcs_push.improve.stalls import StallRule, stall_branch_states
from lerobot_gcs_push.planning.factory import check_cost_to_go
from lerobot_gcs_push.registration import ENV_ID, SCENES
from lerobot_gcs_push.scene import Scene
from lerobot_gcs_push.settings import flat_options


@flat_options
@dataclass
class CollectConfig(FanOut):
    # `gcs-push evaluate` output folders of the policy to correct, e.g. '[outputs/active/r1/rollouts]'.
    rollouts: list[str] = field(default_factory=list)
    # The labelled states' dataset: --repo_id (default local/gcs_push_active), --root, --overwrite, --resume
    # (`--output.repo_id` works too).
    output: OutputConfig = field(default_factory=OutputConfig)
    # Chunk starts above these regrets are branched from: any mistake of a successful run; in a failed
    # run also the slower drift (a wrong-face push costs a few decimetres a chunk). The GCS experts'
    # own chunks stay under 0.5 m, so neither picks noise.
    large_regret_m: float = 0.5
    # The same, in a failed rollout.
    failed_regret_m: float = 0.25
    keep_fraction: float = 0.05  # of the other chunk starts, for coverage of the policy's distribution
    # Of the states the expert can start from, spread over the run's time, so the decision and the drift
    # after it both count.
    max_per_run: int = 12
    # Metres between finger and box at a branch state (contact compliance, Drake's query).
    clearance: float = 0.02
    # A slider that turns has no cost-to-go to take regrets from: its branch states are where coverage
    # stalls or falls, in failed runs and in successes slower than the expert's (stalls.py).
    stall: StallRule = field(default_factory=StallRule)
    # Seeds the choice of the other chunk starts and the expert's episodes (collect's own: its starts are
    # the rollouts' states, not a sampler's).
    seed: int = 0

    def __post_init__(self) -> None:
        self.output.fill("local/gcs_push_active")
        if not self.rollouts:
            raise ValueError("give at least one --rollouts folder (written by `gcs-push evaluate`)")
        for r in self.rollouts:
            if not (Path(r) / "runs.jsonl").is_file():
                raise FileNotFoundError(f"{r} has no runs.jsonl: pass a `gcs-push evaluate` output folder")
        if not 0.0 <= self.keep_fraction <= 1.0:
            raise ValueError(f"keep_fraction must be in [0, 1], got {self.keep_fraction}")
        if self.max_per_run < 1:
            raise ValueError(f"max_per_run must be >= 1, got {self.max_per_run}")
        self.check_fan_out()
        from lerobot_gcs_push.scene import check_seed

        check_seed(self.seed)


def branch_states(records: list[dict], cfg: CollectConfig, scene: Scene | None = None) -> list[dict]:
    """The states to label, in a deterministic order: for each learned-policy run, its chunk starts of
    large regret and a seeded `keep_fraction` of the rest, at most `max_per_run` spread over time.

    States the expert cannot start from are left out: a box already at the goal, or one the policy
    pushed out of the box workspace (the env refuses such an initial condition).
    """
    scene = scene or Scene()
    out = []
    for rec in sorted(records, key=lambda r: (r["policy"], r["disturbances"], r["initial_condition_index"], r["run"])):
        if rec["policy"] in GCS_POLICIES or not rec.get("regret_chunks"):
            continue
        rng = np.random.default_rng([cfg.seed, rec["initial_condition_index"], rec["run"], int(rec["disturbances"])])
        chunks = np.array(rec["regret_chunks"], float)  # step, regret, box x, box y, finger x, finger y
        threshold = cfg.large_regret_m if rec["success"] else cfg.failed_regret_m
        keep = (np.nan_to_num(chunks[:, 1], nan=np.inf) > threshold) | (rng.random(len(chunks)) < cfg.keep_fraction)
        startable = []
        for step, regret, bx, by, fx, fy in chunks[keep]:
            box, finger = plannable(scene, [bx, by], [fx, fy], clearance=cfg.clearance)
            if scene.box_goal_distance(box) <= scene.success_threshold:
                continue
            try:  # the env's own checks: box and finger inside their workspaces, no overlap
                scene.validate_state(box, finger)
            except ValueError:
                continue
            startable.append((step, regret, box, finger))
        # Capped after the checks: a failed run that pinned the box outside its workspace (a corner box
        # pushed into the wall) spends its whole budget on the seconds before, where the mistake was made.
        if len(startable) > cfg.max_per_run:
            startable = [
                startable[i] for i in np.unique(np.linspace(0, len(startable) - 1, cfg.max_per_run).round().astype(int))
            ]
        for step, regret, box, finger in startable:
            out.append(
                {
                    "box": box.round(6).tolist(),
                    "finger": finger.round(6).tolist(),
                    "source": {
                        "rollouts": rec.get("_source", ""),
                        "label": rec["label"],
                        "initial_condition_index": rec["initial_condition_index"],
                        "run": rec["run"],
                        "step": int(step),
                        "regret": float(regret),
                        "run_success": rec["success"],
                    },
                }
            )
    return out


def rollouts_env_id(folders: list[str]) -> str:
    """The env the rollouts ran in (from each folder's settings.json; folders from before the env was
    recorded ran in the box's): the states to label are that env's, so the expert must act in it too."""
    ids = set()
    for folder in folders:
        path = Path(folder) / "settings.json"
        ids.add(json.loads(path.read_text()).get("env_id", ENV_ID) if path.is_file() else ENV_ID)
    if len(ids) > 1:
        raise ValueError(
            f"the rollouts {folders} ran in different envs ({', '.join(sorted(ids))}): collect one at a time"
        )
    return ids.pop()


def rollouts_obs_type(records: list[dict]) -> str:
    """The observations the learned policies of these rollouts saw (each record's `obs_type`; records from
    before it was recorded are an image policy's): the expert's demonstrations are recorded the same way,
    so a keypoint policy's takeover data holds keypoints (and its replay list), an image policy's images."""
    types = {rec.get("obs_type", PIXELS_OBS) for rec in records if rec["policy"] not in GCS_POLICIES}
    if len(types) > 1:
        raise ValueError(f"the rollouts hold policies that saw {' and '.join(sorted(types))}: collect one at a time")
    return types.pop() if types else PIXELS_OBS


def collect(cfg: CollectConfig) -> tuple[GenerateReport, list[dict]]:
    """Branch states from the rollouts, labelled by the closed-loop GCS expert, as a LeRobotDataset: chunks
    of large regret for the box, chunks where coverage stalls for a slider that turns."""
    env_id = rollouts_env_id(cfg.rollouts)
    scene = SCENES[env_id]
    records = []
    for folder in cfg.rollouts:
        for rec in read_runs(Path(folder) / "runs.jsonl"):
            records.append(rec | {"_source": str(folder)})
    if scene.kind.records_coverage:
        states = stall_branch_states(records, cfg, scene, GCS_POLICIES)
        why = "no failed or slow run of a learned policy with a stall to branch from"
    else:
        check_cost_to_go(env_id, "collect labels the policy's states with it")
        states = branch_states(records, cfg, scene)
        why = "did the evaluation record regret for a learned policy?"
    if not states:
        raise ValueError(f"no branch states in {cfg.rollouts}: {why}")
    gen = GenerateConfig(
        env_id=env_id,
        episodes=len(states),
        output=replace(cfg.output),  # a copy: generate fills in its own
        seed=cfg.seed,
        expert="closed-loop",
        obs_type=rollouts_obs_type(records),
        **cfg.fan_out(),
    )
    root = dataset_root(gen)
    # The list sits beside the dataset (kept for provenance), written whole before generation reads it.
    states_path = root.with_name(root.name + ".branch_states.json")
    text = json.dumps(states)
    if cfg.output.resume and states_path.exists():
        if states_path.read_text() != text:  # the states are the run's settings: other ones would mix lists
            raise ValueError(
                f"{states_path} holds the branch states of a collect with other rollouts or settings; "
                "--resume needs the same ones (or pass --overwrite=true, or choose another --repo_id)"
            )
    elif cfg.output.overwrite or not (root.exists() or root.with_name(root.name + ".work").exists()):
        with atomic_path(states_path) as tmp:
            tmp.write_text(text)
    # else generate() refuses the existing dataset or interrupted run, and their list stays as it was.
    gen.starts.initial_conditions = str(states_path)
    return generate(gen), states
