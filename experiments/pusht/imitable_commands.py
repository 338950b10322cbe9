"""The gym-pusht expert's command variants side by side, start by start on gym-pusht's resets: success,
steps, plans, and what the actions ask of a policy (their second difference against the agent's own, and
the share of their variance that the agent's velocity explains, as `action_analysis.py` fits it). One JSON
line per start and variant; a summary per variant at the end.

A variant is COMMANDS:LEAD:ACCEL[:TOLERANCE[:ARRIVE]] (`ExpertConfig.commands`, `.lead_actions`, the path's
acceleration bound in m/s^2, 0 for none, `.replan_tolerance`, the config's if not given or empty, and
`.arrive` in m/s over the config's `arrive_m`); the order alternates start by start. Steps and plans do not
depend on the load. `arrive_px` is how fast the T moved over the last 3 frames (px a frame, its centre plus
its turn at 30 px): what a policy must stop within.

    python experiments/pusht/imitable_commands.py 11820 11840 steer:2:0 position:2:4 position:3:4
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import replace

import numpy as np

from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert, make_planner
from lerobot_gcs_push.registration import make_env


def velocity_share(acts, pos) -> float:
    """The velocity term's share of the variance of (action - agent), fitted on the next move, the
    velocity and a constant (frames with both neighbours)."""
    lead, move, vel = acts[1:-1] - pos[1:-1], pos[2:] - pos[1:-1], pos[1:-1] - pos[:-2]
    X = np.hstack([move, vel, np.ones((len(lead), 1))])
    coef, *_ = np.linalg.lstsq(X, lead, rcond=None)
    return float((vel @ coef[2:4]).var(0).sum() / max(lead.var(0).sum(), 1e-12))


def run(env, planner, seed: int, variant: str) -> dict:
    commands, lead, accel, *rest = variant.split(":")
    config = ExpertConfig(mode="closed-loop", commands=commands, lead_actions=int(lead))
    if rest and rest[0]:
        config = replace(config, replan_tolerance=float(rest[0]))
    if len(rest) > 1:
        config = replace(config, arrive=float(rest[1]))
    expert = make_expert(env.scene, env.fps, config, planner)
    expert.expert.speeds = replace(expert.expert.speeds, accel=float(accel))
    obs, info = env.reset(seed=seed)
    t0 = time.perf_counter()
    expert.reset(obs, info, seed)
    acts, pos, block = [], [], []
    while True:
        pos.append(np.asarray(info["pos_agent"], float))
        block.append(np.asarray(info["block_pose"], float))
        a = np.clip(expert.act(obs, info), 0, 512)
        acts.append(a)
        obs, _, term, trunc, info = env.step(a)
        if term or trunc:
            break
    pos.append(np.asarray(info["pos_agent"], float))
    block.append(np.asarray(info["block_pose"], float))
    acts, pos, block = np.array(acts), np.array(pos), np.array(block)
    moves = np.diff(block[-4:], axis=0)
    arrive = np.linalg.norm(moves[:, :2], axis=1) + 30 * np.abs(np.angle(np.exp(1j * moves[:, 2])))
    second = np.linalg.norm(np.diff(acts, 2, axis=0), axis=1) if len(acts) > 2 else np.zeros(1)
    own = np.linalg.norm(np.diff(pos, 2, axis=0), axis=1) if len(pos) > 2 else np.zeros(1)
    return {
        "seed": seed,
        "variant": variant,
        "success": bool(info.get("is_success")),
        "steps": len(acts),
        "wall": round(time.perf_counter() - t0, 2),
        "plans": len(expert.expert.plans),
        "second": second.tolist(),
        "own": own.tolist(),
        "velocity_share": round(velocity_share(acts, pos[:-1]), 4) if len(acts) > 3 else None,
        "arrive_px": round(float(arrive.mean()), 3),
    }


def summary(rows: list[dict]) -> dict:
    second = np.concatenate([r["second"] for r in rows])
    own = np.concatenate([r["own"] for r in rows])
    steps = [r["steps"] for r in rows]
    return {
        "variant": rows[0]["variant"],
        "success": f"{sum(r['success'] for r in rows)} / {len(rows)}",
        "steps_median": float(np.median(steps)),
        "steps_mean": round(float(np.mean(steps)), 1),
        "plans": sum(r["plans"] for r in rows),
        "second_p90_px": round(float(np.percentile(second, 90)), 2),
        "own_p90_px": round(float(np.percentile(own, 90)), 2),
        "ratio_p90": round(float(np.percentile(second, 90) / np.percentile(own, 90)), 2),
        "velocity_share_median": round(float(np.median([r["velocity_share"] for r in rows])), 3),
        "arrive_px_median": round(float(np.median([r["arrive_px"] for r in rows])), 2),
        "wall_s": round(sum(r["wall"] for r in rows), 1),
    }


def main(first: int, last: int, variants: list[str]) -> None:
    env = make_env("gym_pusht/PushT-v0")
    planner = make_planner(env.scene)
    planner.warm_up()
    rows: dict[str, list] = {v: [] for v in variants}
    for seed in range(first, last):
        for v in variants if seed % 2 == 0 else variants[::-1]:
            row = run(env, planner, seed, v)
            rows[v].append(row)
            brief = {k: row[k] for k in ("seed", "variant", "success", "steps", "plans", "velocity_share", "arrive_px")}
            print(json.dumps(brief), flush=True)
    for v in variants:
        print(json.dumps(summary(rows[v])), flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3:])
