"""Branch states without a cost-to-go: where a learned policy's coverage of the goal stalls or falls.

A slider that turns has no GCS cost-to-go to score a policy's chunks by (a regret would take a plan
through contact at every chunk of every rollout, at 0.4-3 s a plan). What the box's regret found, the
chunks in which the policy lost ground, shows here in the coverage of the goal: a chunk after which the
slider covers no more of the goal a couple of seconds later is one the policy spent without progress
(pushing the wrong face, hovering, turning the T away). The runs looked at are the failed ones and the
successes slower than the expert's on the same start; the states are labelled by the closed-loop expert
from there (`collect.collect`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_gcs_push.scene import Scene


@dataclass
class StallRule:
    # Coverage is judged this far ahead of a chunk start: 2 s is 2-3 pushes of the expert's (its plans push
    # at 1 m/s), so a policy that is merely repositioning for its next push is not caught.
    window_s: float = 2.0
    # A chunk whose coverage `window_s` later has grown by less than this is a stall (a fall is below 0).
    min_gain: float = 0.02
    # A success slower than this times the expert's on the same start counts as slow and is branched from
    # too (issue 48's bound on the policy's steps to success).
    slow_factor: float = 1.3
    # Steps between candidate states: the policy's action chunk (the CPU presets' n_action_steps).
    every: int = 8

    def __post_init__(self) -> None:
        for name in ("window_s", "slow_factor"):
            if not getattr(self, name) > 0:
                raise ValueError(f"stall.{name} must be positive, got {getattr(self, name)}")
        if self.every < 1:
            raise ValueError(f"stall.every must be >= 1, got {self.every}")


def stall_steps(coverage, fps: float, rule: StallRule, success_coverage: float) -> np.ndarray:
    """Chunk starts (every `rule.every` steps) not yet at success whose coverage `window_s` later (or at the
    run's end) has grown by less than `min_gain`. `coverage` has one entry a step and the final state."""
    cov = np.asarray(coverage, float)
    last = len(cov) - 1
    ks = np.arange(0, last, rule.every)
    ahead = cov[np.minimum(ks + round(rule.window_s * fps), last)]
    return ks[(cov[ks] < success_coverage) & (ahead - cov[ks] < rule.min_gain)]


def expert_times(records: list[dict], gcs_policies) -> dict[tuple, float]:
    """The expert's fastest successful time on each start (keyed by source folder, start and disturbances)."""
    out: dict[tuple, float] = {}
    for rec in records:
        if rec["policy"] in gcs_policies and rec["success"]:
            key = (rec.get("_source", ""), rec["initial_condition_index"], rec["disturbances"])
            out[key] = min(out.get(key, np.inf), rec["sim_time_s"])
    return out


def stall_branch_states(records: list[dict], cfg, scene: Scene, gcs_policies) -> list[dict]:
    """The states to label, in a deterministic order. `cfg` is a `collect.CollectConfig` (its `stall` rule,
    `keep_fraction` of the other chunk starts, `max_per_run` spread over time, `seed`). Every record needs its
    `_source` folder, where its trajectory (`trajectory`, written by `gcs-push evaluate`) lies."""
    rule = cfg.stall
    fastest = expert_times(records, gcs_policies)
    out = []
    for rec in sorted(records, key=lambda r: (r["policy"], r["disturbances"], r["initial_condition_index"], r["run"])):
        if rec["policy"] in gcs_policies:
            continue
        expert_s = fastest.get((rec.get("_source", ""), rec["initial_condition_index"], rec["disturbances"]))
        slow = rec["success"] and expert_s is not None and rec["sim_time_s"] > rule.slow_factor * expert_s
        if rec["success"] and not slow:
            continue
        traj = np.load(Path(rec.get("_source", "")) / rec["trajectory"])
        poses, fingers = traj["slider_pose"], traj["finger"]
        coverage = np.array([scene.coverage(p) for p in poses])
        stalls = set(stall_steps(coverage, scene.fps, rule, scene.success_coverage).tolist())
        rng = np.random.default_rng([cfg.seed, rec["initial_condition_index"], rec["run"], int(rec["disturbances"])])
        chunks = np.arange(0, len(poses) - 1, rule.every)
        kept = rng.random(len(chunks)) < cfg.keep_fraction
        startable = []
        for k, keep in zip(chunks.tolist(), kept):
            if (k not in stalls and not keep) or coverage[k] >= scene.success_coverage:
                continue
            start = {"box": poses[k][:2], "finger": fingers[k], "heading": float(poses[k][2])}
            try:  # the env's own checks: the slider and finger inside their workspaces (and apart, in Drake)
                scene.validate_start(start, "branch state")
            except ValueError:
                continue
            startable.append((k, "stall" if k in stalls else "kept"))
        if len(startable) > cfg.max_per_run:
            pick = np.unique(np.linspace(0, len(startable) - 1, cfg.max_per_run).round().astype(int))
            startable = [startable[i] for i in pick]
        for k, why in startable:
            source = {
                "rollouts": rec.get("_source", ""),
                "label": rec["label"],
                "initial_condition_index": rec["initial_condition_index"],
                "run": rec["run"],
                "step": k,
                "coverage": round(float(coverage[k]), 4),
                "why": why,
                "run_success": rec["success"],
                "run_slow": bool(slow),
            }
            out.append(start_entry(scene, poses[k], fingers[k]) | {"source": source})
    return out


def start_entry(scene: Scene, pose, finger) -> dict:
    """An initial-condition entry for the state: gym-pusht's own state vector for a scene in pixels (the env
    is reset to report exactly it), else the slider's position, heading and the finger in metres."""
    if scene.kind.pixel_starts:
        return {"pusht_state": np.round(scene.frame.state_of(pose, finger), 6).tolist()}
    return {
        "box": np.round(pose[:2], 6).tolist(),
        "finger": np.round(finger, 6).tolist(),
        "heading": round(float(pose[2]), 6),
    }
