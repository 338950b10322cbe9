"""Branch states without a cost-to-go (stalls.py): the stall rule on hand-computed coverage, the runs and
states it picks from hand-made rollout folders, and the gym-pusht starts it writes, checked in gym-pusht."""

import json
from types import SimpleNamespace

import numpy as np
import pytest

from lerobot_gcs_push.evaluation import GCS_POLICIES
from lerobot_gcs_push.improve.stalls import StallRule, stall_branch_states, stall_steps
from lerobot_gcs_push.registration import PUSHT_ENV_ID, SCENES, make_env

SCENE = SCENES[PUSHT_ENV_ID]


def test_a_stall_is_a_chunk_whose_coverage_two_seconds_later_has_not_grown():
    # 10 fps, judged 20 steps ahead, chunks every 8. Coverage climbs 0.01 a step to 0.5 at step 50, stays
    # there to step 80, falls 0.01 a step to step 100; the final state is step 100.
    cov = np.r_[np.arange(51) * 0.01, np.full(30, 0.5), 0.5 - 0.01 * np.arange(1, 21)]
    assert len(cov) == 101
    rule = StallRule(window_s=2.0, min_gain=0.02, every=8)
    # Chunk starts 0, 8, ..., 96. Gain over 20 steps: k <= 30 climbs 0.2; k = 32 reaches 0.5 at 52 (+0.18);
    # k = 40: +0.10; k = 48: 0.48 -> 0.5 (+0.02, not below); k = 56, 64, 72, 80, 88, 96: flat or falling.
    assert stall_steps(cov, 10, rule, 0.95).tolist() == [56, 64, 72, 80, 88, 96]
    assert stall_steps(cov, 10, StallRule(min_gain=0.021), 0.95).tolist() == [48, 56, 64, 72, 80, 88, 96]
    # A state at success is never a branch state, however flat its coverage.
    assert stall_steps(np.full(40, 0.97), 10, rule, 0.95).tolist() == []
    with pytest.raises(ValueError, match="stall.window_s"):
        StallRule(window_s=0)


def pusht_poses(n, still_from=None):
    """gym-pusht's T sliding 1 px a step along the diagonal toward its goal from 60 px away (coverage 0.29
    there, 0.43 at 30 px, 1 at the goal), still from step `still_from` on; its agent parked at (100, 400) px.
    As (slider poses, fingers) in metres, through the scene's frame."""
    pairs = []
    for k in range(n):
        off = 60.0 - min(k, still_from if still_from is not None else k)
        state = np.array([100.0, 400.0, 256.0 + off / np.sqrt(2), 256.0 + off / np.sqrt(2), np.pi / 4])
        pairs.append(SCENE.frame.pose_finger_of(state))
    return np.array([p for p, _ in pairs]), np.array([f for _, f in pairs])


def write_folder(tmp_path, runs):
    """An evaluation folder as `gcs-push evaluate` writes it: runs.jsonl and one trajectory per run."""
    (tmp_path / "trajectories").mkdir()
    lines = []
    for i, (policy, success, sim_time_s, poses, fingers) in enumerate(runs):
        path = tmp_path / "trajectories" / f"run{i}.npz"
        np.savez(path, slider_pose=poses, finger=fingers, box=poses[:, :2])
        lines.append(
            {
                "policy": policy,
                "label": policy,
                "disturbances": False,
                "initial_condition_index": i // 2,
                "run": 0,
                "success": success,
                "sim_time_s": sim_time_s,
                "trajectory": f"trajectories/run{i}.npz",
                "_source": str(tmp_path),
            }
        )
    return lines


def test_failed_and_slow_runs_are_branched_from_where_they_stall(tmp_path):
    fast, dawdling, stuck = pusht_poses(40), pusht_poses(60, still_from=30), pusht_poses(120, still_from=10)
    records = write_folder(
        tmp_path,
        [
            ("gcs-closed-loop", True, 3.0, *fast),  # start 0: the expert, 3 s
            ("policy", True, 3.5, *dawdling),  # start 0: stalls, but within 1.3 x the expert's time: left out
            ("gcs-closed-loop", True, 3.0, *fast),  # start 1: the expert, 3 s
            ("policy", False, 12.0, *stuck),  # start 1: the T stops 40 px short and the run fails
        ],
    )
    cfg = SimpleNamespace(stall=StallRule(), keep_fraction=0.0, max_per_run=4, seed=0)
    states = stall_branch_states(records, cfg, SCENE, GCS_POLICIES)
    # The stuck run (120 states, chunk starts 0, 8, ..., 112): still from step 10, so every chunk from 16
    # on stalls; chunk 8 gains 2 px of approach in 20 steps (coverage about +0.01) and stalls too; chunk 0
    # gains 10 px (+0.05) and does not. 14 stalls, 4 kept at linspace(0, 13, 4) -> 0, 4, 9, 13.
    steps = [s["source"]["step"] for s in states]
    assert all(s["source"]["initial_condition_index"] == 1 and s["source"]["why"] == "stall" for s in states)
    assert steps == [8, 40, 80, 112]
    # More than 1.3 x slower than the expert's on its start, the same success is branched from where it
    # stalls: still from step 30, so chunks 32-56 stall; chunk 24 gains 6 px in 20 steps (coverage about
    # +0.03, slope 0.0048 a px between 40 and 30 px off) and does not.
    records[1]["sim_time_s"] = 4.0
    slow = [s for s in stall_branch_states(records, cfg, SCENE, GCS_POLICIES) if s["source"]["run_slow"]]
    assert [s["source"]["step"] for s in slow] == [32, 40, 48, 56]
    # The same rule, seeds and records: the same list.
    assert stall_branch_states(records, cfg, SCENE, GCS_POLICIES) == stall_branch_states(
        records, cfg, SCENE, GCS_POLICIES
    )


def test_a_pusht_branch_state_is_one_gym_pusht_resets_to(tmp_path):
    """gym-pusht itself (pymunk) reports the state each entry was made from, and the planner's metres."""
    poses, fingers = pusht_poses(120, still_from=10)
    records = write_folder(tmp_path, [("policy", False, 12.0, poses, fingers)])
    cfg = SimpleNamespace(stall=StallRule(), keep_fraction=0.0, max_per_run=3, seed=0)
    states = stall_branch_states(records, cfg, SCENE, GCS_POLICIES)
    assert len(states) == 3
    env = make_env(PUSHT_ENV_ID, obs_type="state")
    try:
        for s in states:
            json.dumps(s)  # an initial-condition file entry
            obs, info = env.reset(options={"pusht_state": s["pusht_state"]})
            np.testing.assert_allclose(obs, s["pusht_state"], atol=1e-6)
            k = s["source"]["step"]
            np.testing.assert_allclose(info["slider_pose"], poses[k], atol=1e-6)
            np.testing.assert_allclose(info["finger"], fingers[k], atol=1e-6)
    finally:
        env.close()


@pytest.mark.slow
def test_collect_labels_a_pusht_stall_with_the_expert(tmp_path):
    """`gcs-push collect` on a gym-pusht rollout folder: the expert starts from the stalled state (gym-pusht's
    own first observation is that state's agent position) and brings the T to gym-pusht's success."""
    import subprocess

    from conftest import gcs_push
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    poses, fingers = pusht_poses(60, still_from=10)
    folder = tmp_path / "rollouts"
    folder.mkdir()
    records = write_folder(folder, [("policy", False, 6.0, poses, fingers)])
    (folder / "runs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    (folder / "settings.json").write_text(json.dumps({"env_id": PUSHT_ENV_ID}))
    repo = "local/test_stall_collect"
    out = subprocess.run(
        gcs_push("collect", f"--rollouts=[{folder}]", f"--repo_id={repo}", "--max_per_run=1", "--workers=1"),
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    ds = LeRobotDataset(repo)
    assert ds.meta.total_episodes == 1
    first = ds[0]
    start = SCENE.frame.state_of(poses[8], fingers[8])  # the one state kept: linspace over the stalls from 8
    np.testing.assert_allclose(first["observation.state"].numpy(), start[:2], atol=1e-3)
    assert bool(ds.hf_dataset["next.success"][-1])
