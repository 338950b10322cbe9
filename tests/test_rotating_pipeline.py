"""The pipeline on the rotating envs (issue 32, part 5): rollouts keep the heading and the slider's pose,
datasets store the pose, a learned policy is evaluated by coverage, and regret and collect (which need the
GCS cost-to-go) refuse clearly."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from conftest import gcs_push

import lerobot_gcs_push  # noqa: F401  (registers the envs)
from lerobot_gcs_push.episodes.rollout import rollout
from lerobot_gcs_push.evaluation import EvaluateConfig, Trajectory, read_runs
from lerobot_gcs_push.generate import FEATURE_KEYS, EpisodeFrames, GenerateConfig
from lerobot_gcs_push.generate.frames import _Writer
from lerobot_gcs_push.registration import ENV_ID, SCENES, SE2_ENV_ID, TEE_ENV_ID
from lerobot_gcs_push.scene import sample_initial_conditions, wrap_angle

POLICY = Path(__file__).resolve().parents[1] / "policies" / "diffusion_cpu"


class TowardsTheSlider:
    """Drives the finger at the slider's centre: it meets the slider and pushes (and turns) it."""

    def reset(self, obs, info, seed):
        pass

    def act(self, obs, info):
        return np.asarray(info["box"], float)


def _env_pose(env) -> np.ndarray:
    """The slider's pose read from the simulator itself, not from the env's info."""
    return np.array([*env.sim.box_position(), wrap_angle(env.sim.box_heading())])


def test_a_rotating_rollout_keeps_its_heading_and_its_slider_pose_to_the_end():
    env = gym.make(TEE_ENV_ID, max_sim_time_s=3.0).unwrapped
    traj = Trajectory(env.scene.kind.trajectory_keys)
    res = rollout(env, TowardsTheSlider(), [1.5, -1.0], [-1.5, 1.0], seed=0, on_step=lambda o, a, i: traj.add(i),
                  heading=1.2)  # fmt: skip
    traj.add_final(res)
    poses = np.array(traj.rows["slider_pose"])
    assert len(poses) == round(3.0 * env.fps) + 1  # one per step and the final state
    np.testing.assert_allclose(poses[0], [1.5, -1.0, 1.2], atol=1e-9)  # reset with the heading given
    assert np.ptp(poses[:, 2]) > 0.01, "the push should have turned the T"
    np.testing.assert_allclose(poses[-1], _env_pose(env), atol=1e-12)
    np.testing.assert_allclose(res["slider_pose_final"], _env_pose(env), atol=1e-12)
    assert res["coverage"] == pytest.approx(env.scene.coverage(_env_pose(env)), abs=1e-12)
    assert res["heading_error"] == pytest.approx(wrap_angle(_env_pose(env)[2] + math.pi / 4), abs=1e-12)
    np.testing.assert_allclose(np.array(traj.rows["box"]), poses[:, :2])


def test_a_rotating_slider_episode_is_stored_with_its_pose_and_its_task(tmp_path):
    """The dataset's environment state is the slider's (x, y, heading) at each frame, and the task is the
    scene's; written by the same writer as the box's datasets."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    env = gym.make(TEE_ENV_ID, max_sim_time_s=1.0).unwrapped
    frames, poses = EpisodeFrames(env.scene), []

    def on_step(obs, action, info):
        poses.append(np.array(info["slider_pose"]))
        frames(obs, action, info)

    rollout(env, TowardsTheSlider(), [1.0, 0.5], [-0.5, -1.0], seed=0, on_step=on_step, heading=-2.0)
    cfg = GenerateConfig(env_id=TEE_ENV_ID, episodes=1, repo_id="local/tee_frames", progress=False)
    writer = _Writer(cfg, tmp_path / "ds")
    writer.add(frames.arrays())
    writer.finish()
    ds = LeRobotDataset("local/tee_frames", root=tmp_path / "ds", video_backend="pyav")
    feature = ds.meta.features["observation.environment_state"]
    assert tuple(feature["shape"]) == (3,) and feature["names"] == ["slider_x", "slider_y", "slider_heading"]
    stored = np.stack([ds[i]["observation.environment_state"].numpy() for i in range(len(ds))])
    np.testing.assert_allclose(stored, np.array(poses, np.float32))
    assert stored[0, 2] == pytest.approx(-2.0, abs=1e-6)
    assert ds[0]["task"] == SCENES[TEE_ENV_ID].task == "Push the red T onto the green outline."
    assert set(FEATURE_KEYS) <= set(ds.meta.features)


@pytest.mark.parametrize("env_id", [SE2_ENV_ID, TEE_ENV_ID])
def test_regret_refuses_a_rotating_env_by_name_and_the_experts_do_not(env_id):
    needle = f"no GCS cost-to-go for {env_id} yet"
    with pytest.raises(ValueError, match=needle + r".*regret"):
        EvaluateConfig(env_id=env_id, policies=[str(POLICY)], regret=True)
    # Regret defaults on where the env has a cost-to-go, off where it has none.
    assert EvaluateConfig(env_id=env_id, policies=[str(POLICY)]).regret is False
    assert EvaluateConfig(policies=[str(POLICY)]).regret is True
    for policy in ("gcs-open-loop", "gcs-closed-loop"):  # the experts plan through contact (test_expert_turning.py)
        assert EvaluateConfig(env_id=env_id, policies=[policy]).regret is False
    # Demonstrations of a rotating slider default to the closed-loop expert and plan with the relaxation only.
    assert GenerateConfig(env_id=env_id).expert.mode == "closed-loop" and GenerateConfig().expert.mode == "open-loop"
    with pytest.raises(ValueError, match="relaxation only"):
        GenerateConfig(env_id=env_id, method="micp")


def test_an_unknown_env_id_is_refused_with_the_choices(tmp_path):
    for make in (EvaluateConfig, GenerateConfig):
        with pytest.raises(ValueError, match=f"unknown env_id 'GcsPushTee-v0'.*{ENV_ID}.*{TEE_ENV_ID}"):
            make(env_id="GcsPushTee-v0")
    res = subprocess.run(
        gcs_push("evaluate", f"--env_id={SE2_ENV_ID}", "--policies=[gcs-closed-loop]", "--regret=true",
                 f"--output_dir={tmp_path}"),
        capture_output=True,
        text=True,
    )  # fmt: skip
    assert res.returncode == 2 and f"no GCS cost-to-go for {SE2_ENV_ID} yet" in res.stderr
    assert "Traceback" not in res.stderr and not (tmp_path / "runs.jsonl").exists()


@pytest.fixture(scope="module")
def tee_eval(tmp_path_factory):
    """The shipped policy (trained on the box) on the T, from the command line: it fails, by coverage."""
    out = tmp_path_factory.mktemp("tee") / "eval"
    args = [f"--env_id={TEE_ENV_ID}", f"--policies=[{POLICY}]", "--num_initial_conditions=2", "--runs=1"]
    subprocess.run(gcs_push("evaluate", *args, "--timeout_s=5", "--videos=1", f"--output_dir={out}"), check=True,
                   capture_output=True)  # fmt: skip
    return out


@pytest.mark.slow
def test_a_learned_policy_is_evaluated_on_the_tee_by_coverage(tee_eval):
    out = tee_eval
    settings = json.loads((out / "settings.json").read_text())
    assert settings["env_id"] == TEE_ENV_ID and settings["regret"] is False
    # The initial conditions are the T scene's own, headings included.
    expected = [ic.to_json() for ic in sample_initial_conditions(SCENES[TEE_ENV_ID], 2, seed=1000, sampler="uniform")]
    assert settings["initial_conditions"] == expected and all("heading" in ic for ic in expected)
    recs = sorted(read_runs(out / "runs.jsonl"), key=lambda r: r["initial_condition_index"])
    assert len(recs) == 2
    for rec, ic in zip(recs, expected):
        assert rec["heading_initial"] == ic["heading"]
        assert 0.0 <= rec["coverage"] <= 1.0 and rec["success"] == (rec["coverage"] >= 0.95)
        assert "regret" not in rec and "success_0.2" not in rec
        assert rec["sim_time_s"] == pytest.approx(5.0) or rec["success"]
        traj = np.load(out / rec["trajectory"])
        np.testing.assert_allclose(traj["slider_pose"][0], [*ic["box"], wrap_angle(ic["heading"])], atol=1e-9)
        np.testing.assert_allclose(traj["slider_pose"][-1], rec["slider_pose_final"])
        assert rec["coverage"] == pytest.approx(SCENES[TEE_ENV_ID].coverage(traj["slider_pose"][-1]), abs=1e-12)
        assert len(traj["slider_pose"]) == len(traj["finger"]) == round(rec["sim_time_s"] * 10) + 1
    md = (out / "tables.md").read_text()
    assert f"on {TEE_ENV_ID}" in md and "success (coverage >= 0.95)" in md and "mean coverage" in md
    summary = json.loads((out / "summary.json").read_text())
    (variant,) = summary["variants"].values()
    assert variant["coverage"] == pytest.approx(np.mean([r["coverage"] for r in recs]))
    assert len(list((out / "videos").glob("*.mp4"))) == 1
    for name in ("fig6_success_map.png", "fig7_trajectories.png"):
        assert (out / name).stat().st_size > 10_000


def _drawn_fig7(monkeypatch, cfg, out, records, ics):
    """Fig. 7 drawn as evaluate draws it, kept open to read its artists."""
    import matplotlib.pyplot as plt

    from lerobot_gcs_push.evaluation.figures import fig7_trajectories

    monkeypatch.setattr(plt, "close", lambda *a, **k: None)
    fig7_trajectories(cfg, out, records, ics)
    fig = plt.figure(plt.get_fignums()[-1])
    monkeypatch.undo()
    return fig


def _polygons(ax, gid: str) -> list[np.ndarray]:
    return [p.get_xy()[:-1] for p in ax.patches if p.get_gid() == gid]  # matplotlib closes the ring


@pytest.mark.slow
def test_fig7_draws_the_slider_outline_along_the_path_and_at_the_goal(tee_eval, monkeypatch):
    import matplotlib.pyplot as plt

    out = tee_eval
    scene = SCENES[TEE_ENV_ID]
    settings = json.loads((out / "settings.json").read_text())
    ics = settings["initial_conditions"]
    records = read_runs(out / "runs.jsonl")
    cfg = EvaluateConfig(env_id=TEE_ENV_ID, policies=[str(POLICY)], output_dir=str(out))
    fig = _drawn_fig7(monkeypatch, cfg, out, records, ics)
    for i, ax in enumerate(fig.axes[: len(ics)]):
        (goal,) = _polygons(ax, "goal")
        np.testing.assert_allclose(goal, scene.shape.world_outline(scene.goal_pose))
        (start,) = _polygons(ax, "start")
        np.testing.assert_allclose(start, scene.shape.world_outline((*ics[i]["box"], ics[i]["heading"])))
        rec = next(r for r in records if r["initial_condition_index"] == i)
        along = _polygons(ax, "along_path")
        assert len(along) == 4
        np.testing.assert_allclose(along[-1], scene.shape.world_outline(rec["slider_pose_final"]))
    plt.close(fig)
    # The box's figure keeps its squares: no outlines along the path.
    box_cfg = EvaluateConfig(policies=[str(POLICY)], output_dir=str(out))
    box_ics = [{"box": ic["box"], "finger": ic["finger"]} for ic in ics]
    fig = _drawn_fig7(monkeypatch, box_cfg, out, records, box_ics)
    assert not any(p.get_gid() for ax in fig.axes for p in ax.patches)
    assert sum(len(ax.patches) for ax in fig.axes[: len(ics)]) == 2 * len(ics)
    plt.close(fig)


@pytest.mark.slow
def test_collect_takes_the_env_from_the_rollouts_and_branches_where_the_ts_coverage_stalls(tee_eval, tmp_path):
    """The T has no cost-to-go: `collect` picks the states where the policy's coverage stalls (stalls.py),
    in the T's own terms (position, heading, finger), each a start the T's env and `generate` accept."""
    from lerobot_gcs_push.evaluation import GCS_POLICIES
    from lerobot_gcs_push.improve.collect import CollectConfig, rollouts_env_id
    from lerobot_gcs_push.improve.stalls import stall_branch_states
    from lerobot_gcs_push.scene import load_initial_conditions

    assert rollouts_env_id([str(tee_eval)]) == TEE_ENV_ID
    scene = SCENES[TEE_ENV_ID]
    records = [r | {"_source": str(tee_eval)} for r in read_runs(tee_eval / "runs.jsonl")]
    cfg = CollectConfig(rollouts=[str(tee_eval)], max_per_run=3)
    states = stall_branch_states(records, cfg, scene, GCS_POLICIES)
    # Both runs failed (the box's policy on the T, 5 s): each gives up to 3 states, from its own trajectory.
    assert 1 <= len(states) <= 6 and {s["source"]["initial_condition_index"] for s in states} <= {0, 1}
    for s in states:
        rec = next(r for r in records if r["initial_condition_index"] == s["source"]["initial_condition_index"])
        pose = np.load(tee_eval / rec["trajectory"])["slider_pose"][s["source"]["step"]]
        np.testing.assert_allclose([*s["box"], s["heading"]], pose, atol=1e-6)
        assert s["source"]["coverage"] < scene.success_coverage
    path = tmp_path / "states.json"
    path.write_text(json.dumps(states))
    for i, ic in enumerate(load_initial_conditions(str(path), scene)):  # what generate reads, checked as it does
        scene.validate_start(ic, f"branch state {i}")
    box = tmp_path / "box_rollouts"  # a folder from before the env was recorded: the box's
    box.mkdir()
    (box / "runs.jsonl").write_text("")
    assert rollouts_env_id([str(box)]) == ENV_ID
    with pytest.raises(ValueError, match="different envs"):
        rollouts_env_id([str(box), str(tee_eval)])


def test_initial_conditions_from_a_file_keep_their_headings_and_are_checked_at_them(tmp_path):
    """A heading in the file is the one the run starts at; a finger clear of the box at heading 0 but inside
    it at the file's heading is refused before any run, its entry named."""
    from lerobot_gcs_push.evaluation import evaluate

    ics = tmp_path / "ics.json"
    ics.write_text(json.dumps([{"box": [2.0, -1.0], "finger": [-1.0, 1.5], "heading": 2.5}]))
    out = tmp_path / "eval"
    common = dict(env_id=SE2_ENV_ID, policies=[str(POLICY)], runs=1, timeout_s=1.0, videos=0)
    evaluate(EvaluateConfig(**common, initial_conditions=str(ics), output_dir=str(out)))
    (rec,) = read_runs(out / "runs.jsonl")
    assert rec["heading_initial"] == 2.5
    np.testing.assert_allclose(np.load(out / rec["trajectory"])["slider_pose"][0], [2.0, -1.0, 2.5], atol=1e-9)
    # Turned 45 degrees, the box's corner reaches 0.71 m along x: the finger (radius 0.3 m) centred 0.9 m
    # out along x clears the face at heading 0 by 0.1 m and overlaps the corner at 45 degrees.
    finger = [2.0 + 0.9, -1.0]
    assert SCENES[SE2_ENV_ID].finger_box_gap([2.0, -1.0], finger, 0.0) == pytest.approx(0.1)
    ics.write_text(json.dumps([{"box": [2.0, -1.0], "finger": finger, "heading": math.pi / 4}]))
    with pytest.raises(ValueError, match="initial condition 0.*overlaps"):
        evaluate(EvaluateConfig(**common, initial_conditions=str(ics), output_dir=str(tmp_path / "refused")))
    assert not (tmp_path / "refused" / "runs.jsonl").exists()


def test_gcs_push_plan_plans_a_rotating_box_through_contact(tmp_path):
    """`gcs-push plan --env_id=GcsPushBoxSE2-v0 --initial_conditions=FILE --jsonl=true`: one object per entry,
    each ending at the goal pose from the entry's own pose and finger, its cost above its certified bound."""
    ics = [{"box": [2.0, -1.5], "finger": [-2.0, 1.0], "heading": 0.5}, {"box": [-3.0, 2.0], "finger": [3.0, 3.0]}]
    path = tmp_path / "ics.json"
    path.write_text(json.dumps(ics))
    args = ["plan", f"--env_id={SE2_ENV_ID}", f"--initial_conditions={path}", "--jsonl=true"]
    out = subprocess.run(gcs_push(*args), capture_output=True, text=True, timeout=600, check=True)
    plans = [json.loads(line) for line in out.stdout.splitlines()]
    assert len(plans) == len(ics)
    goal = np.array(SCENES[SE2_ENV_ID].goal_pose)
    for ic, plan in zip(ics, plans, strict=True):
        assert plan["certified"] and np.isfinite(plan["lower_bound"]) and plan["gap"] >= -1e-9
        assert plan["lower_bound"] <= plan["cost"] + 1e-9 and plan["solve_time_s"] > 0
        np.testing.assert_allclose(plan["slider_poses"][0], [*ic["box"], ic.get("heading", 0.0)], atol=1e-6)
        np.testing.assert_allclose(plan["finger_path"][0], ic["finger"], atol=1e-6)
        final = np.array(plan["slider_final"])
        assert np.linalg.norm(final[:2] - goal[:2]) < 0.05
        # The square looks the same every quarter turn: the heading error is taken modulo pi/2.
        assert abs(wrap_angle(4 * (final[2] - goal[2]))) / 4 < 0.05
