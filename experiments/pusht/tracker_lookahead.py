"""The gym-pusht expert's actions steered over one action or over N (the target held N actions lands the
agent on the plan's point N actions ahead; N = 2 is the setting since 2026-12-05), alternated start by
start on gym-pusht's resets: success, steps, and what the actions ask of a policy (their jumps, their
distance from the agent, the share of their variance that the agent's velocity explains). One JSON line
per start and setting.

    python experiments/pusht/tracker_lookahead.py 9901 9921 1,3
"""

import json
import sys
import time

import numpy as np

from lerobot_gcs_push.planning.factory import ExpertConfig, make_expert, make_planner
from lerobot_gcs_push.pusht.agent import PixelActions
from lerobot_gcs_push.registration import make_env

env = make_env("gym_pusht/PushT-v0")
planner = make_planner(env.scene)
planner.warm_up()


def velocity_share(actions, pos, vel) -> float:
    """R^2 gained by adding the velocity to a least-squares fit of the action on (1, position, next move)."""
    nxt = np.diff(pos, axis=0, append=pos[-1:])
    base = np.column_stack([np.ones(len(pos)), pos, nxt])
    full = np.column_stack([base, vel])
    out = []
    for cols in (base, full):
        res = actions - cols @ np.linalg.lstsq(cols, actions, rcond=None)[0]
        out.append(1 - (res**2).sum() / ((actions - actions.mean(0)) ** 2).sum())
    return float(out[1] - out[0])


ns = [int(n) for n in sys.argv[3].split(",")]
for seed in range(int(sys.argv[1]), int(sys.argv[2])):
    for n in ns if seed % 2 == 0 else ns[::-1]:
        inner = make_expert(env.scene, env.fps, ExpertConfig(mode="closed-loop"), planner)
        expert = PixelActions(inner.expert, env.scene.frame, n)
        obs, info = env.reset(seed=seed)
        t0 = time.perf_counter()
        expert.reset(obs, info, seed)
        acts, pos, vel = [], [], []
        while True:
            pos.append(np.asarray(info["pos_agent"], float))
            vel.append(np.asarray(info["vel_agent"], float))
            a = np.clip(expert.act(obs, info), 0, 512)
            acts.append(a)
            obs, _, term, trunc, info = env.step(a)
            if term or trunc:
                break
        acts, pos, vel = map(np.array, (acts, pos, vel))
        jumps = np.linalg.norm(np.diff(acts, 2, axis=0), axis=1) if len(acts) > 2 else np.zeros(1)
        row = {
            "seed": seed,
            "n": n,
            "success": bool(info.get("is_success")),
            "steps": len(acts),
            "wall": round(time.perf_counter() - t0, 2),
            "plans": len(inner.expert.plans),
            "jump_median_px": round(float(np.median(jumps)), 2),
            "jump_p90_px": round(float(np.percentile(jumps, 90)), 2),
            "offset_rms_px": round(float(np.sqrt(np.mean(np.sum((acts - pos) ** 2, axis=1)))), 2),
            "velocity_share": round(velocity_share(acts, pos, vel), 4),
        }
        print(json.dumps(row), flush=True)
