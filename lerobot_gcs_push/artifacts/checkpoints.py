"""Ship a LeRobot `pretrained_model` directory in half precision, loadable as it is.

A CPU-preset checkpoint is 63 MB in fp32; in 16-bit floats it is 32 MB, small enough to keep every
headline policy in git, so that it survives a fresh machine and needs no unpack step:
`lerobot-eval --policy.path=DIR` and `gcs-push evaluate --policies='[DIR]'` load it directly (PyTorch's
`load_state_dict` casts the stored tensors to the model's fp32 parameters).

fp16 rather than bf16: the weights of this network all lie well inside fp16's range, where its 10-bit
mantissa keeps three more bits than bf16's (the test suite checks the actions against fp32).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

MODEL_FILE = "model.safetensors"
CONFIG_FILE = "config.json"
TRAIN_CONFIG_FILE = "train_config.json"
# A training partial's bookkeeping (its step), written only by `export_policy(..., step=)`: a policy copied
# from a partial does not carry it, so it is never mistaken for a partial to resume.
STEP_FILE = "step.json"
DTYPES = ("float16", "bfloat16", "float32")


def is_pretrained_dir(path) -> bool:
    path = Path(path)
    return (path / CONFIG_FILE).is_file() and (path / MODEL_FILE).is_file()


def export_policy(src, dst, dtype: str = "float16", overwrite: bool = False, step: int | None = None) -> Path:
    """Write `src` (a `pretrained_model` directory) to `dst` with its floating-point weights in `dtype`.

    The processors' statistics and the config are copied unchanged, except that the config forgets the
    path it was fine-tuned from (a path on the machine that trained it) and its training-time `use_amp`.
    `dst` appears whole or not at all: it is written beside itself and renamed into place. With `step`,
    `dst` is a training partial and records it in STEP_FILE; a STEP_FILE in `src` is never copied.
    """
    import torch
    from safetensors.torch import load_file, save_file

    src, dst = Path(src), Path(dst)
    if dtype not in DTYPES:
        raise ValueError(f"dtype must be one of {DTYPES}, got {dtype!r}")
    if not is_pretrained_dir(src):
        raise FileNotFoundError(
            f"{src} is not a LeRobot pretrained_model directory (needs {CONFIG_FILE} and {MODEL_FILE})"
        )
    if dst.exists() and not overwrite:
        raise FileExistsError(f"{dst} exists: pass overwrite=True to replace it")
    target = getattr(torch, dtype)
    tensors = {
        k: (v.to(target) if v.is_floating_point() else v).contiguous() for k, v in load_file(src / MODEL_FILE).items()
    }
    dst.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix="." + dst.name + ".", dir=dst.parent))
    staging.chmod(0o755)
    try:
        for f in src.iterdir():
            if f.is_file() and f.name not in (MODEL_FILE, TRAIN_CONFIG_FILE, STEP_FILE):
                shutil.copy2(f, staging / f.name)
        save_file(tensors, staging / MODEL_FILE, metadata={"format": "pt", "dtype": dtype})
        config = json.loads((src / CONFIG_FILE).read_text())
        config["pretrained_path"] = None
        # Its numbers are measured with fp32 inference (`gcs-push evaluate`); lerobot-eval would autocast
        # a `use_amp` policy to bf16 on CPU. Fine-tuning turns it back on with --policy.use_amp=true.
        config["use_amp"] = False
        (staging / CONFIG_FILE).write_text(json.dumps(config, indent=4) + "\n")
        if step is not None:
            (staging / STEP_FILE).write_text(json.dumps({"step": int(step)}) + "\n")
        # The old directory steps aside before the new one moves in: a kill between the two moves leaves
        # the old policy whole at .<name>.old, never a half-written one at <name>.
        old = dst.with_name("." + dst.name + ".old")
        if dst.exists():
            shutil.rmtree(old, ignore_errors=True)
            os.replace(dst, old)
        os.replace(staging, dst)
        shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return dst
