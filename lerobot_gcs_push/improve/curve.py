"""The curve of a `gcs-push improve` run, read from its state file: each round's rollout scores (fresh
initial conditions, GCS beside) placed at the stage hours when the policy they measure became current.

    python -m lerobot_gcs_push.improve.curve STATE_DIR   # writes STATE_DIR/curve.png, prints the points

`improve` redraws it after every round's rollouts, so the committed state folder always holds its picture.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

CURVE_FILE = "curve.png"
SETS = ("hard", "uniform")


def curve_points(state: dict) -> list[dict]:
    """One point per round whose rollouts are scored: the round, the hours spent before its rollouts began
    (stages in the order they ran, every machine's and resume's time counted), and the scores."""
    points, hours = [], 0.0
    for name, rec in state["stages"].items():
        if name.endswith(".rollouts") and rec.get("scores"):
            points.append({"round": int(name[1:].split(".")[0]), "hours": hours, "scores": rec["scores"]})
        hours += rec.get("wall_s", 0.0) / 3600
    return points


def plot_curve(state: dict, path: Path) -> Path | None:
    """Success with and without disturbances, time over GCS's and regret (or, for a slider that turns,
    the goal's final coverage) against hours; the run's stop
    targets (`state["stop"]`, as its last invocation set them) drawn as dotted lines. None when no round is
    scored yet."""
    points = curve_points(state)
    stop = state.get("stop") or {}
    if not points:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    hours = [p["hours"] for p in points]
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), sharex=True)
    colors = {"hard": "tab:red", "uniform": "tab:blue"}
    for name in SETS:
        rows = [p["scores"].get(name) for p in points]
        if not any(rows):
            continue
        for key, style in (("without", "-o"), ("with", "--s")):
            if not any(r and key in r for r in rows):  # gym-pusht's rounds run no disturbances
                continue
            axes[0].plot(hours, [r.get(key) if r else None for r in rows], style, color=colors[name],
                         label=f"{name}, {key} disturbances")  # fmt: skip
        axes[1].plot(hours, [r.get("time_ratio") if r else None for r in rows], "-o", color=colors[name], label=name)
        third = "regret_mean" if any(r and "regret_mean" in r for r in rows) else "coverage_mean"
        axes[2].plot(hours, [r.get(third) if r else None for r in rows], "-o", color=colors[name], label=name)
    for key, name in (("hard_success", "hard"), ("uniform_success", "uniform")):
        if key in stop:
            axes[0].axhline(stop[key], color=colors[name], lw=0.8, ls=":")
    if "time_ratio" in stop:
        axes[1].axhline(stop["time_ratio"], color="k", lw=0.8, ls=":")
    for x, p in zip(hours, points):
        axes[0].text(x, 1.05, f"r{p['round']}", ha="center", fontsize=8)
    axes[0].set(ylim=(0, 1.1), ylabel="success on the round's rollouts")
    axes[1].set(ylabel="mean success time / GCS's")
    ratios = [p["scores"].get(n, {}).get("time_ratio", math.inf) for p in points for n in SETS]
    if not any(math.isfinite(r) for r in ratios):  # gym-pusht's first rounds: an empty panel would say nothing
        axes[1].text(0.5, 0.5, "no success yet:\nno time to compare", ha="center", va="center",
                     transform=axes[1].transAxes, color="0.4")  # fmt: skip
    covered = not any(p["scores"].get(n, {}).get("regret_mean") is not None for p in points for n in SETS)
    axes[2].set(ylabel="final coverage of the goal, mean" if covered else "regret per run, mean (m)", ylim=(0, None))
    for ax in axes:
        ax.set_xlabel("stage hours when the policy became current")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="lower right")
    axes[1].legend(fontsize=7)
    fig.suptitle("gcs-push improve: each round's rollouts measure the policy the rounds before it shipped")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def main(argv=None) -> None:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        raise SystemExit("usage: python -m lerobot_gcs_push.improve.curve STATE_DIR")
    state_file = Path(args[0]) / "state.json"
    if not state_file.is_file():
        raise SystemExit(f"{state_file} does not exist: give a gcs-push improve --state_dir")
    state = json.loads(state_file.read_text())
    out = plot_curve(state, Path(args[0]) / CURVE_FILE)
    for p in curve_points(state):
        cells = "; ".join(
            f"{k} {s.get('without', float('nan')):.3f}"
            + (f" / {s['with']:.3f}" if "with" in s else "")  # gym-pusht's rounds run no disturbances
            + f", {s.get('time_ratio', float('nan')):.2f}x, "
            + (
                f"final coverage {s['coverage_mean']:.3f}"
                if "coverage_mean" in s and "regret_mean" not in s
                else f"regret {s.get('regret_mean', float('nan')):.1f} m"
            )
            for k, s in p["scores"].items()
        )
        print(f"round {p['round']} at {p['hours']:.2f} h: {cells}")
    print(out or "no round scored yet")


if __name__ == "__main__":
    main()
