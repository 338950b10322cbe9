"""The Ray backend on a real Ray cluster started here, on loopback only, and stopped at the end.

The evidence is the process pool's output for the same seeds: datasets equal frame by frame (images decoded
from their PNG bytes), evaluation records equal run by run, whatever the backend, worker count, shard size,
a worker killed mid-shard or a driver killed mid-run.
"""

from __future__ import annotations

import io
import json
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from conftest import gcs_push, kill_when

# Before Ray is imported: without it, Ray swaps 127.0.0.1 for the machine's reachable address and its
# servers listen there; with it, the whole cluster (GCS, raylet, workers) listens on loopback only.
os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
ray = pytest.importorskip("ray")

from lerobot_gcs_push.episodes.workers import open_pool  # noqa: E402
from lerobot_gcs_push.evaluation import TIMING_FIELDS, EvaluateConfig, evaluate, read_runs  # noqa: E402
from lerobot_gcs_push.generate import GenerateConfig, generate, read_episode_metadata  # noqa: E402
from lerobot_gcs_push.generate.shards import CRASH_ENV, SHARD_FILE  # noqa: E402

N = 4
# Before the cluster starts, so that its workers inherit it: a file `episode_<i>` in this folder kills the
# worker that is about to roll out episode i, once.
CRASH_DIR = Path(tempfile.mkdtemp(prefix="gcs_push_crash_"))
os.environ[CRASH_ENV] = str(CRASH_DIR)
# Per-episode metadata: timings differ from run to run, and the GCS relaxation's optimum differs in its last
# digits (1e-12 relative) with what the planner solved before in the same process: compared approximately.
EPISODE_TIMING = ("wall_time_s", "plan_time_s")
SOLVER_FLOATS = ("plan_cost", "plan_lower_bound")


@pytest.fixture(scope="module")
def cluster():
    """A one-node Ray cluster with 2 CPUs on 127.0.0.1; yields the address other drivers join it at."""
    ray.init(num_cpus=2, include_dashboard=False, _node_ip_address="127.0.0.1")
    address = ray.get_runtime_context().gcs_address
    assert address.startswith("127.0.0.1:")
    yield address
    ray.shutdown()


def _cfg(tmp: Path, name: str, **kw) -> GenerateConfig:
    return GenerateConfig(
        **{"episodes": N, "repo_id": f"local/{name}", "root": str(tmp / name), "progress": False, **kw}
    )


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The process backend in this process, all 4 episodes in one shard."""
    cfg = _cfg(tmp_path_factory.mktemp("ref"), "reference", workers=1)
    report = generate(cfg)
    assert report.episodes == N and report.shards == 1
    return Path(report.root)


def _columns(root: Path) -> dict[str, np.ndarray]:
    """Every stored column of a dataset, in stored order; images decoded from their PNG bytes."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    from PIL import Image

    table = pa.concat_tables([pq.read_table(f) for f in sorted((root / "data").rglob("*.parquet"))])
    out = {}
    for name in table.column_names:
        values = table.column(name).to_pylist()
        if name == "observation.image":
            out[name] = np.stack([np.asarray(Image.open(io.BytesIO(v["bytes"]))) for v in values])
        else:
            out[name] = np.asarray(values)
    return out


def _assert_same_dataset(root: Path, reference: Path) -> None:
    got, want = _columns(root), _columns(reference)
    assert sorted(got) == sorted(want)
    for name in want:
        np.testing.assert_array_equal(got[name], want[name], err_msg=name)
    got, want = read_episode_metadata(root), read_episode_metadata(reference)
    assert len(got) == len(want)
    for mine, theirs in zip(got, want, strict=True):
        exact = set(theirs) - set(EPISODE_TIMING) - set(SOLVER_FLOATS)
        assert {k: mine[k] for k in exact} == {k: theirs[k] for k in exact}
        for k in SOLVER_FLOATS:
            assert mine[k] == pytest.approx(theirs[k], rel=1e-9)


def _assert_each_episode_once(root: Path) -> None:
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata

    meta = read_episode_metadata(root)
    assert [m["episode_index"] for m in meta] == list(range(N))
    assert len({m["index"] for m in meta}) == N  # N distinct initial conditions
    info = LeRobotDatasetMetadata(f"local/{root.name}", root=root)
    assert info.total_episodes == N
    episodes = _columns(root)["episode_index"]
    assert np.all(np.diff(episodes) >= 0)
    assert np.bincount(episodes).tolist() == [m["num_frames"] for m in meta]
    assert not root.with_name(root.name + ".shards").exists() and not root.with_name(root.name + ".work").exists()


@pytest.mark.slow
def test_ray_and_process_backends_write_the_same_dataset(tmp_path, cluster, reference):
    """2 Ray actors and shards of at most 2 against 1 process and one shard: the same frames, images and
    metadata. The shards are [0, 2), then a worker's share of the 2 missing, [2, 3) and [3, 4)."""
    report = generate(_cfg(tmp_path, "ray", backend="ray", workers=2, shard_size=2))
    assert report.shards == 3 and report.episodes == N
    _assert_same_dataset(Path(report.root), reference)
    _assert_each_episode_once(Path(report.root))


@pytest.mark.slow
def test_a_worker_killed_mid_shard_loses_and_duplicates_nothing(tmp_path, cluster, reference):
    """The worker dies after the first episode of the shard [0, 2): Ray restarts it and runs the shard again."""
    trigger = CRASH_DIR / "episode_1"
    trigger.touch()
    report = generate(_cfg(tmp_path, "crash", backend="ray", workers=2, shard_size=2))
    assert not trigger.exists(), "the worker never reached episode 1"
    _assert_same_dataset(Path(report.root), reference)
    _assert_each_episode_once(Path(report.root))


@pytest.mark.slow
def test_a_frame_budget_reached_inside_a_shard_cuts_that_shard(tmp_path, reference):
    """`frames` are reached at episode 1, inside the shard [0, 3): the dataset is the reference's first two
    episodes, and nothing of the shard's third episode or of the shard [3, 4) queued behind it is kept. (The
    cut is the driver's, the same for every backend: the process backend in this process is the cheapest.)"""
    budget = read_episode_metadata(reference)[0]["num_frames"] + 1
    report = generate(_cfg(tmp_path, "budget", frames=budget, workers=1, shard_size=3))
    assert (report.episodes, report.attempts, report.shards) == (2, 2, 1)
    got, want = _columns(Path(report.root)), _columns(reference)
    first_two = want["episode_index"] < 2
    for name in want:
        np.testing.assert_array_equal(got[name], want[name][first_two], err_msg=name)
    assert [m["index"] for m in read_episode_metadata(Path(report.root))] == [0, 1]


@pytest.mark.slow
def test_a_killed_driver_resumes_keeping_its_finished_shards(tmp_path, cluster, reference):
    """A CLI driver joins the cluster at its address and is killed once it has shards; the resumed run (another
    shard size and worker count) takes them as they are: their episodes keep the wall times they were run in."""
    root = tmp_path / "killed"
    shards = tmp_path / "killed.shards"
    cmd = gcs_push(
        "generate",
        f"--episodes={N}",
        "--repo_id=local/killed",
        f"--root={root}",
        "--workers=1",
        "--shard_size=1",
        "--backend=ray",
        f"--ray_address={cluster}",
    )
    kill_when(cmd, lambda: bool(list(shards.glob("shard_*"))))
    assert not root.exists(), "a killed run must leave no dataset"
    finished = [json.loads((p / SHARD_FILE).read_text()) for p in shards.glob("shard_*")]
    assert 0 < len(finished) < N

    generate(_cfg(tmp_path, "killed", backend="ray", workers=1, shard_size=3, resume=True))
    _assert_same_dataset(root, reference)
    _assert_each_episode_once(root)
    meta = {m["index"]: m for m in read_episode_metadata(root)}
    for shard in finished:
        for episode in shard["episodes"]:
            assert meta[episode["index"]]["wall_time_s"] == episode["wall_time_s"], "a finished shard was run again"


@pytest.mark.slow
def test_evaluation_records_match_the_process_pool(tmp_path, cluster):
    ics = tmp_path / "ics.json"
    ics.write_text(
        json.dumps([{"box": [2.0, -1.5], "finger": [-2.0, 1.0]}, {"box": [-3.0, 3.5], "finger": [0.5, -4.0]}])
    )
    common = dict(
        policies=["gcs-open-loop", "gcs-closed-loop"],
        disturbances=True,
        initial_conditions=str(ics),
        runs=1,
        videos=0,
        workers=2,
        timeout_s=120.0,
    )
    runs = {}
    for backend in ("process", "ray"):
        out = tmp_path / backend
        evaluate(EvaluateConfig(**common, output_dir=str(out), backend=backend))
        runs[backend] = sorted(read_runs(out / "runs.jsonl"), key=lambda r: (r["label"], r["initial_condition_index"]))
    assert len(runs["ray"]) == 6  # 2 ICs x (open loop, closed loop, closed loop with disturbances)
    assert any(r["num_disturbances"] > 0 for r in runs["ray"])
    for mine, theirs in zip(runs["ray"], runs["process"], strict=True):
        assert {k: v for k, v in mine.items() if k not in TIMING_FIELDS} == {
            k: v for k, v in theirs.items() if k not in TIMING_FIELDS
        }
        a, b = np.load(tmp_path / "ray" / mine["trajectory"]), np.load(tmp_path / "process" / theirs["trajectory"])
        np.testing.assert_array_equal(a["finger"], b["finger"])
        np.testing.assert_array_equal(a["box"], b["box"])


@pytest.mark.slow
def test_pools_return_every_result_and_report_a_worker_that_keeps_dying(cluster):
    """Both backends: every result once; a job calling os._exit is retried by Ray, then
    given up, while the process pool gives up at once: an error naming what to do, never a hang."""
    for backend in ("process", "ray"):
        with open_pool(backend, 2, int, ()) as pool:
            assert sorted(pool.map(abs, range(0, -6, -1))) == [0, 1, 2, 3, 4, 5]
            assert sorted(pool.map(abs, [-7, 8])) == [7, 8]
        with open_pool(backend, 2, int, (), hint="HINT") as pool, pytest.raises(RuntimeError, match="(?s)died.*HINT"):
            list(pool.map(os._exit, [1]))
    with pytest.raises(ValueError, match="3 workers need 3 CPUs"):
        with open_pool("ray", 3, int, ()):
            pass


def test_bad_backend_settings_are_named():
    with pytest.raises(ValueError, match="unknown backend"):
        GenerateConfig(backend="dask")
    with pytest.raises(ValueError, match="needs backend ray"):
        EvaluateConfig(ray_address="auto")
    with pytest.raises(ValueError, match="shard_size"):
        GenerateConfig(shard_size=0)
