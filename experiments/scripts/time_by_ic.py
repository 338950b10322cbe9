"""Where a policy's extra simulated time goes: its mean success time per initial condition against GCS's.

The mean ratio over all successes (tables.md) is pulled up by a few detours; the median of the per-condition
ratios shows the typical run. Usage: python experiments/scripts/time_by_ic.py POLICY_DIR results/<dir> [...]
(POLICY_DIR as in runs.jsonl, e.g. experiments/active_data/round3/active_step2000; no disturbances).
"""

import statistics
import sys
from collections import defaultdict
from pathlib import Path

from lerobot_gcs_push.evaluation import read_runs


def main(policy: str, dirs: list[str]) -> None:
    for d in dirs:
        times: dict[str, dict[int, list[float]]] = defaultdict(lambda: defaultdict(list))
        for rec in read_runs(Path(d) / "runs.jsonl"):
            if rec["success"] and not rec["disturbances"]:
                times[rec["policy"]][rec["initial_condition_index"]].append(rec["sim_time_s"])
        gcs = times["gcs-open-loop"] or times["gcs-closed-loop"]
        rows = []
        for ic, ts in times[policy].items():
            mine, best = statistics.mean(ts), statistics.mean(gcs[ic])
            rows.append((mine - best, mine / best, ic, best))
        rows.sort(reverse=True)
        ratios = [r for _, r, _, _ in rows]
        print(f"## {d}: {policy} against GCS, per initial condition (successes, no disturbances)")
        print(f"median ratio {statistics.median(ratios):.2f}; largest extra time:")
        for extra, ratio, ic, best in rows[:5]:
            print(f"  IC {ic:2d}: +{extra:5.1f} s ({ratio:.2f}x GCS's {best:.1f} s)")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
