"""Print the policy a round's rule ships.

Usage: validation_winner.py [--tie_break=time] [--margin=N] [--time_gain=G] OLD NEW DIR...

Over the validation folders' runs without disturbances, the new policy ships with at least `margin` more
successes than the old one (default 1) and the old one stays with `margin` fewer. In between, the old one
stays, or with --tie_break=time the one with the lower mean simulation time of its successful runs (the
issue's time target) ships, or with --time_gain=G the new one ships if its mean is at least G (a fraction)
lower.
"""

import json
import sys

opts = dict(a.partition("=")[::2] for a in sys.argv[1:] if a.startswith("--"))
old, new, *dirs = [a for a in sys.argv[1:] if not a.startswith("--")]
margin = int(opts.get("--margin", 1))
wins = {old: 0, new: 0}
times: dict[str, list[float]] = {old: [], new: []}
for d in dirs:
    for line in open(f"{d}/runs.jsonl"):
        rec = json.loads(line)
        if rec["policy"] in wins and not rec["disturbances"]:
            wins[rec["policy"]] += bool(rec["success"])
            if rec["success"]:
                times[rec["policy"]].append(rec["sim_time_s"])
mean_time = {p: sum(t) / len(t) if t else float("inf") for p, t in times.items()}
print(f"validation successes: {wins}; mean success simulation time: {mean_time}", file=sys.stderr)
diff = wins[new] - wins[old]
if abs(diff) >= margin:
    print(new if diff > 0 else old)
elif "--time_gain" in opts:
    print(new if mean_time[new] <= (1 - float(opts["--time_gain"])) * mean_time[old] else old)
elif opts.get("--tie_break") == "time":
    print(new if mean_time[new] < mean_time[old] else old)
else:
    print(old)
