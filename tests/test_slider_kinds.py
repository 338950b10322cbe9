"""The slider kinds (`scene.kinds`): which scene has which, and the one `info` layout every Drake env
reports, read back by each kind as the state its planner and its datasets use."""

import dataclasses

import numpy as np
import pytest

from lerobot_gcs_push.planning.factory import make_planner
from lerobot_gcs_push.registration import ENV_ID, PUSHT_ENV_ID, SCENES, SE2_ENV_ID, TEE_ENV_ID
from lerobot_gcs_push.scene import Scene
from lerobot_gcs_push.scene.kinds import FIXED_BOX, GYM_PUSHT, TURNING_SLIDER


def test_each_registered_scene_has_its_kind():
    kinds = {env_id: scene.kind for env_id, scene in SCENES.items()}
    assert kinds == {ENV_ID: FIXED_BOX, SE2_ENV_ID: TURNING_SLIDER, TEE_ENV_ID: TURNING_SLIDER, PUSHT_ENV_ID: GYM_PUSHT}
    # A scene changed by `dataclasses.replace` (the envs' goals, thresholds, cameras) keeps its kind.
    assert dataclasses.replace(SCENES[TEE_ENV_ID], success_coverage=0.9).kind is TURNING_SLIDER
    assert dataclasses.replace(SCENES[PUSHT_ENV_ID], success_coverage=0.9).kind is GYM_PUSHT


@pytest.mark.parametrize("env_id", [ENV_ID, SE2_ENV_ID])
def test_every_drake_env_reports_the_slider_pose_and_its_kind_reads_the_state_from_it(env_id):
    from lerobot_gcs_push.sim.env import GcsPushEnv

    scene = SCENES[env_id]
    env = GcsPushEnv(scene=scene, obs_type="state", render_size=32, image_size=32)
    heading = {ENV_ID: 0.0, SE2_ENV_ID: 0.7}[env_id]
    obs, info = env.reset(options={"box": [1.0, -0.5], "finger": [-3.0, 2.0], "heading": heading})
    np.testing.assert_allclose(info["slider_pose"], [1.0, -0.5, heading], atol=1e-9)
    state = scene.kind.state(info["slider_pose"])
    assert len(state) == scene.kind.pose_size == len(scene.kind.state_names)
    np.testing.assert_array_equal(obs[2:], state)  # the state observation: the finger, then the slider's state
    np.testing.assert_array_equal(state[:2], info["box"])
    assert scene.kind.pose(scene.kind.slider(info["box"], heading)) == pytest.approx([1.0, -0.5, heading])
    summary = scene.kind.summary(info)
    if scene.kind is FIXED_BOX:  # the box's records keep no more than before the kinds
        assert summary == {} and env.observation_space.shape == (4,)
    else:
        assert set(summary) == {"slider_pose_final", "coverage", "heading_error"}
        assert summary["coverage"] == pytest.approx(scene.coverage(info["slider_pose"]))
        assert env.observation_space.shape == (5,)
    env.close()


def test_the_box_refuses_a_heading_and_what_it_cannot_do():
    box = Scene()
    assert box.kind.refuses_heading(0.3) and not box.kind.refuses_heading(0.0)
    with pytest.raises(ValueError, match="cannot rotate"):
        box.validate_state([1.0, 1.0], [-3.0, -3.0], heading=0.3)
    with pytest.raises(ValueError, match="goal heading"):
        box.with_goal([0.0, 0.0, 0.5])
    turning = SCENES[SE2_ENV_ID]
    assert turning.with_goal([0.5, 0.0, 0.5]).goal_pose.tolist() == [0.5, 0.0, 0.5]
    with pytest.raises(ValueError, match="relaxation only"):
        make_planner(turning, "micp")
    assert (box.kind.cost_to_go, turning.kind.cost_to_go) == (True, False)
    assert (box.kind.default_expert, turning.kind.default_expert) == ("open-loop", "closed-loop")
