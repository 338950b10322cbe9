"""Pushing a finished dataset to the Hugging Face Hub (the one place that needs the network)."""

from __future__ import annotations

import os
from pathlib import Path


def check_online() -> None:
    # `gcs-push` sets HF_HUB_OFFLINE=1 unless the caller set it, so the way out is to set it to 0.
    if os.environ.get("HF_HUB_OFFLINE", "0") not in ("0", "", "false", "False"):
        raise ValueError(
            "push_to_hub needs the network, but HF_HUB_OFFLINE is on: run with HF_HUB_OFFLINE=0, after `hf auth login`"
        )


def push_to_hub(repo_id: str, root: Path) -> None:
    """LeRobot's own upload; fails clearly without a network or a token."""
    check_online()
    from huggingface_hub import get_token
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    if not get_token():
        raise RuntimeError("push_to_hub needs a Hugging Face token: run `hf auth login` or set HF_TOKEN")
    LeRobotDataset(repo_id, root=root).push_to_hub()
