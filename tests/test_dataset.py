"""The demonstration generator: file contents against the planner, the env and the images."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import gcs_push, kill_when

from lerobot_gcs_push.generate import FEATURE_KEYS, GenerateConfig, generate, read_episode_metadata
from lerobot_gcs_push.scene import Scene

N = 3


def _cfg(tmp: Path, name: str, **kw) -> GenerateConfig:
    return GenerateConfig(
        **{"episodes": N, "repo_id": f"local/{name}", "root": str(tmp / name), "workers": 1, "progress": False, **kw}
    )


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """3 episodes written to the default place: $HF_LEROBOT_HOME/<repo_id>."""
    cfg = GenerateConfig(episodes=N, repo_id="local/test_gcs_push", workers=1, progress=False)
    report = generate(cfg)
    return cfg, report


def _load(repo_id, root=None, **kw):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    return LeRobotDataset(repo_id, root=root, video_backend="pyav", **kw)


def _episodes(ds):
    starts = np.asarray(ds.meta.episodes["dataset_from_index"])
    ends = np.asarray(ds.meta.episodes["dataset_to_index"])
    return list(zip(starts, ends))


def test_dataset_loads_from_the_lerobot_cache_with_the_right_features(reference):
    cfg, report = reference
    assert Path(report.root) == Path(os.environ["HF_LEROBOT_HOME"]) / cfg.output.repo_id
    ds = _load(cfg.output.repo_id)  # no root: LeRobot's own cache lookup, offline
    assert ds.meta.total_episodes == N and ds.fps == 10
    assert set(FEATURE_KEYS) <= set(ds.meta.features)
    assert ds.meta.features["observation.image"]["dtype"] == "image"
    for key in ("observation.state", "observation.environment_state", "action"):
        assert ds.meta.features[key]["dtype"] == "float32" and tuple(ds.meta.features[key]["shape"]) == (2,)
    item = ds[0]
    assert tuple(item["observation.image"].shape) == (3, 96, 96)
    assert item["task"] == "Push the red box onto the green goal."
    meta = read_episode_metadata(report.root)
    assert [m["num_frames"] for m in meta] == [e - s for s, e in _episodes(ds)]
    assert all(m["success"] for m in meta) and ds.meta.total_frames == report.frames


def test_frames_match_the_planner_and_the_initial_condition(reference):
    """Actions are the expert's commands, recomputed here from an independent planner call; the first
    state is the initial condition; the box sits in the image where the state says."""
    from lerobot_gcs_push.box_gcs import GcsPlanner
    from lerobot_gcs_push.planning import Speeds
    from lerobot_gcs_push.sim import PushSim

    cfg, report = reference
    ds = _load(cfg.output.repo_id)
    scene = Scene()
    planner = GcsPlanner(scene)
    sim = PushSim(scene, render_size=None)
    for (start, end), meta in zip(_episodes(ds), read_episode_metadata(report.root)):
        frames = [ds[int(i)] for i in range(start, end)]
        actions = np.stack([f["action"].numpy() for f in frames])
        plan = planner.plan(meta["box_initial"], meta["finger_initial"])
        assert plan.cost == pytest.approx(meta["plan_cost"], rel=1e-6)
        cmds = plan.schedule(cfg.fps, Speeds(), scene.push_lag_s).commands
        n = min(len(cmds), len(actions))
        np.testing.assert_allclose(actions[:n], cmds[:n], atol=1e-5)
        assert np.all(actions[n:] == actions[n - 1])  # then it holds the final command
        first = frames[0]
        np.testing.assert_allclose(first["observation.state"].numpy(), meta["finger_initial"], atol=1e-5)
        np.testing.assert_allclose(first["observation.environment_state"].numpy(), meta["box_initial"], atol=1e-5)
        # Red pixels: their centroid is where the box's recorded position projects.
        img = (first["observation.image"].numpy().transpose(1, 2, 0) * 255).astype(int)
        red = (img[..., 0] > 150) & (img[..., 1] < 90) & (img[..., 2] < 90)
        assert red.sum() > 20
        rows, cols = np.nonzero(red)
        expected = sim.world_to_pixel(meta["box_initial"])
        assert np.hypot(rows.mean() - expected[0], cols.mean() - expected[1]) < 1.5
        # Every stored image is the scene rendered afresh at that frame's recorded positions: the PNG
        # bytes were embedded intact and in order. Measured: identical pixels here, while the next frame's
        # image differs in 20-60 pixels by more than 8 levels (float32 positions may move an edge pixel).
        for f in (frames[0], frames[len(frames) // 2], frames[-1]):
            sim.reset(f["observation.environment_state"].numpy(), f["observation.state"].numpy())
            stored = np.round(f["observation.image"].numpy().transpose(1, 2, 0) * 255).astype(int)
            diff = np.abs(stored - sim.image().astype(int))
            assert np.count_nonzero(diff > 8) <= 3, np.count_nonzero(diff > 8)
        # The final frame is within reach of success (the env ends episodes on success).
        last_box = frames[-1]["observation.environment_state"].numpy()
        assert np.linalg.norm(last_box - scene.goal_array) < 0.1 + 0.05


def test_refuses_to_overwrite_without_a_flag(reference):
    cfg, _ = reference
    with pytest.raises(FileExistsError, match="--overwrite"):
        generate(cfg)


def _digest(root: Path) -> str:
    """Hash of every stored value, PNG bytes included. (The parquet files' footers also carry a random
    fingerprint from the `datasets` library, so whole-file bytes cannot match across runs.)"""
    import pyarrow.parquet as pq

    h = hashlib.sha256()
    for f in sorted((root / "data").rglob("*.parquet")):
        table = pq.read_table(f)
        for name in table.schema.names:
            h.update(name.encode())
            h.update(repr(table.column(name).to_pylist()).encode())
    return h.hexdigest()


@pytest.mark.slow
def test_worker_count_and_interruption_do_not_change_the_dataset(tmp_path, reference):
    """workers=2 writes the same data as workers=1; a run killed midway and resumed equals both."""
    _, report = reference
    two = _cfg(tmp_path, "two", workers=2)
    generate(two)
    assert _digest(Path(two.output.root)) == _digest(Path(report.root))

    root = tmp_path / "killed"
    cmd = gcs_push("generate", f"--episodes={N}", "--repo_id=local/killed", f"--root={root}", "--workers=1")
    work = root.with_name(root.name + ".work")
    kill_when(cmd, lambda: bool(list(work.glob("episode_*.npz"))))
    assert not root.exists(), "a killed run must leave no dataset in the cache"
    res = subprocess.run(cmd, capture_output=True, text=True)
    assert res.returncode != 0 and "--resume" in res.stderr
    subprocess.run(cmd + ["--resume=true"], check=True, capture_output=True)
    assert _digest(root) == _digest(Path(report.root))
    assert not work.exists()

    # Resuming a finished run reports it and leaves it alone; asking it for something else is refused.
    stamp = (root / "meta/info.json").stat().st_mtime_ns
    res = subprocess.run(cmd + ["--resume=true"], check=True, capture_output=True, text=True)
    assert f"already complete: {N} demonstrations" in res.stdout
    assert (root / "meta/info.json").stat().st_mtime_ns == stamp
    res = subprocess.run(cmd + ["--resume=true", "--seed=1"], capture_output=True, text=True)
    assert res.returncode != 0 and "other settings" in res.stderr and "seed: 0 -> 1" in res.stderr


def test_a_merge_holds_each_datasets_episodes_in_turn(reference):
    """LeRobot's aggregation as `improve` merges its rounds (`merge_datasets`): the reference twice is every
    stored value of the reference, then every one again with its episode and frame indices continued; a
    merge already made is kept as it is; a missing input is named."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from lerobot_gcs_push.generate import merge_datasets

    def table(root: Path):
        return pa.concat_tables([pq.read_table(f) for f in sorted((root / "data").rglob("*.parquet"))])

    cfg, report = reference
    twice = merge_datasets([cfg.output.repo_id, cfg.output.repo_id], "local/test_gcs_push_twice", desc="test merge")
    assert _load("local/test_gcs_push_twice").meta.total_episodes == 2 * N
    one, two = table(Path(report.root)), table(twice)
    assert two.num_rows == 2 * one.num_rows == 2 * report.frames
    shift = {"episode_index": N, "index": one.num_rows}
    for name in one.column_names:
        values = one.column(name).to_pylist()
        again = [v + shift[name] for v in values] if name in shift else values
        assert two.column(name).to_pylist() == values + again, name
    stamp = (twice / "meta" / "info.json").stat().st_mtime_ns
    assert merge_datasets([cfg.output.repo_id], "local/test_gcs_push_twice") == twice
    assert (twice / "meta" / "info.json").stat().st_mtime_ns == stamp
    with pytest.raises(FileNotFoundError, match="local/no_such_dataset"):
        merge_datasets([cfg.output.repo_id, "local/no_such_dataset"], "local/test_gcs_push_other")


def test_bad_settings_are_named(tmp_path, monkeypatch):
    with pytest.raises(ValueError, match="unknown expert"):
        GenerateConfig(expert="human")
    with pytest.raises(ValueError, match="not both"):
        GenerateConfig(overwrite=True, resume=True)
    with pytest.raises(ValueError, match="owner/name"):
        GenerateConfig(repo_id="nodash")
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    with pytest.raises(ValueError, match="HF_HUB_OFFLINE=0"):  # before any demonstration, not after all
        GenerateConfig(push_to_hub=True)
    # --episodes defaults to one try of every listed initial condition, else 100.
    ics = tmp_path / "ics.json"
    ics.write_text(json.dumps([{"box": [2.0, 1.0], "finger": [-2.0, 0.5]}] * 3))
    assert GenerateConfig().episodes == 100
    assert GenerateConfig(initial_conditions=str(ics)).episodes == 3
    assert GenerateConfig(initial_conditions=str(ics), episodes=2).episodes == 2
    # --overwrite deletes a dataset, never a folder that is not one.
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "thesis.tex").write_text("x")
    with pytest.raises(FileExistsError, match="is not one"):
        generate(GenerateConfig(root=str(notes), overwrite=True, workers=1, progress=False))
    assert (notes / "thesis.tex").read_text() == "x"


@pytest.mark.parametrize(
    "content, needle",
    [
        ('[{"box": [1, 2]}]', "entry 0 must be"),
        ("[1, 2]", "entry 0 must be"),
        ("{", "not valid JSON"),
        (None, "Is a directory"),
    ],
)
def test_bad_initial_conditions_file_gets_its_own_message(tmp_path, content, needle):
    """The CLI shows the message written for the user, not the KeyError or TypeError behind it."""
    path = tmp_path / "ics.json"
    path.mkdir() if content is None else path.write_text(content)
    res = subprocess.run(
        gcs_push("generate", f"--initial_conditions={path}", f"--root={tmp_path / 'ds'}"),
        capture_output=True,
        text=True,
    )
    assert res.returncode == 2 and needle in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "ds").exists()


@pytest.mark.slow
def test_lerobot_dataset_viz_reads_a_generated_dataset(reference, tmp_path):
    """LeRobot's own viewer (the `viz` extra, rerun) saves an episode of ours as a recording of it."""
    import shutil

    viz = shutil.which("lerobot-dataset-viz", path=str(Path(sys.executable).parent))
    assert viz, "make install installs lerobot[viz], which provides lerobot-dataset-viz"
    cfg, report = reference
    args = [viz, "--repo-id", cfg.output.repo_id, "--episode-index", "1", "--save", "1", "--output-dir", str(tmp_path)]
    subprocess.run([*args, "--num-workers", "0"], check=True, capture_output=True, timeout=300)
    rrd = tmp_path / f"{cfg.output.repo_id.replace('/', '_')}_episode_1.rrd"
    assert rrd.stat().st_size > 10_000  # 96x96 frames of the episode, not an empty recording
    printed = subprocess.run(
        [str(Path(sys.executable).parent / "rerun"), "rrd", "print", str(rrd)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert f'"{cfg.output.repo_id}/episode_1"' in printed.stdout + printed.stderr
