"""The shipping rule: does a candidate policy replace the current one, judged on a validation set?

Eleven hand-run rounds taught it (experiments/active_data/README.md): decide on initial conditions no
choice has used yet; ask for a margin in successes, since one run in 240 was noise (round 10 won by one
and then lost on every test set); within the margin, ship only a clearly faster policy (round 10b: 5.6 %
lower mean success time at one run fewer), else keep the current one (round 8's tie kept round 7).

Where neither policy succeeds (gym-pusht's first rounds: 0 / 100 on both sides of round 1), success and
time cannot tell them apart and every round would start again from the same weights; with `coverage_margin`
set, the candidate then ships when it leaves the slider covering the goal more: its mean final coverage at
least `coverage_margin` higher, and higher on more of the set's starts than lower (paired by start and run).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class PolicyScore:
    runs: int
    successes: int
    mean_success_time_s: float  # inf without a success
    regret_mean: float | None
    regret_p95: float | None
    coverage_mean: float | None = None  # the final coverage of a slider that turns, where runs record it

    @property
    def success_rate(self) -> float:
        return self.successes / self.runs if self.runs else 0.0


@dataclass(frozen=True)
class Decision:
    ship: bool
    reason: str
    current: PolicyScore
    candidate: PolicyScore

    def to_json(self) -> dict:
        return asdict(self) | {"current": _score_json(self.current), "candidate": _score_json(self.candidate)}


def _score_json(s: PolicyScore) -> dict:
    return asdict(s) | {"success_rate": s.success_rate}


def score(records: list[dict], policy: str) -> PolicyScore:
    """One policy's runs without disturbances (the validation sets' condition) in `records`."""
    recs = [r for r in records if r["policy"] == policy and not r["disturbances"]]
    if not recs:
        raise ValueError(f"no runs of {policy!r} without disturbances in the validation records")
    times = [r["sim_time_s"] for r in recs if r["success"]]
    regrets = [r["regret"] for r in recs if r.get("regret") is not None]
    coverages = [r["coverage"] for r in recs if r.get("coverage") is not None]
    return PolicyScore(
        runs=len(recs),
        successes=len(times),
        mean_success_time_s=float(np.mean(times)) if times else float("inf"),
        regret_mean=float(np.mean(regrets)) if regrets else None,
        regret_p95=float(np.percentile(regrets, 95)) if regrets else None,
        coverage_mean=float(np.mean(coverages)) if len(coverages) == len(recs) else None,
    )


def decide(
    records: list[dict],
    current: str,
    candidate: str,
    margin: int = 3,
    time_gain: float = 0.05,
    coverage_margin: float | None = None,
) -> Decision:
    """The candidate ships with at least `margin` more successes; the current policy stays with `margin`
    fewer; in between, the candidate ships only if its mean success time is `time_gain` (a fraction) lower.
    Where neither has a success, and `coverage_margin` is set, on final coverage (`coverage_decision`)."""
    if margin < 1:
        raise ValueError(f"margin must be >= 1 run, got {margin}")
    if not 0.0 <= time_gain < 1.0:
        raise ValueError(f"time_gain must be a fraction in [0, 1), got {time_gain}")
    if coverage_margin is not None and not 0.0 < coverage_margin < 1.0:
        raise ValueError(f"coverage_margin must be a fraction in (0, 1), or None, got {coverage_margin}")
    a, b = score(records, current), score(records, candidate)
    if a.runs != b.runs:
        raise ValueError(f"the two policies ran different sets: {a.runs} runs against {b.runs}")
    diff = b.successes - a.successes
    if diff >= margin:
        return Decision(True, f"{diff} more successes (margin {margin})", a, b)
    if diff <= -margin:
        return Decision(False, f"{-diff} fewer successes (margin {margin})", a, b)
    # No success: no time to compare. A candidate without one never ships on time; against a current
    # policy without one, any success is faster.
    faster = b.successes > 0 and b.mean_success_time_s <= (1 - time_gain) * a.mean_success_time_s
    why = f"{diff:+d} successes, within the margin of {margin}; "
    if not b.successes and not a.successes and coverage_margin is not None:
        ship, because = coverage_decision(records, current, candidate, coverage_margin)
        return Decision(ship, why + "neither has a success; " + because, a, b)
    if not b.successes:
        return Decision(False, why + "the candidate has no success", a, b)
    if not a.successes:
        return Decision(True, why + "the current policy has no success", a, b)
    gain = 1 - b.mean_success_time_s / a.mean_success_time_s
    why += f"mean success time {100 * gain:+.1f} % lower"
    return Decision(
        bool(faster), why + (f" (>= {100 * time_gain:g} %)" if faster else f" (< {100 * time_gain:g} %)"), a, b
    )


def coverage_decision(records: list[dict], current: str, candidate: str, margin: float) -> tuple[bool, str]:
    """(ship, why) on final coverage alone: the candidate's mean at least `margin` higher than the current
    policy's, and higher on more starts than lower, each start and run paired by its seed (the two policies
    ran the same starts). A set whose runs do not record coverage cannot be judged so."""
    pairs: dict[tuple, dict[str, float]] = {}
    for r in records:
        if r["policy"] in (current, candidate) and not r["disturbances"]:
            if r.get("coverage") is None:
                raise ValueError(f"a run of {r['policy']!r} records no final coverage: judge it on success alone")
            key = (r.get("seed"), r["initial_condition_index"], r["run"])
            pairs.setdefault(key, {})[r["policy"]] = float(r["coverage"])
    if any(len(p) != 2 for p in pairs.values()):
        raise ValueError("the two policies ran different starts: their coverages cannot be paired")
    a = np.array([p[current] for p in pairs.values()])
    b = np.array([p[candidate] for p in pairs.values()])
    gain, more, less = float(b.mean() - a.mean()), int(np.sum(b > a)), int(np.sum(b < a))
    ship = gain >= margin and more > less
    why = (
        f"mean final coverage {a.mean():.3f} -> {b.mean():.3f} ({gain:+.3f}, margin {margin:g}), "
        f"higher on {more} starts and lower on {less}"
    )
    return ship, why


def read_validation(folders: list[str | Path]) -> list[dict]:
    from lerobot_gcs_push.evaluation import read_runs

    return [rec for folder in folders for rec in read_runs(Path(folder) / "runs.jsonl")]
