"""Demonstrations per minute: plan, roll out, record and write a LeRobotDataset (issue target: 100
demonstrations in at most 2 minutes with 2 workers; the paper: 100 x 126 s of planning)."""

from __future__ import annotations

import tempfile
from pathlib import Path


def run(episodes: int = 100, workers: int = 2) -> dict:
    from lerobot_gcs_push.generate import GenerateConfig, generate

    with tempfile.TemporaryDirectory() as tmp:
        report = generate(
            GenerateConfig(
                episodes=episodes,
                repo_id="bench/gcs_push_box",
                root=str(Path(tmp) / "ds"),
                workers=workers,
                progress=False,
            )
        )
    return {
        "episodes": float(report.episodes),
        "workers": float(workers),
        "wall_time_s": report.wall_time_s,
        "demonstrations_per_min": report.episodes_per_min,
        "frames_per_s": report.frames / report.wall_time_s,
        "failures": float(report.failures),
        "paper_planning_time_for_100_s": 100 * 126.07,
    }
