"""Ray's overhead and the merge's cost: the same demonstrations with the process pool and with a local Ray on
the same cores, side by side in one run, then LeRobot's aggregation of the shards (issue #19).

Each wall time counts everything a user waits for: starting the workers (and Ray), the rollouts, the shards'
writing and their merge. `merge_at_scale_*` merges the finished dataset with itself `copies` times, to see the
merge's cost per shard once the merged data file has grown (LeRobot rewrites it on every append, up to 100 MB).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path


def run(episodes: int = 100, workers: int = 2, shard_size: int = 10, copies: int = 10) -> dict:
    from lerobot_gcs_push.generate import GenerateConfig, generate
    from lerobot_gcs_push.generate.frames import _batched_image_embedding

    out: dict[str, float] = {"episodes": float(episodes), "workers": float(workers), "shard_size": float(shard_size)}
    reports = {}
    with tempfile.TemporaryDirectory() as tmp:
        for backend in ("process", "ray"):
            cfg = GenerateConfig(
                episodes=episodes,
                repo_id=f"bench/ray_{backend}",
                root=str(Path(tmp) / backend),
                workers=workers,
                shard_size=shard_size,
                backend=backend,
                progress=False,
            )
            reports[backend] = report = generate(cfg)
            out[f"{backend}_wall_time_s"] = report.wall_time_s
            out[f"{backend}_demonstrations_per_min"] = report.episodes_per_min
            out[f"{backend}_merge_s_per_shard"] = report.merge_time_s / report.shards
        out["ray_over_process_time_ratio"] = reports["ray"].wall_time_s / reports["process"].wall_time_s
        out["shards"] = float(reports["process"].shards)
        out["merge_s_per_shard"] = sum(r.merge_time_s for r in reports.values()) / sum(
            r.shards for r in reports.values()
        )
        out["merge_frac_of_wall_time"] = reports["process"].merge_time_s / reports["process"].wall_time_s
        out["merge_s_per_episode"] = reports["process"].merge_time_s / episodes
        if copies > 1:
            seconds = _merge_copies(
                Path(reports["process"].root), Path(tmp) / "copies", copies, _batched_image_embedding
            )
            out["merge_at_scale_episodes"] = float(episodes * copies)
            out["merge_at_scale_s"] = seconds
            out["merge_at_scale_s_per_episode"] = seconds / (episodes * copies)
        out["failures"] = float(reports["process"].failures)
    return out


def _merge_copies(root: Path, dest: Path, copies: int, batched) -> float:
    from lerobot.datasets.aggregate import aggregate_datasets

    t0 = time.perf_counter()
    with batched():  # as generate() merges
        aggregate_datasets(["bench/copy"] * copies, "bench/copies", roots=[root] * copies, aggr_root=dest)
    return time.perf_counter() - t0


if __name__ == "__main__":
    import argparse
    import json

    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--shard-size", type=int, default=10)
    ap.add_argument("--copies", type=int, default=10)
    args = ap.parse_args()
    print(json.dumps(run(args.episodes, args.workers, args.shard_size, args.copies), indent=1))
