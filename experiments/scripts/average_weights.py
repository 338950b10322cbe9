"""Average the weights of several fine-tuned policies of one lineage (a "model soup") into one directory
that `lerobot-eval` and `gcs-push evaluate` load as they load any shipped policy.

Why it can work here: rounds 3 and 4 of active data are consecutive fine-tunings of one network (round 4
started from round 3), about 6% apart in weight norm, so their average stays in the same basin and
averages out some of the noise of a short fine-tuning (what an EMA of the weights does during training).

The processors (normalisation statistics) are taken from the first policy. That is sound only if the
statistics the network actually uses agree: min/max of state and action (MIN_MAX), the fixed image
mean/std (MEAN_STD). The script checks that they agree within `--tolerance` (relative) and refuses
otherwise.

    .venv/bin/python experiments/scripts/average_weights.py \
        experiments/active_data/round3/active_step2000 experiments/active_data/round4/active_step2000 \
        --output experiments/active_data/soup/r3_r4
"""

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

import torch
from safetensors.torch import load_file, save_file

from lerobot_gcs_push.artifacts.checkpoints import MODEL_FILE, export_policy, is_pretrained_dir

NORMALIZER = "policy_preprocessor_step_3_normalizer_processor.safetensors"
USED_STATS = (
    "observation.state.min",
    "observation.state.max",
    "action.min",
    "action.max",
    "observation.image.mean",
    "observation.image.std",
)


def check_statistics(dirs: list[Path], tolerance: float) -> None:
    first = load_file(dirs[0] / NORMALIZER)
    for d in dirs[1:]:
        other = load_file(d / NORMALIZER)
        for key in USED_STATS:
            a, b = first[key].double(), other[key].double()
            rel = ((a - b).abs() / a.abs().clamp_min(1e-6)).max().item()
            if rel > tolerance:
                sys.exit(f"{key} differs by {rel:.2e} (relative) between {dirs[0]} and {d}: not averaging")


def average(dirs: list[Path]) -> dict[str, torch.Tensor]:
    states = [load_file(d / MODEL_FILE) for d in dirs]
    keys = set(states[0])
    for d, s in zip(dirs[1:], states[1:]):
        if set(s) != keys:
            sys.exit(f"{d} holds other tensors than {dirs[0]}: not one architecture")
    out = {}
    for k in states[0]:
        if states[0][k].is_floating_point():
            out[k] = torch.stack([s[k].double() for s in states]).mean(0).float()
        else:
            out[k] = states[0][k]
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("policies", nargs="+", type=Path)
    p.add_argument("--output", type=Path, required=True)
    p.add_argument("--tolerance", type=float, default=1e-3)
    args = p.parse_args()
    if len(args.policies) < 2:
        sys.exit("give at least two policies to average")
    for d in args.policies:
        if not is_pretrained_dir(d):
            sys.exit(f"{d} is not a policy directory")
    check_statistics(args.policies, args.tolerance)
    with tempfile.TemporaryDirectory() as tmp:
        staging = Path(tmp) / "fp32"
        shutil.copytree(args.policies[0], staging)
        save_file(average(args.policies), staging / MODEL_FILE, metadata={"format": "pt"})
        (staging / "README.md").unlink(missing_ok=True)
        export_policy(staging, args.output)
    print(f"{args.output}: mean of {', '.join(map(str, args.policies))}")


if __name__ == "__main__":
    main()
