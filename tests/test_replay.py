"""A dataset rebuilt from its replay list (`meta/gcs_push_replay.json`): the starts and actions alone give
back the same data, with no planning. The gym-pusht case is in tests/test_pusht_dataset.py (slow)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lerobot_gcs_push.generate import GenerateConfig, generate, read_episode_metadata
from lerobot_gcs_push.generate.replay import REPLAY_META, ReplayActions, entry_line


def _columns(root: Path) -> dict[str, np.ndarray]:
    import pyarrow.parquet as pq

    table = pq.read_table(sorted((root / "data").rglob("*.parquet"))).to_pandas()
    return {
        k: np.array([v["bytes"] for v in table[k]], object) if k == "observation.image" else np.stack(table[k])
        for k in table.columns
    }


@pytest.fixture(scope="module")
def box_dataset(tmp_path_factory):
    home = tmp_path_factory.mktemp("replay")
    cfg = GenerateConfig(episodes=2, repo_id="local/replay_src", root=str(home / "src"), workers=1, progress=False)
    generate(cfg)
    return home, Path(cfg.output.root)


def test_replay_list_holds_each_episodes_start_and_its_stored_actions(box_dataset):
    """Read against the dataset itself (LeRobot's loader), not against the writer's own arrays."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    _, root = box_dataset
    entries = json.loads((root / REPLAY_META).read_text())
    metas = read_episode_metadata(root)
    ds = LeRobotDataset("local/replay_src", root=root)
    assert len(entries) == len(metas) == ds.num_episodes == 2
    begin = 0
    for entry, meta in zip(entries, metas):
        assert entry["box"] == meta["box_initial"] and entry["finger"] == meta["finger_initial"]
        stored = np.stack([ds[begin + t]["action"].numpy() for t in range(meta["num_frames"])])
        assert np.array_equal(np.float32(entry["actions"]), stored)
        begin += meta["num_frames"]


def test_replaying_the_list_rebuilds_the_same_dataset(box_dataset):
    home, root = box_dataset
    cfg = GenerateConfig(
        repo_id="local/replay_copy",
        root=str(home / "copy"),
        initial_conditions=str(root / REPLAY_META),
        workers=1,
        progress=False,
    )
    assert cfg.expert.mode == "replay" and cfg.episodes == 2  # the list's own default
    report = generate(cfg)
    assert (report.episodes, report.failures) == (2, 0)
    copy, source = _columns(Path(cfg.output.root)), _columns(root)
    assert copy.keys() == source.keys()
    for key in copy:
        if key.startswith("observation.") and "image" not in key:
            # The Drake envs ran the expert's float64 commands; the list holds them as stored, in float32.
            np.testing.assert_allclose(copy[key], source[key], rtol=0, atol=1e-5, err_msg=key)
        else:  # actions, indices and the images' bytes: equal
            assert np.array_equal(copy[key], source[key]), key
    assert (Path(cfg.output.root) / REPLAY_META).read_text() == (root / REPLAY_META).read_text()


def test_a_replay_that_does_not_repeat_its_episode_fails_and_is_reported(box_dataset, tmp_path):
    """Actions cut short: the run holds the last action, never reaches the goal and is left out."""
    _, root = box_dataset
    entries = json.loads((root / REPLAY_META).read_text())
    entries[0]["actions"] = entries[0]["actions"][:3]  # the other runs whole, within the time given
    path = tmp_path / "cut.json"
    path.write_text(json.dumps(entries))
    cfg = GenerateConfig(
        repo_id="local/replay_cut",
        root=str(tmp_path / "cut"),
        initial_conditions=str(path),
        workers=1,
        progress=False,
        max_sim_time_s=max(len(e["actions"]) for e in entries) / 10 + 1,
    )
    report = generate(cfg)
    assert (report.episodes, report.failures) == (1, 1)


def test_replay_settings_are_checked_before_any_run(tmp_path):
    plain = tmp_path / "plain.json"
    plain.write_text(json.dumps([{"box": [2.0, 1.0], "finger": [-2.0, 0.5]}]))
    with pytest.raises(ValueError, match="initial_conditions list"):
        GenerateConfig(expert="replay")
    with pytest.raises(ValueError, match='initial condition 0 has no "actions"'):
        GenerateConfig(expert="replay", initial_conditions=str(plain))
    assert GenerateConfig(initial_conditions=str(plain)).expert.mode == "open-loop"
    acted = tmp_path / "acted.json"
    acted.write_text(json.dumps([{"box": [2.0, 1.0], "finger": [-2.0, 0.5], "actions": [[0.0, 0.0]]}]))
    with pytest.raises(ValueError, match="drop --disturbances"):
        GenerateConfig(initial_conditions=str(acted), disturbances=True)
    with pytest.raises(ValueError, match="finite rows"):
        ReplayActions().load([[0.0, float("nan")]])
    for bad in ([], [[0.0, "x"]], [[0.0, 1.0], [2.0]]):  # named with its entry before any run
        acted.write_text(json.dumps([{"box": [2.0, 1.0], "finger": [-2.0, 0.5], "actions": bad}]))
        with pytest.raises(ValueError, match="initial condition 0: replayed actions"):
            GenerateConfig(initial_conditions=str(acted))


def test_actions_are_written_exactly():
    """Shortest float32 text: read back and cast, every value is the same float32, bit for bit."""
    rng = np.random.default_rng(0)
    edges = np.float32([[0.0, 512.0], [1e-30, 3.4e38], [511.99997, 2**-20], [np.nextafter(np.float32(256), 0), -7.5]])
    actions = np.concatenate([rng.uniform(-600, 600, (500, 2)).astype(np.float32), edges])
    back = np.float32(json.loads(entry_line({"box": [0, 0], "finger": [1, 1], "actions": actions}))["actions"])
    assert back.tobytes() == actions.tobytes()
