"""The learnability benchmark (issue 65): what LeRobot's DiffusionPolicy learns from a pool of gym-pusht
demonstrations, on keypoints, at a fixed budget. A dataset exporter is judged by what policies learn from it.

- The model: `configs/policy/diffusion_pusht_keypoints.json` (LeRobot's DiffusionPolicy on
  `environment_state_agent_pos`), trained as `gcs-push train --config_path=configs/train/pusht_keypoints.json`
  trains it (`lerobot_gcs_push.pusht.keypoint_training`), on one thread.
- The data: the pool's first 1000 demonstrations, rebuilt from its replay lists (no planning).
- The budget: 1.28 M samples (20,000 steps of 64), seed 1000.
- The judge: `lerobot-eval --env.type=pusht --env.obs_type=environment_state_agent_pos`, 100 episodes of seed
  JUDGE_SEED (fixed on 2026-12-07 before any run; no other choice uses it).

About 1.5 hours on a quiet core, so it runs in stages: each ends after `--stage_minutes`, its small state
(fp16 weights, EMA and Adam's second moments) in `experiments/pusht/learnability/v2/<pool>/partial` to commit;
the same command on any machine goes on from there, and judges once the budget is spent.

    python -m benchmarks.run --only learnability                      # the default pool, to the end
    python -m benchmarks.learnability --pool=position --stage_minutes=60
    python -m benchmarks.learnability --pool=position --validation_seed=12100   # its finished policy, again

The same command after the budget is spent judges the saved policy again (a judge cut short loses nothing).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
DEMOS = REPO / "experiments" / "pusht" / "demos"
SEEDS = (4800, 4801, 4802, 4803)  # every pool's starts: gym-pusht's resets of these seeds, 250 each
POSITION = [DEMOS / "position" / f"seed{s}.json" for s in SEEDS]


@dataclass(frozen=True)
class Pool:
    """A pool's replay lists in order (the benchmark takes their first `episodes`), how its labels are read
    (`KeypointDataConfig.label_shift`, `hold_frames`), and the peak learning rate when a variant tests the
    schedule rather than the data (None: the preset's)."""

    lists: list
    episodes: int = 1000
    label_shift: int = 0
    hold_frames: int = 0
    lr: float | None = None
    down_dims: tuple | None = None  # the UNet's channels (None: the preset's 64/128/256)


POOLS = {
    # The expert steered over one action (inverting gym-pusht's PD), 2026-12-05: base 1000's pool.
    "steer1": Pool([DEMOS / f"seed{s}.json" for s in SEEDS]),
    # Position commands (`ExpertConfig.commands="position"`, lead 3 actions), 2026-12-07.
    "position": Pool(POSITION),
    # The same states, each frame labelled with the command 1 or 2 frames later: a proxy for leads 4 and 5
    # (v1's one-frame-early windows were shift 1).
    "position_shift1": Pool(POSITION, label_shift=1),
    "position_shift2": Pool(POSITION, label_shift=2),
    # The same demonstrations, each followed by 10 frames in which the agent is held where it was at the
    # success: what stopping at the goal looks like (the v2 policy's rollouts push the T past it).
    "position_hold10": Pool(POSITION, hold_frames=10),
    # The best data so far (shift 1) at three times the preset's peak learning rate: whether 1.28 M samples
    # leave the small UNet under-trained (the schedule, not the data).
    "position_shift1_lr3e-4": Pool(POSITION, label_shift=1, lr=3e-4),
    # Shift 1's data on a UNet of 128/256/512 (16.6 M weights, 3.7x the preset's): whether the near misses are
    # the small model's precision (the model, not the data or the schedule).
    "position_shift1_unet128": Pool(POSITION, label_shift=1, down_dims=(128, 256, 512)),
    # The expert leading by 4 actions, with DART's 4 px of command noise (labels clean), 2026-12-07.
    "lead4_dart4": Pool([DEMOS / "lead4_dart4" / f"seed{s}.json" for s in SEEDS]),
    # The expert leading by 4 actions, each demonstration going on past gym-pusht's success until the T covers
    # 0.98 of the goal, or 60 frames after it (`generate --finish_coverage`): the judges' near misses.
    "lead4_finish98": Pool([DEMOS / "lead4_finish98" / f"seed{s}.json" for s in SEEDS]),
    # The expert's last push arriving at 0.15 m/s over its last 0.1 m (`--expert.arrive`), read as shift 1
    # reads the position pool: one change against position_shift1, the T's arrival speed.
    "arrive_shift1": Pool([DEMOS / "position_arrive15" / f"seed{s}.json" for s in SEEDS], label_shift=1),
    # Aggregated as DAgger does: the position pool and takeover round 1's 350 demonstrations from the v2
    # position policy's stall states (`experiments/pusht/takeover/round.sh`).
    "position_takeover1": Pool([*POSITION, DEMOS / "takeover" / "r1.json"], episodes=1350),
}
DEFAULT_POOL = "position"
STEPS, BATCH, SEED = 20000, 64, 1000
JUDGE_SEED, JUDGE_EPISODES = 12000, 100
# v2 (2026-12-07): the trainer's action chunks start at the first observed frame, as LeRobot's do (v1's
# started a frame later, so the policy ran each action one frame early); v1's records stay in git history.
VERSION = "v2"
OUT = REPO / "experiments" / "pusht" / "learnability" / VERSION
CONFIG = REPO / "configs" / "train" / "pusht_keypoints.json"


def folder(pool: str) -> Path:
    return OUT / pool


def train_config(pool: str, steps: int = STEPS, episodes: int | None = None, work=None, threads: int = 1):
    """`configs/train/pusht_keypoints.json` (what `gcs-push train` runs) on the pool's lists, its state in
    the pool's folder."""
    import draccus

    from lerobot_gcs_push.pusht.keypoint_training import TrainKeypointsConfig

    work = Path(work or REPO / "outputs" / "learnability" / VERSION / pool)
    raw = json.loads(CONFIG.read_text())
    spec = POOLS[pool]
    raw["data"] |= {"lists": [str(p) for p in spec.lists], "episodes": episodes or spec.episodes,
                    "cache_dir": str(REPO / "outputs" / "keypoints"), "label_shift": spec.label_shift,
                    "hold_frames": spec.hold_frames}  # fmt: skip
    raw["schedule"] |= {"steps": steps, "batch_size": BATCH} | ({"lr": spec.lr} if spec.lr is not None else {})
    if spec.down_dims is not None:
        raw["model"] = {"down_dims": list(spec.down_dims)}
    raw |= {"preset": str(REPO / raw["preset"]), "output_dir": str(work / "train"),
            "partial_dir": str(folder(pool) / "partial"), "seed": SEED, "threads": threads}  # fmt: skip
    return draccus.decode(TrainKeypointsConfig, raw)


def judge(policy_dir: Path, out: Path, seed: int = JUDGE_SEED, episodes: int = JUDGE_EPISODES,
          overrides: tuple[str, ...] = ()) -> dict:  # fmt: skip
    """`lerobot-eval` on gym-pusht's keypoints: success, average max reward and sum reward. `overrides` are
    more `lerobot-eval` arguments (`--policy.num_inference_steps=100`: a sampler probe)."""
    cmd = [
        str(Path(sys.executable).parent / "lerobot-eval"), f"--policy.path={policy_dir}", "--env.type=pusht",
        "--env.obs_type=environment_state_agent_pos", f"--eval.n_episodes={episodes}", "--eval.batch_size=10",
        "--eval.use_async_envs=false", f"--seed={seed}", "--policy.device=cpu", f"--output_dir={out}", *overrides,
    ]  # fmt: skip
    t0 = time.perf_counter()
    # One thread, as the trainer: beside another job on 2 cores, torch's two threads waiting on each other
    # made a 2-minute judge run at 1 step a second (2026-12-07).
    subprocess.run(cmd, check=True, env={**os.environ, "HF_HUB_OFFLINE": "1", "OMP_NUM_THREADS": "1"})
    overall = json.loads((out / "eval_info.json").read_text())["overall"]
    return {
        "command": " ".join(cmd[1:]),
        "success": overall["pc_success"] / 100,
        "avg_max_reward": overall["avg_max_reward"],
        "avg_sum_reward": overall["avg_sum_reward"],
        "judge_episodes": overall["n_episodes"],
        "eval_s": round(time.perf_counter() - t0, 1),
    }


def run(pool: str = DEFAULT_POOL, stage_minutes: float | None = None, steps: int = STEPS,
        episodes: int | None = None, judge_episodes: int = JUDGE_EPISODES, threads: int = 1) -> dict:  # fmt: skip
    """Train the pool's policy to the budget (or for one stage), then judge it; the record lands in
    `experiments/pusht/learnability/v2/<pool>/result.json`."""
    from lerobot_gcs_push.pusht.keypoint_training import train

    cfg = train_config(pool, steps, episodes, threads=threads)
    folder(pool).mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    saved = train(cfg, stop_after_s=None if stage_minutes is None else 60 * stage_minutes)
    log = [json.loads(line) for line in (Path(cfg.output_dir) / "log.jsonl").read_text().splitlines() if line]
    stage = {"pool": pool, "stage_s": round(time.perf_counter() - t0, 1), "step": log[-1]["step"] if log else 0}
    if saved is None:
        return stage | {"status": "stage ended: run the same command again to go on"}
    result = {
        "pool": pool,
        "lists": [str(p.relative_to(REPO)) for p in POOLS[pool].lists],
        "episodes": cfg.data.episodes,
        "label_shift": cfg.data.label_shift,
        "hold_frames": cfg.data.hold_frames,
        "lr": cfg.schedule.lr,  # None: the preset's
        "down_dims": cfg.model.down_dims,  # None: the preset's
        "threads": threads,
        "steps": steps,
        "batch_size": BATCH,
        "samples": steps * BATCH,
        "loss_last": log[-1]["loss"],
        "s_per_step_last_stage": log[-1]["s_per_step"],
        "judge_seed": JUDGE_SEED,
    }
    result |= judge(saved, Path(cfg.output_dir).parent / "judge", episodes=judge_episodes)
    (folder(pool) / "result.json").write_text(json.dumps(result, indent=1))
    return result


def validate(pool: str, seed: int, episodes: int = JUDGE_EPISODES) -> dict:
    """The pool's finished policy judged again on a validation seed (never the judge's own), recorded in
    `experiments/pusht/learnability/v2/<pool>/validation<seed>.json`."""
    if seed == JUDGE_SEED:
        raise ValueError(f"seed {seed} is the benchmark's judge; a validation seed is another one")
    saved = Path(train_config(pool).output_dir) / "pretrained_model"
    if not (saved / "model.safetensors").is_file():
        raise FileNotFoundError(f"{saved}: no finished policy; run --pool={pool} to its end first")
    record = judge(saved, saved.parent.parent / f"judge{seed}", seed=seed, episodes=episodes)
    (folder(pool) / f"validation{seed}.json").write_text(json.dumps(record, indent=1))
    return record


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pool", default=DEFAULT_POOL, choices=sorted(POOLS))
    ap.add_argument("--stage_minutes", type=float, default=None, help="end this stage after so many minutes")
    ap.add_argument("--validation_seed", type=int, default=None,
                    help="judge the pool's finished policy on this seed instead (validation<seed>.json)")  # fmt: skip
    ap.add_argument("--threads", type=int, default=1,
                    help="torch threads for training (a record without `threads` used 1)")  # fmt: skip
    args = ap.parse_args(argv)
    if args.validation_seed is not None:
        print(json.dumps(validate(args.pool, args.validation_seed), indent=1))
    else:
        print(json.dumps(run(args.pool, args.stage_minutes, threads=args.threads), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
