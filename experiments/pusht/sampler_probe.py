"""A finished benchmark policy judged again with other inference settings (`lerobot-eval` overrides), on a
validation seed: what the sampler and the executed chunk do to the same weights.

    python -m experiments.pusht.sampler_probe position_shift1_lr3e-4 12200 preset
    python -m experiments.pusht.sampler_probe position_shift1_lr3e-4 12200 act4 --policy.n_action_steps=4

Each record lands in `experiments/pusht/learnability/v2/<pool>/probe<seed>_<name>.json`.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from benchmarks import learnability as bench


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) < 3 or not all(a.startswith("--") for a in args[3:]):
        print(__doc__)
        return 2
    pool, seed, name, overrides = args[0], int(args[1]), args[2], tuple(args[3:])
    if seed == bench.JUDGE_SEED:
        raise SystemExit(f"seed {seed} is the benchmark's judge; a probe uses a validation seed")
    saved = Path(bench.train_config(pool).output_dir) / "pretrained_model"
    if not (saved / "model.safetensors").is_file():
        raise SystemExit(f"{saved}: no finished policy; run the benchmark on {pool} first")
    record = bench.judge(saved, saved.parent.parent / f"probe{seed}_{name}", seed=seed, overrides=overrides)
    record["overrides"] = list(overrides)
    (bench.folder(pool) / f"probe{seed}_{name}.json").write_text(json.dumps(record, indent=1))
    print(json.dumps(record, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
