"""Print the policy a round's rule ships. Usage: validation_winner.py [--tie_break=time] OLD NEW DIR...

The new policy ships only with more successes than the old one over the validation folders' runs without
disturbances. On equal successes the old one stays, or with --tie_break=time the one with the lower mean
simulation time of its successful runs (the issue's time target) ships.
"""

import json
import sys

args = sys.argv[1:]
tie_break = "--tie_break=time" in args
old, new, *dirs = [a for a in args if a != "--tie_break=time"]
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
if wins[new] != wins[old]:
    print(new if wins[new] > wins[old] else old)
else:
    print(new if tie_break and mean_time[new] < mean_time[old] else old)
