"""Success and regret on a hard-sampler evaluation, by family of initial condition.

The hard sampler cycles through its families (`scene.HARD_KINDS`), so initial condition i is of family
i % 4. Usage: python experiments/scripts/hard_families.py results/active_round1_hard [more dirs]
"""

import json
import statistics
import sys
from collections import defaultdict
from pathlib import Path

from lerobot_gcs_push.evaluation import read_runs, variant_label
from lerobot_gcs_push.scene import HARD_KINDS


def main(dirs: list[str]) -> None:
    for d in dirs:
        settings = json.loads((Path(d) / "settings.json").read_text())
        cells: dict[tuple[str, str], list[dict]] = defaultdict(list)
        for rec in read_runs(Path(d) / "runs.jsonl"):
            kind = HARD_KINDS[rec["initial_condition_index"] % len(HARD_KINDS)]
            cells[(variant_label(rec["policy"], rec["disturbances"]), kind)].append(rec)
        labels = sorted({label for label, _ in cells})
        print(f"## {d} (seed {settings['seed']}): success at 0.1 m / median regret per run (m)\n")
        print("| policy | " + " | ".join(HARD_KINDS) + " |")
        print("|---|" + "---|" * len(HARD_KINDS))
        for label in labels:
            row = []
            for kind in HARD_KINDS:
                recs = cells[(label, kind)]
                ok = sum(bool(r["success"]) for r in recs) / len(recs)
                regrets = [r["regret"] for r in recs if r.get("regret") is not None]
                row.append(f"{ok:.2f} / {statistics.median(regrets):.1f}" if regrets else f"{ok:.2f}")
            print(f"| {label} | " + " | ".join(row) + " |")
        print()


if __name__ == "__main__":
    main(sys.argv[1:])
