"""One compact JSON record per evaluation, from the folder `gcs-push evaluate` wrote (runs.jsonl, settings.json,
summary.json, command.txt), and the tables the READMEs quote, printed back from such a record.

    python experiments/scripts/compact_results.py make results/active_round11_hard  # -> .../active_round11_hard.json
    python experiments/scripts/compact_results.py make --out=R.json DIR_A DIR_B    # several evaluations in one file
    python experiments/scripts/compact_results.py show results/active_round11_hard.json [--policy=LABEL_PART]

A record keeps, per policy variant (the label `gcs-push evaluate` gives it): the run counts and success
counts at both thresholds; the means over the successes of simulation, run, plan and total time; the
regret summary (mean and 95th percentile per run, 95th percentile per chunk, ...); the sums over the
successes of V at the start, of the finger path (V + regret) and of the simulation time, from which the
path over GCS's optimum and the mean finger speed follow; per initial condition the runs, successes, mean
success simulation time and mean / median regret (so per-IC success counts and the per-IC time ratios of
`time_by_ic.py` follow); per hard family success and median regret per run (as `hard_families.py`); and
every failed run (initial condition, run, final distance to the goal, simulated time, regret), so that
`failure_analysis.py`'s wrong-face count (final distance above the box's start distance) follows too. The
initial conditions (box, finger, family, V at the start), the settings, the command and any
`failure_analysis.txt` are kept as they were. Trajectories, videos, figures and per-chunk regrets are not:
git history has the folders (see experiments/README.md for the commit).

`make` checks every figure it writes against the folder's summary.json and stops on a mismatch.
"""

from __future__ import annotations

import argparse
import json
import statistics
from collections import defaultdict
from pathlib import Path

FORMAT = "gcs-push-evaluation-record/1"
HARD_KINDS = ("goal_side", "corner", "tiny_push", "edge")  # scene.HARD_KINDS; IC i is of kind i % 4
GOAL = (0.0, 0.0)  # Scene().goal for every evaluation kept here
PER_IC = ["runs", "successes", "successes_0.2", "success_sim_time_s", "regret_mean_m", "regret_median_m"]
FAILURE = ["ic", "run", "final_distance_m", "sim_time_s", "regret_m"]


def _r(x, d=4):
    return None if x is None else round(float(x), d)


def _mean(xs):
    xs = list(xs)
    return sum(xs) / len(xs) if xs else None


def _label(rec: dict) -> str:
    if "label" in rec:
        return rec["label"]
    raise ValueError("a run without a label")


def _p95(xs: list[float]) -> float:
    # numpy.percentile's default (linear) without numpy
    s = sorted(xs)
    k = (len(s) - 1) * 0.95
    lo = int(k)
    hi = min(lo + 1, len(s) - 1)
    return s[lo] + (s[hi] - s[lo]) * (k - lo)


def compact(d: Path) -> dict:
    settings = json.loads((d / "settings.json").read_text())
    summary = json.loads((d / "summary.json").read_text())["variants"]
    recs = [json.loads(line) for line in (d / "runs.jsonl").read_text().splitlines() if line.strip()]
    ics = settings["initial_conditions"]
    kinds = [ic.get("kind") for ic in ics]
    value0: dict[int, float] = {}
    for r in recs:
        if r.get("value_initial") is not None:
            value0.setdefault(r["initial_condition_index"], r["value_initial"])
    by_variant = defaultdict(list)
    for r in recs:
        by_variant[(r["policy"], bool(r["disturbances"]))].append(r)
    variants = {}
    for label, s in summary.items():
        rs = by_variant[(s["policy"], bool(s["disturbances"]))]
        assert len(rs) == s["runs"], (d, label, len(rs), s["runs"])
        succ = [r for r in rs if r["success"]]
        v = {
            "policy": s["policy"],
            "disturbances": s["disturbances"],
            "runs": len(rs),
            "successes": len(succ),
            "successes_0.2": sum(bool(r["success_0.2"]) for r in rs),
        }
        for k, rk in (
            ("success_sim_time_s", "sim_time_s"),
            ("run_time_s", "run_time_s"),
            ("plan_time_s", "plan_time_s"),
            ("total_time_s", "total_time_s"),
        ):
            v[k] = _r(_mean(r[rk] for r in succ))
            assert v[k] is None or abs(v[k] - s[k]) < 1e-4, (d, label, k)
        assert abs(v["successes"] / v["runs"] - s["success"]) < 1e-9
        has_regret = "regret_mean" in s
        if has_regret:
            for k in (
                "regret_mean",
                "regret_p95",
                "chunk_regret_p95",
                "runs_with_large_regret",
                "first_large_regret_s_median",
                "large_regret_m",
                "unscored_chunks",
            ):
                v[k] = _r(s.get(k)) if k != "unscored_chunks" else s.get(k)
            assert abs(_mean(r["regret"] for r in rs) - s["regret_mean"]) < 1e-9
            assert abs(_p95([r["regret"] for r in rs]) - s["regret_p95"]) < 1e-9
            v["successes_sum"] = {
                "value_initial_m": _r(sum(r["value_initial"] for r in succ), 3),
                "path_m": _r(sum(r["value_initial"] + r["regret"] for r in succ), 3),
                "sim_time_s": _r(sum(r["sim_time_s"] for r in succ), 3),
            }
        rows = []
        for i in range(len(ics)):
            ri = [r for r in rs if r["initial_condition_index"] == i]
            si = [r for r in ri if r["success"]]
            reg = [r["regret"] for r in ri if r.get("regret") is not None]
            rows.append(
                [
                    len(ri),
                    len(si),
                    sum(bool(r["success_0.2"]) for r in ri),
                    _r(_mean(r["sim_time_s"] for r in si), 3),
                    _r(_mean(reg), 3) if reg else None,
                    _r(statistics.median(reg), 3) if reg else None,
                ]
            )
            if len(ri):
                assert abs(len(si) / len(ri) - s["per_initial_condition"][str(i)]["success"]) < 1e-9
        v["per_ic"] = rows
        if any(kinds):
            fam = {}
            for kind in dict.fromkeys(k for k in kinds if k):
                rk = [r for r in rs if kinds[r["initial_condition_index"]] == kind]
                reg = [r["regret"] for r in rk if r.get("regret") is not None]
                fam[kind] = [
                    len(rk),
                    sum(bool(r["success"]) for r in rk),
                    _r(statistics.median(reg), 3) if reg else None,
                ]
            v["families"] = fam
        v["failures"] = [
            [
                r["initial_condition_index"],
                r["run"],
                _r(r["final_distance"], 3),
                _r(r["sim_time_s"], 2),
                _r(r.get("regret"), 3),
            ]
            for r in sorted(rs, key=lambda r: (r["initial_condition_index"], r["run"]))
            if not r["success"]
        ]
        variants[label] = v
    out = {
        "format": FORMAT,
        "command": (d / "command.txt").read_text() if (d / "command.txt").exists() else None,
        "settings": {k: v for k, v in settings.items() if k != "initial_conditions"},
        "goal": list(GOAL),
        "initial_conditions": {
            "columns": ["box_x", "box_y", "finger_x", "finger_y", "kind", "value_initial_m"],
            "rows": [
                [
                    _r(ic["box"][0], 3),
                    _r(ic["box"][1], 3),
                    _r(ic["finger"][0], 3),
                    _r(ic["finger"][1], 3),
                    ic.get("kind"),
                    _r(value0.get(i), 3),
                ]
                for i, ic in enumerate(ics)
            ],
        },
        "per_ic_columns": PER_IC,
        "families_columns": ["runs", "successes", "regret_median_m"],
        "failures_columns": FAILURE,
        "variants": variants,
    }
    if (d / "failure_analysis.txt").exists():
        out["failure_analysis"] = (d / "failure_analysis.txt").read_text()
    return out


def dumps(obj, ind: int = 0) -> str:
    """JSON with one line per list of scalars (or list of such lists' rows), so a record stays short."""
    pad, pad1 = " " * ind, " " * (ind + 1)
    if isinstance(obj, dict):
        if not obj:
            return "{}"
        items = [f"{pad1}{json.dumps(k)}: {dumps(v, ind + 1)}" for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(obj, list):
        if all(not isinstance(x, (dict, list)) for x in obj):
            return json.dumps(obj, separators=(",", ":"))
        return "[\n" + ",\n".join(pad1 + dumps(x, ind + 1) for x in obj) + "\n" + pad + "]"
    return json.dumps(obj)


def load(path: Path) -> dict[str, dict]:
    """name -> record, for a file of one evaluation or of several."""
    data = json.loads(path.read_text())
    return {path.stem: data} if data.get("format") == FORMAT else data["evaluations"]


def _f(x, d=2):
    return "-" if x is None else f"{x:.{d}f}"


def show(path: Path, policy: str | None) -> None:
    for name, rec in load(path).items():
        vs = rec["variants"]
        ics = rec["initial_conditions"]["rows"]
        print(
            f"## {name} (seed {rec['settings']['seed']}, {len(ics)} x {rec['settings']['runs']}, "
            f"timeout {rec['settings']['timeout_s']:g} s)\n"
        )

        def ref(v, vs=vs):  # GCS beside it: closed loop under the same disturbances, else open loop
            same = [
                g for g in vs.values() if g["policy"] == "gcs-closed-loop" and g["disturbances"] == v["disturbances"]
            ]
            opened = [g for g in vs.values() if g["policy"] == "gcs-open-loop"]
            return (opened if not v["disturbances"] and opened else same or opened or [None])[0]

        print(
            "| policy | successes | success 0.1 / 0.2 m | success sim time (s) | over GCS | median IC ratio "
            "| run time (s) | regret mean / p95 (m) | path over optimum | speed over GCS | ICs below 4/5 |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for label, v in vs.items():
            if policy and policy not in label:
                continue
            gcs = ref(v)
            gsum = gcs.get("successes_sum") if gcs else None
            ratio = ratios = None
            if gcs and v["success_sim_time_s"]:
                # The ratio of the means, as tables.md; +dist rows against GCS closed loop +dist when it ran.
                ratio = v["success_sim_time_s"] / gcs["success_sim_time_s"]
                ratios = [row[3] / g[3] for row, g in zip(v["per_ic"], gcs["per_ic"]) if row[1] and g[1]]
            path_r = speed_r = None
            ss = v.get("successes_sum")
            if ss and ss["value_initial_m"]:
                path_r = ss["path_m"] / ss["value_initial_m"]
                if gsum:
                    speed_r = (ss["path_m"] / ss["sim_time_s"]) / (gsum["path_m"] / gsum["sim_time_s"])
            below = sum(1 for row in v["per_ic"] if row[0] and row[1] / row[0] < 0.8)
            print(
                f"| {label} | {v['successes']} / {v['runs']} | {_f(v['successes'] / v['runs'])} / "
                f"{_f(v['successes_0.2'] / v['runs'])} | {_f(v['success_sim_time_s'], 1)} | "
                f"{_f(ratio) + 'x' if ratio else '-'} | "
                f"{_f(statistics.median(ratios)) if ratios else '-'} | {_f(v['run_time_s'])} | "
                f"{_f(v.get('regret_mean'))} / {_f(v.get('regret_p95'))} | {_f(path_r)} | {_f(speed_r)} | {below} |"
            )
        print()
        for label, v in vs.items():
            if policy and policy not in label:
                continue
            fam = v.get("families")
            fam_s = ", ".join(f"{k} {s / n:.2f} / {_f(m, 1)} m" for k, (n, s, m) in fam.items()) if fam else ""
            low = [f"IC {i} {row[1]}/{row[0]}" for i, row in enumerate(v["per_ic"]) if row[1] < row[0]]
            print(f"- {label}: {fam_s}{'; ' if fam_s and low else ''}{', '.join(low)}")
        print()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    mk = sub.add_parser("make")
    mk.add_argument("dirs", nargs="+", type=Path)
    mk.add_argument("--out", type=Path)
    sh = sub.add_parser("show")
    sh.add_argument("files", nargs="+", type=Path)
    sh.add_argument("--policy")
    a = ap.parse_args()
    if a.cmd == "make":
        if len(a.dirs) == 1:
            out = a.out or a.dirs[0].with_suffix(".json")
            text = dumps(compact(a.dirs[0]))
        else:
            out = a.out
            text = dumps({"format": FORMAT + " (several)", "evaluations": {d.name: compact(d) for d in a.dirs}})
        out.write_text(text + "\n")
        print(f"{out}: {len(text)} bytes")
    else:
        for f in a.files:
            show(f, a.policy)


if __name__ == "__main__":
    main()
