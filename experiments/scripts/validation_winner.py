"""Print the policy a round's rule ships: the new one only if it has more successes without disturbances
over the validation folders' runs; a tie keeps the old one. Usage: validation_winner.py OLD NEW DIR..."""

import json
import sys

old, new, *dirs = sys.argv[1:]
wins = {old: 0, new: 0}
for d in dirs:
    for line in open(f"{d}/runs.jsonl"):
        rec = json.loads(line)
        if rec["policy"] in wins and not rec["disturbances"]:
            wins[rec["policy"]] += bool(rec["success"])
print(f"validation successes: {wins}", file=sys.stderr)
print(new if wins[new] > wins[old] else old)
