"""What the expert's actions depend on, in a gym-pusht dataset: the action (the PD agent's target, px) less
the agent's position, fitted by least squares to the agent's next move and to its velocity now (both from
`observation.state`, px per step). The steered expert inverts the PD map, so its target is close to a linear
function of the two; the velocity part is what a policy that sees one frame (`n_obs_steps` 1) cannot know.

    python experiments/pusht/action_analysis.py local/gcs_pusht_206
"""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd

from lerobot_gcs_push.generate import lerobot_home


def main(repo_id: str) -> None:
    files = sorted((lerobot_home() / repo_id / "data").glob("*/*.parquet"))
    if not files:
        raise SystemExit(f"no dataset at {lerobot_home() / repo_id}: rebuild it (count_table.py dataset N)")
    df = pd.concat([pd.read_parquet(f, columns=["action", "observation.state", "episode_index"]) for f in files])
    a = np.stack(df["action"].to_numpy()).astype(float)
    s = np.stack(df["observation.state"].to_numpy()).astype(float)
    ep = df["episode_index"].to_numpy()
    inner = np.flatnonzero((ep[1:-1] == ep[:-2]) & (ep[1:-1] == ep[2:])) + 1  # frames with both neighbours
    lead, move, vel = a[inner] - s[inner], s[inner + 1] - s[inner], s[inner] - s[inner - 1]
    X = np.hstack([move, vel, np.ones((len(inner), 1))])
    coef, *_ = np.linalg.lstsq(X, lead, rcond=None)
    r2 = 1 - (lead - X @ coef).var(0).sum() / lead.var(0).sum()
    vel_part = vel @ coef[2:4]
    second = np.linalg.norm(a[inner + 1] - 2 * a[inner] + a[inner - 1], axis=1)
    rms, p99 = np.sqrt((lead**2).sum(1).mean()), np.percentile(np.linalg.norm(lead, axis=1), 99)
    share, vel_rms = vel_part.var(0).sum() / lead.var(0).sum(), np.sqrt((vel_part**2).sum(1).mean())
    print(f"{repo_id}: {len(a)} frames, {len(np.unique(ep))} episodes")
    print(f"|action - agent|: rms {rms:.1f} px, 99th percentile {p99:.1f}")
    print(f"action - agent ~ {coef[0, 0]:.2f} x next move {coef[2, 0]:+.2f} x velocity (R^2 {r2:.3f})")
    print(f"the velocity term: {share:.0%} of the variance, rms {vel_rms:.1f} px")
    p50, p90 = np.percentile(second, [50, 90])
    print(f"the action's second difference: median {p50:.1f} px, 90th percentile {p90:.1f}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "local/gcs_pusht_206")
