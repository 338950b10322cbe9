"""Summarise the CPU training run: loss curve from the lerobot-train log, success per checkpoint from
`gcs-push evaluate` runs in results/learning_curve/step_*/. Writes learning_curve.{csv,png}.

    python results/train/summarize.py outputs/train/cpu_run.log
"""

import csv
import json
import re
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

here = Path(__file__).parent
log = Path(sys.argv[1]).read_text(errors="ignore")
LOG_FREQ = 50  # lerobot-train prints "step:2K" past 1000, so steps are counted from the log frequency
loss = [((i + 1) * LOG_FREQ, float(m.group(1))) for i, m in enumerate(re.finditer(r"step:\S+ smpl:\S+ ep:\S+ epch:\S+ loss:([\d.]+)", log))]
rows = []
for d in sorted((here.parent / "learning_curve").glob("step_*")):
    s = d / "summary.json"
    if s.exists():
        v = next(iter(json.loads(s.read_text())["variants"].values()))
        rows.append({"step": int(d.name.split("_")[1]), "runs": v["runs"], "success_0.1": v["success"],
                     "success_0.2": v["success_0.2"], "success_sim_time_s": v["success_sim_time_s"]})
with open(here / "learning_curve.csv", "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=["step", "runs", "success_0.1", "success_0.2", "success_sim_time_s"])
    w.writeheader()
    w.writerows(rows)
with open(here / "loss.csv", "w") as f:
    f.write("step,loss\n" + "".join(f"{s},{l}\n" for s, l in loss))
fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.5))
a.plot(*zip(*loss)) if loss else None
a.set_yscale("log"); a.set_xlabel("training step"); a.set_ylabel("diffusion loss"); a.set_title("training loss")
if rows:
    b.plot([r["step"] for r in rows], [r["success_0.1"] for r in rows], "o-", label="success 0.1 m")
    b.plot([r["step"] for r in rows], [r["success_0.2"] for r in rows], "s--", label="success 0.2 m")
b.set_ylim(-0.05, 1.05); b.set_xlabel("training step"); b.set_title("closed-loop success (60 s timeout)"); b.legend() if rows else None
fig.tight_layout()
fig.savefig(here / "learning_curve.png", dpi=110)
print(json.dumps(rows, indent=1))
