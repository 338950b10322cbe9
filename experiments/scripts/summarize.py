"""Summarise a CPU training run: the loss curve from the lerobot-train log and success per checkpoint
from the `gcs-push evaluate` runs in <run dir>/learning_curve/step_*/. Writes learning_curve.{csv,png}
and loss.csv into the run directory, with offline_error.csv (offline_error.py) in the plot if present.

    .venv/bin/python results/train/summarize.py results/train/run2_nocrop outputs/train/cpu_run_v2.log [--log-freq 50]
"""

import argparse
import csv
import json
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

parser = argparse.ArgumentParser()
parser.add_argument("run_dir", type=Path)
parser.add_argument("log", type=Path)
# lerobot-train prints "step:2K" past 1000, so steps are counted from the logging frequency
parser.add_argument("--log-freq", type=int, default=50)
args = parser.parse_args()

log = args.log.read_text(errors="ignore")
pattern = r"step:\S+ smpl:\S+ ep:\S+ epch:\S+ loss:([\d.]+)"
loss = [((i + 1) * args.log_freq, float(m.group(1))) for i, m in enumerate(re.finditer(pattern, log))]
rows = []
for d in sorted((args.run_dir / "learning_curve").glob("step_*")):
    s = d / "summary.json"
    if s.exists():
        settings = json.loads((d / "settings.json").read_text())
        v = next(iter(json.loads(s.read_text())["variants"].values()))
        rows.append(
            {
                "step": int(d.name.split("_")[1]),
                "runs": v["runs"],
                "timeout_s": settings["timeout_s"],
                "success_0.1": v["success"],
                "success_0.2": v["success_0.2"],
                "success_sim_time_s": v["success_sim_time_s"],
            }
        )
with open(args.run_dir / "learning_curve.csv", "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=["step", "runs", "timeout_s", "success_0.1", "success_0.2", "success_sim_time_s"])
    w.writeheader()
    w.writerows(rows)
with open(args.run_dir / "loss.csv", "w") as f:
    f.write("step,loss\n" + "".join(f"{s},{v}\n" for s, v in loss))

errors = []
if (args.run_dir / "offline_error.csv").exists():  # written by offline_error.py
    with open(args.run_dir / "offline_error.csv") as f:
        errors = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]

fig, (a, c, b) = plt.subplots(1, 3, figsize=(13, 3.5))
if errors:
    c.plot([r["step"] for r in errors], [r["action_error_m_mean"] for r in errors], "o-", label="policy")
    c.axhline(errors[0]["hold_baseline_m"], color="grey", ls=":", label="hold still")
    c.axhline(0.1, color="green", ls="--", label="success radius")
    c.legend()
c.set_ylim(bottom=0)
c.set_xlabel("training step")
c.set_ylabel("m")
c.set_title("action error on demo frames (8 actions)")
if loss:
    a.plot(*zip(*loss))
a.set_yscale("log")
a.set_xlabel("training step")
a.set_ylabel("diffusion loss")
a.set_title("training loss")
if rows:
    b.plot([r["step"] for r in rows], [r["success_0.1"] for r in rows], "o-", label="success 0.1 m")
    b.plot([r["step"] for r in rows], [r["success_0.2"] for r in rows], "s--", label="success 0.2 m")
    b.legend()
timeouts = sorted({r["timeout_s"] for r in rows})
b.set_ylim(-0.05, 1.05)
b.set_xlabel("training step")
b.set_title(f"closed-loop success ({', '.join(f'{t:g}' for t in timeouts)} s timeout)")
fig.suptitle(args.run_dir.name)
fig.tight_layout()
fig.savefig(args.run_dir / "learning_curve.png", dpi=110)
print(json.dumps(rows, indent=1))
