"""Where a gym-pusht demonstration's CPU time goes: `gcs-push generate` in this process under cProfile,
timed by CPU (process) time so that a busy machine changes the shares little.

    python experiments/pusht/profile_generate.py [EPISODES] [SEED]

Writes EPISODES (default 8) demonstrations of gym-pusht's resets of SEED (default 9411) with one worker
into a temporary LeRobot home, then prints the wall and CPU seconds and the 45 costliest calls by
cumulative CPU time. The first plan of a machine compiles the relaxation (cached on disk after): subtract
`ContactPlanner.warm_up`'s line to get the episodes' own time.
"""

from __future__ import annotations

import cProfile
import os
import pstats
import sys
import tempfile
import time


def main(episodes: int = 8, seed: int = 9411) -> None:
    os.environ["HF_LEROBOT_HOME"] = tempfile.mkdtemp(prefix="profile_generate.")
    from lerobot_gcs_push.cli import main as gcs_push

    args = ["generate", "--env_id=gym_pusht/PushT-v0", f"--episodes={episodes}", f"--seed={seed}", "--workers=1"]
    profile = cProfile.Profile(time.process_time)
    wall, cpu = time.perf_counter(), time.process_time()
    profile.runcall(gcs_push, [*args, "--repo_id=local/profile_generate"])
    print(f"wall {time.perf_counter() - wall:.1f} s, CPU {time.process_time() - cpu:.1f} s")
    pstats.Stats(profile).sort_stats("cumulative").print_stats(45)


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
