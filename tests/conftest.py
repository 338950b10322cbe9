import os
import tempfile
from pathlib import Path

import pytest

# Tests never reach the network, and figures render off-screen.
os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
# LeRobot reads HF_LEROBOT_HOME once, at import: point it at a private cache before anything imports
# lerobot, so tests never touch (or depend on) the user's real cache.
os.environ["HF_LEROBOT_HOME"] = tempfile.mkdtemp(prefix="gcs_push_lerobot_home_")


def gcs_push(*args: str) -> list[str]:
    """The `gcs-push` command line, run by this interpreter."""
    import sys

    return [sys.executable, "-m", "lerobot_gcs_push.cli", *args]


def kill_when(cmd: list[str], ready, timeout_s: float = 300.0) -> None:
    """Start `cmd` in a session of its own and SIGKILL the whole group as soon as `ready()` holds (or the
    command ends, or the timeout passes): an interruption at a chosen point, like an OOM kill."""
    import signal
    import subprocess
    import time

    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.time() + timeout_s
    while not ready() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.1)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


@pytest.fixture
def compilations(monkeypatch, tmp_path):
    """Calls to cvxpy's one entry point to compilation, `Problem.get_problem_data`, with the planner's
    cache of conic data in an empty directory."""
    import cvxpy as cp

    from lerobot_gcs_push.conic import CACHE_ENV

    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    calls = []
    original = cp.Problem.get_problem_data

    def counting(self, *args, **kwargs):
        calls.append(1)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(cp.Problem, "get_problem_data", counting)
    return calls


@pytest.fixture(scope="session")
def keypoint_policy(tmp_path_factory):
    """A tiny keypoint policy (LeRobot's DiffusionPolicy on gym-pusht's keypoints), trained 2 steps on 3
    replayed demonstrations: a real `pretrained_model` folder, its processors holding the data's statistics."""
    from pathlib import Path

    from lerobot_gcs_push.pusht.keypoint_training import (
        KeypointDataConfig,
        ScheduleConfig,
        TrainKeypointsConfig,
        train,
    )

    root = Path(__file__).parent.parent
    tmp = tmp_path_factory.mktemp("keypoint_policy")
    cfg = TrainKeypointsConfig(
        data=KeypointDataConfig(
            lists=[str(root / "experiments" / "pusht" / "demos" / "seed4800.json")],
            episodes=3,
            cache_dir=str(tmp / "cache"),
        ),
        schedule=ScheduleConfig(steps=2, batch_size=8, warmup_steps=1, save_every=2),
        preset=str(root / "configs" / "policy" / "diffusion_pusht_keypoints.json"),
        output_dir=str(tmp / "train"),
    )
    return str(train(cfg, progress=False))


def evaluate_on_pusht(policy: str, out, n: int) -> list[dict]:
    """`gcs-push evaluate` of one policy on n of gym-pusht's resets, 3 s each: its run records."""
    from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate, read_runs
    from lerobot_gcs_push.registration import PUSHT_ENV_ID

    cfg = EvaluateConfig(env_id=PUSHT_ENV_ID, policies=[policy], num_initial_conditions=n, runs=1, timeout_s=3.0,
                         videos=0, output_dir=str(out))  # fmt: skip
    evaluate(cfg)
    return read_runs(Path(out) / "runs.jsonl")
