"""Carry a checkpoint across sessions in git: pack a `pretrained_model` directory into int8 (about 16 MB
instead of 61 MB, under the repository's 25 MB limit for weights) and unpack it back into a directory that
`lerobot-train --policy.path=...` and `gcs-push evaluate --policy ...` load as usual.

Why: every session starts on a fresh machine, the fp32 weights (61 MB) may not go into git, and rebuilding
them takes longer than a session. So training progress was lost between sessions.

Each weight matrix / convolution kernel is stored as int8 with one fp32 scale per output channel (symmetric,
scale = max |w| / 127, so the rounding error of any weight is at most scale / 2); small tensors (biases,
norms, anything under 4096 values) and non-float tensors are kept exactly. The unpacked weights are what gets
evaluated, so a packed checkpoint's numbers are measured on the packed weights themselves; run 5 checks the
cost on the action error (results/train/run5_scratch1200/packing.csv).

    .venv/bin/python experiments/scripts/weights_int8.py pack \
        outputs/train/X/checkpoints/005000/pretrained_model experiments/runs/run5_scratch1200/weights
    .venv/bin/python experiments/scripts/weights_int8.py unpack \
        experiments/runs/run5_scratch1200/weights outputs/train/run5_unpacked/pretrained_model
"""

import argparse
import shutil
import sys
from pathlib import Path

import torch
from safetensors.torch import load_file, save_file

MODEL = "model.safetensors"
PACKED = "model.int8.safetensors"
SCALE = ".__int8_scale"
MIN_NUMEL = 4096


def pack_tensors(tensors: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    out = {}
    for name, t in tensors.items():
        if name.endswith(SCALE):
            raise ValueError(f"tensor name {name!r} collides with the packing's scale suffix")
        if t.is_floating_point() and t.ndim >= 2 and t.numel() >= MIN_NUMEL:
            rows = t.detach().float().reshape(t.shape[0], -1)
            scale = rows.abs().amax(dim=1) / 127.0
            scale = torch.where(scale > 0, scale, torch.ones_like(scale))  # all-zero rows stay zero
            out[name] = torch.round(rows / scale[:, None]).clamp(-127, 127).to(torch.int8).reshape(t.shape)
            out[name + SCALE] = scale
        else:
            out[name] = t.contiguous()
    return out


def unpack_tensors(packed: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    out = {}
    for name, t in packed.items():
        if name.endswith(SCALE):
            continue
        scale = packed.get(name + SCALE)
        if scale is None:
            out[name] = t
        else:
            out[name] = (t.float().reshape(t.shape[0], -1) * scale[:, None]).reshape(t.shape).contiguous()
    return out


def _copy_dir(src: Path, dst: Path, skip: str) -> None:
    if not src.is_dir():
        sys.exit(f"not a directory: {src}")
    if dst.exists():
        sys.exit(f"{dst} exists; remove it first (nothing was written)")
    dst.mkdir(parents=True)
    for f in src.iterdir():
        if f.is_file() and f.name != skip:
            shutil.copy2(f, dst / f.name)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("action", choices=["pack", "unpack"])
    parser.add_argument("src", type=Path)
    parser.add_argument("dst", type=Path)
    args = parser.parse_args()
    if args.action == "pack":
        if not (args.src / MODEL).exists():
            sys.exit(f"{args.src / MODEL} not found: pass a checkpoint's pretrained_model directory")
        _copy_dir(args.src, args.dst, MODEL)
        save_file(pack_tensors(load_file(args.src / MODEL)), args.dst / PACKED, metadata={"format": "int8-per-row-v1"})
    else:
        if not (args.src / PACKED).exists():
            sys.exit(f"{args.src / PACKED} not found: pass a directory written by `pack`")
        _copy_dir(args.src, args.dst, PACKED)
        save_file(unpack_tensors(load_file(args.src / PACKED)), args.dst / MODEL)
    size = sum(f.stat().st_size for f in args.dst.iterdir()) / 1e6
    print(f"{args.action}ed {args.src} -> {args.dst} ({size:.1f} MB)")


if __name__ == "__main__":
    main()
