"""Issue 48, the demonstration-count table: diffusion policies on 206 / 500 / 1000 optimal gym-pusht
demonstrations, demonstrations only, equal training steps, in stages that survive a fresh machine.

    python experiments/pusht/count_table.py dataset 206   # rebuild local/gcs_pusht_206 from the replay lists
    python experiments/pusht/count_table.py train 206     # train (or resume) to STEPS; kill it any time

Every choice here was fixed on 2026-12-05 before any policy trained: the pool is the replay lists in
`demos/` in seed order (4800, 4801, 4802, 4803), a count takes its first N episodes; the preset is
`configs/policy/diffusion_pusht_cpu.json` (the box's CPU preset on lerobot/pusht's features); every count
trains STEPS steps with seed 1000. Training exports an fp16 copy of each checkpoint (every 500 steps) to
`base_<N>/partial`, the small state a fresh machine resumes from (`lerobot_gcs_push.training`): commit it
at the end of a session. The datasets are rebuilt from the lists with no planning.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
SEEDS = (4800, 4801, 4802, 4803)
COUNTS = (206, 500, 1000)
STEPS = 8000
SEED = 1000
PRESET = REPO / "configs" / "policy" / "diffusion_pusht_cpu.json"


def repo_id(n: int) -> str:
    return f"local/gcs_pusht_{n}"


def pool_list(n: int) -> Path:
    """The first `n` episodes of the pool as one replay list (in outputs/, rebuilt, never committed)."""
    entries = []
    for seed in SEEDS:
        path = HERE / "demos" / f"seed{seed}.json"
        if len(entries) >= n:
            break
        if not path.is_file():
            raise SystemExit(f"{path} is missing: the pool has {len(entries)} episodes, {n} asked")
        entries += json.loads(path.read_text())
    if len(entries) < n:
        raise SystemExit(f"the pool has {len(entries)} episodes, {n} asked")
    out = REPO / "outputs" / "pusht" / f"pool_{n}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(entries[:n]))
    return out


def dataset(n: int) -> None:
    from lerobot_gcs_push.generate import lerobot_home

    if (lerobot_home() / repo_id(n) / "meta" / "info.json").is_file():
        print(f"{repo_id(n)} is there")
        return
    gcs_push = Path(sys.executable).parent / "gcs-push"
    cmd = [str(gcs_push), "generate", "--env_id=gym_pusht/PushT-v0", f"--initial_conditions={pool_list(n)}"]
    subprocess.run([*cmd, f"--repo_id={repo_id(n)}", "--workers=2", "--resume=true"], check=True)


def train(n: int) -> Path:
    from lerobot_gcs_push.training import TrainJob
    from lerobot_gcs_push.training import train as run

    dataset(n)
    job = TrainJob(
        config_path=str(PRESET),
        dataset_repo_id=repo_id(n),
        output_dir=REPO / "outputs" / "pusht" / f"train_{n}",
        steps=STEPS,
        seed=SEED,
        partial=HERE / f"base_{n}" / "partial",
    )
    final = run(job, progress_desc=f"base {n}")
    print(final)
    return final


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in ("dataset", "train") or int(sys.argv[2]) not in COUNTS:
        raise SystemExit(f"usage: count_table.py dataset|train {'|'.join(map(str, COUNTS))}")
    {"dataset": dataset, "train": train}[sys.argv[1]](int(sys.argv[2]))
