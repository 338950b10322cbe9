"""Open-loop action error of checkpoints on demonstration frames: does the policy learn at all, and how
fast? Closed-loop success can stay at zero for a long while; this error falls as soon as the policy
starts to read the box off the image.

For `--frames` random frames of the dataset (fixed seed, frames with a full chunk of 8 future actions in
their episode), each checkpoint predicts a chunk from that frame's image and finger position, the way
`gcs-push evaluate` runs it (LeRobot processors, `select_action` from an empty queue); the error is the
mean distance in metres between the 8 executed actions and the expert's. Baseline: holding the finger
still (action = current finger position). Writes <run dir>/offline_error.csv.

    .venv/bin/python results/train/offline_error.py results/train/run2_nocrop outputs/train/gcs_push_diffusion_cpu_v2
"""

import argparse
import csv
import os
from pathlib import Path

import numpy as np

os.environ.setdefault("HF_HUB_OFFLINE", "1")
EXECUTED = 8

parser = argparse.ArgumentParser()
parser.add_argument("run_dir", type=Path)
parser.add_argument("train_dir", type=Path)
parser.add_argument("--frames", type=int, default=100)
parser.add_argument("--repo-id", default="local/gcs_push_box")
# Frames are drawn from the first N episodes only: the datasets share their first episodes (same Sobol
# sequence and episode seeds), so --first-episodes 200 on a larger dataset draws the same 100 frames as
# the default 200-demonstration dataset, and errors stay comparable across runs.
parser.add_argument("--first-episodes", type=int, default=None)
args = parser.parse_args()

import torch  # noqa: E402
from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: E402

from lerobot_gcs_push.evaluation import LearnedPolicy  # noqa: E402
from lerobot_gcs_push.scene import TASK  # noqa: E402

torch.set_num_threads(1)
ds = LeRobotDataset(args.repo_id)
ends = np.asarray(ds.meta.episodes["dataset_to_index"])[: args.first_episodes]
starts = np.asarray(ds.meta.episodes["dataset_from_index"])[: args.first_episodes]
valid = np.concatenate([np.arange(s, e - EXECUTED) for s, e in zip(starts, ends)])
rng = np.random.default_rng(0)
frames = np.sort(rng.choice(valid, size=args.frames, replace=False))
items = [ds[int(i)] for i in frames]
targets = [np.stack([ds[int(i) + k]["action"].numpy() for k in range(EXECUTED)]) for i in frames]
hold = float(
    np.mean([np.linalg.norm(t - it["observation.state"].numpy(), axis=1).mean() for t, it in zip(targets, items)])
)

out = args.run_dir / "offline_error.csv"
rows = []
if out.exists():  # checkpoints already measured are kept, not measured again
    with open(out) as f:
        rows = [{k: (int(v) if k in ("step", "frames") else float(v)) for k, v in r.items()} for r in csv.DictReader(f)]
done = {r["step"] for r in rows}
for ckpt in sorted((args.train_dir / "checkpoints").glob("[0-9]*")):
    if int(ckpt.name) in done:
        continue
    learned = LearnedPolicy(str(ckpt / "pretrained_model"), "cpu")
    errors = []
    for n, (item, target) in enumerate(zip(items, targets)):
        torch.manual_seed(n)
        learned.policy.reset()
        batch = {
            "observation.image": item["observation.image"][None],
            "observation.state": item["observation.state"][None],
            "task": [TASK],
        }
        chunk = []
        with torch.inference_mode():
            for _ in range(EXECUTED):  # the first call denoises a chunk, the next ones pop it
                chunk.append(
                    learned.post(learned.policy.select_action(learned.pre(dict(batch)))).reshape(-1)[:2].numpy()
                )
        errors.append(np.linalg.norm(np.stack(chunk) - target, axis=1).mean())
    rows.append(
        {
            "step": int(ckpt.name),
            "frames": len(errors),
            "action_error_m_mean": float(np.mean(errors)),
            "action_error_m_median": float(np.median(errors)),
            "hold_baseline_m": hold,
        }
    )
    print(rows[-1], flush=True)
rows.sort(key=lambda r: r["step"])
with open(out, "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
