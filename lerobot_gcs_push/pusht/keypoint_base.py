"""A trained keypoint policy as the start of a fine-tune (`TrainKeypointsConfig.init_from`): its model config,
its weights, and the normalisation statistics its saved preprocessor holds.

The statistics are the base's, not the new data's: the weights learned inputs and actions on the base's
[-1, 1] scale, and takeover data (the policy's own stall states, the expert's pushes from there) has other
extremes; renormalised, every input the weights know would move.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lerobot_gcs_push.pusht.keypoint_data import KEYS


def check_base(folder) -> Path:
    """`folder` if it is a LeRobot pretrained_model folder of a keypoint diffusion policy."""
    import json

    from lerobot_gcs_push.artifacts.checkpoints import is_pretrained_dir

    folder = Path(folder)
    if not is_pretrained_dir(folder):
        raise FileNotFoundError(f"init_from: {folder} is no pretrained_model folder (config.json, model.safetensors)")
    cfg = json.loads((folder / "config.json").read_text())
    have = set(cfg.get("input_features", {})) | set(cfg.get("output_features", {}))
    if cfg.get("type") != "diffusion" or have != set(KEYS):
        raise ValueError(f"init_from: {folder} is not a keypoint diffusion policy (it reads {sorted(have)})")
    return folder


def base_config(folder):
    """The base's DiffusionConfig: its weights fix the architecture, whatever the preset says."""
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig  # noqa: F401  (registers it)

    return PreTrainedConfig.from_pretrained(str(check_base(folder)))


def base_weights(folder) -> dict:
    """The base's saved weights (the EMA it exported), as fp32 tensors (a base kept in fp16 included)."""
    from safetensors.torch import load_file

    tensors = load_file(check_base(folder) / "model.safetensors")
    return {k: v.float() if v.is_floating_point() else v for k, v in tensors.items()}


def base_stats(folder) -> dict[str, dict[str, np.ndarray]]:
    """The statistics of the base's saved normaliser (what `keypoint_training.stats_of` gave it), read through
    LeRobot's own processor loading."""
    from lerobot.policies.factory import make_pre_post_processors
    from lerobot.processor import NormalizerProcessorStep

    pre, _ = make_pre_post_processors(None, pretrained_path=str(check_base(folder)))
    step = next(s for s in pre.steps if isinstance(s, NormalizerProcessorStep))
    missing = [k for k in KEYS if k not in step.stats]
    if missing:
        raise ValueError(f"init_from: {folder}'s normaliser has no statistics of {missing}")
    return {k: {s: np.asarray(v, np.float32) for s, v in step.stats[k].items()} for k in KEYS}
