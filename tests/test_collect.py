"""Active data: the hard sampler, the regret bookkeeping, branch states and their expert labels."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from lerobot_gcs_push.improve.collect import CollectConfig, branch_states, collect
from lerobot_gcs_push.planning.factory import chunk_regret, plannable
from lerobot_gcs_push.scene import FAR_FINGER_M, HARD_KINDS, HARD_V2_KINDS, Scene, sample_initial_conditions

SCENE = Scene()


def test_hard_sampler_is_seeded_prefix_stable_and_draws_each_family_in_turn():
    ics = sample_initial_conditions(SCENE, 40, seed=3000, sampler="hard")
    assert sample_initial_conditions(SCENE, 9, seed=3000, sampler="hard") == ics[:9]
    assert sample_initial_conditions(SCENE, 9, seed=3001, sampler="hard") != ics[:9]
    assert [ic.kind for ic in ics[:8]] == list(HARD_KINDS) * 2
    for ic in ics:
        SCENE.validate_state(ic.box, ic.finger)  # in the workspace, no overlap


def test_hard_sampler_families_have_their_geometry():
    g = SCENE.goal_array
    for ic in sample_initial_conditions(SCENE, 80, seed=7, sampler="hard"):
        box, finger = np.array(ic.box), np.array(ic.finger)
        if ic.kind == "goal_side":
            axis = int(np.argmax(np.abs(box - g)))
            # The finger sits between box and goal along the axis, in front of the goal-facing face.
            assert abs(finger[axis] - g[axis]) < abs(box[axis] - g[axis])
            assert abs(finger[1 - axis] - box[1 - axis]) < SCENE.box_half
        elif ic.kind == "corner":
            assert np.all(np.abs(box) >= SCENE.box_limit - 1.5 - 1e-9)
            assert SCENE.finger_box_gap(box, finger) < 0.8
        elif ic.kind == "tiny_push":
            assert 0.15 - 1e-9 <= SCENE.box_goal_distance(box) <= 0.9 + 1e-9
            assert np.max(np.abs(finger)) >= 3.5
        elif ic.kind == "edge":
            assert np.max(np.abs(box)) >= SCENE.box_limit - 1.0 - 1e-9


def test_hard_sampler_still_draws_the_recorded_hard_test_set():
    # hard_v2 came beside `hard` so that the seeded sets on record stay what they were.
    rows = json.loads(open("results/active_round11_hard.json").read())["initial_conditions"]["rows"]
    ics = sample_initial_conditions(SCENE, len(rows), seed=3000, sampler="hard")
    assert len(rows) == 20
    for ic, (bx, by, fx, fy, kind, *_) in zip(ics, rows):  # the record keeps millimetres
        np.testing.assert_allclose([*ic.box, *ic.finger], [bx, by, fx, fy], atol=5.1e-4)
        assert ic.kind == kind


def test_hard_v2_adds_the_far_finger_families():
    ics = sample_initial_conditions(SCENE, 60, seed=11, sampler="hard_v2")
    assert sample_initial_conditions(SCENE, 7, seed=11, sampler="hard_v2") == ics[:7]
    assert [ic.kind for ic in ics[:12]] == list(HARD_V2_KINDS) * 2
    lim, fl = SCENE.box_limit, SCENE.finger_init_half_width
    for ic in ics:
        SCENE.validate_state(ic.box, ic.finger)
        box, finger = np.array(ic.box), np.array(ic.finger)
        if ic.kind == "opposite_corners":  # each coordinate on the other side, both near their corners
            assert np.all(np.sign(box) == -np.sign(finger))
            assert np.all(np.abs(box) >= lim - 1.5 - 1e-9) and np.all(np.abs(finger) >= fl - 1.5 - 1e-9)
            assert np.linalg.norm(box - finger) >= np.hypot(lim + fl - 3.0, lim + fl - 3.0) - 1e-9
        elif ic.kind == "far_finger":
            assert np.linalg.norm(box - finger) >= FAR_FINGER_M - 1e-9
    with pytest.raises(ValueError, match="hard_v2"):
        sample_initial_conditions(dataclasses.replace(SCENE, rotates=True), 1, sampler="hard_v2")


def test_plannable_clears_the_box_by_the_clearance_and_leaves_free_states_alone():
    rng = np.random.default_rng(0)
    for _ in range(5000):
        box = rng.uniform(-4, 4, 2)
        finger = box + rng.uniform(-1.0, 1.0, 2)
        b, f = plannable(SCENE, box, finger, clearance=0.02)
        assert SCENE.finger_box_gap(b, f) >= 0.02 - 1e-9
        if SCENE.finger_box_gap(box, finger) >= 0.02:
            np.testing.assert_array_equal(f, finger)
        else:  # moved no farther than needed: the gap is exactly the clearance
            assert SCENE.finger_box_gap(b, f) == pytest.approx(0.02, abs=1e-9)


def test_chunk_regret_bookkeeping_on_a_hand_computed_case():
    # V = straight-line distance of the finger to a target: a straight walk has zero regret, a detour
    # of known length has that regret, in the chunk where it happens.
    target = np.array([4.0, 0.0])

    def value(box, finger):
        return float(np.linalg.norm(target - finger))

    straight = np.c_[np.linspace(0, 4, 17), np.zeros(17)]
    chunks = chunk_regret(value, np.zeros((17, 2)), straight, every=8)
    assert [c["step"] for c in chunks] == [0, 8]
    assert [c["regret"] for c in chunks] == pytest.approx([0.0, 0.0], abs=1e-12)
    detour = np.array([[0, 0], [0, 1], [0, 0], [4, 0]], float)  # 2 m out and back, then 4 m
    chunks = chunk_regret(value, np.zeros((4, 2)), detour, every=2)
    assert [c["regret"] for c in chunks] == pytest.approx([2.0, 0.0])


def _record(success, regrets, box=(3.0, 0.0), finger=(2.0, 0.0), policy="policies/x", ic=0):
    chunks = [[8 * k, r, box[0] + 0.01 * k, box[1], finger[0], finger[1] + 0.01 * k] for k, r in enumerate(regrets)]
    return {
        "policy": policy,
        "label": "dp:x",
        "disturbances": False,
        "initial_condition_index": ic,
        "run": 0,
        "success": success,
        "regret_chunks": chunks,
    }


def test_branch_states_pick_mistakes_cap_them_over_time_and_skip_what_cannot_start(tmp_path):
    (tmp_path / "runs.jsonl").write_text("")
    cfg = CollectConfig(rollouts=[str(tmp_path)], keep_fraction=0.0, max_per_run=3)
    failed = _record(False, [0.1, 0.3, 0.0, 0.4, 0.6, 0.26, 0.9])  # 5 above 0.25
    ok = _record(True, [0.1, 0.3, 0.7, 0.0], ic=1)  # 1 above 0.5
    gcs = _record(False, [5.0, 5.0], policy="gcs-open-loop", ic=2)  # experts are never branched from
    at_goal = _record(False, [1.0], box=(0.01, 0.0), finger=(2.0, 0.0), ic=3)
    states = branch_states([failed, ok, gcs, at_goal], cfg)
    steps = [(s["source"]["initial_condition_index"], s["source"]["step"]) for s in states]
    assert steps == [(0, 8), (0, 32), (0, 48), (1, 16)]  # first, middle, last of the 5; the one mistake
    for s in states:
        assert SCENE.finger_box_gap(s["box"], s["finger"]) >= cfg.clearance - 1e-6
    everything = branch_states([failed], CollectConfig(rollouts=[str(tmp_path)], keep_fraction=1.0, max_per_run=99))
    assert len(everything) == 7
    # A failed run that pushes the box out of its workspace (x > 4.5) from the fourth chunk on: the cap
    # spreads over the four states the expert can start from, not over all seven.
    pinned = _record(False, [0.4] * 7, box=(3.0, 0.0), finger=(2.0, 0.0))
    for chunk, x in zip(pinned["regret_chunks"], [3.0, 3.4, 3.8, 4.2, 5.0, 5.5, 6.0]):
        chunk[2] = x
    states = branch_states([pinned], cfg)
    assert [s["source"]["step"] for s in states] == [0, 16, 24]


@pytest.mark.slow
def test_collect_records_the_expert_from_the_policy_states(tmp_path):
    """Episodes start at the branch states (the images are rendered there) and reach the goal."""
    runs = [_record(False, [0.1, 0.6, 0.7], box=(2.5, -1.0), finger=(1.0, 1.5))]
    (tmp_path / "runs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in runs))
    cfg = CollectConfig(
        rollouts=[str(tmp_path)], repo_id="local/test_active", root=str(tmp_path / "ds"), keep_fraction=0.0, workers=1
    )
    report, states = collect(cfg)
    assert len(states) == 2 and report.episodes == 2 and report.failures == 0
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ds = LeRobotDataset("local/test_active", root=tmp_path / "ds", video_backend="pyav")
    starts = np.asarray(ds.meta.episodes["dataset_from_index"])
    ends = np.asarray(ds.meta.episodes["dataset_to_index"])
    assert len(starts) == len(ends) == len(states) == 2
    for s, (a, b) in zip(states, zip(starts, ends)):
        first, last = ds[int(a)], ds[int(b) - 1]
        np.testing.assert_allclose(first["observation.environment_state"].numpy(), s["box"], atol=1e-4)
        np.testing.assert_allclose(first["observation.state"].numpy(), s["finger"], atol=1e-4)
        assert np.linalg.norm(last["observation.environment_state"].numpy()) < 0.25  # on its way in
    meta = json.loads((tmp_path / "ds.branch_states.json").read_text())
    assert meta == states
    # A script re-running every step: collecting again with --resume=true finds the work done.
    again, _ = collect(dataclasses.replace(cfg, resume=True))
    assert again.already_finished and (again.episodes, again.frames) == (report.episodes, report.frames)
    # Other settings pick other states: refused on --resume and without it, the kept list untouched.
    with pytest.raises(ValueError, match="other rollouts or settings"):
        collect(dataclasses.replace(cfg, resume=True, keep_fraction=1.0))
    with pytest.raises(FileExistsError, match="already exists"):
        collect(dataclasses.replace(cfg, keep_fraction=1.0))
    assert json.loads((tmp_path / "ds.branch_states.json").read_text()) == states


def test_the_optimal_plan_has_no_regret_along_its_own_path(tmp_path):
    """Regret is zero for the expert, up to tracking lag: executed through the physics, every chunk of
    the open-loop GCS plan keeps path + V(after) - V(before) small, and the runs' sums stay near zero,
    while V at the start is the plan's own optimal cost (two independent routes to the same number)."""
    from lerobot_gcs_push.box_gcs import GcsPlanner
    from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate, read_runs

    out = tmp_path / "eval"
    evaluate(
        EvaluateConfig(
            policies=["gcs-open-loop"],
            sampler="hard",
            seed=3000,
            num_initial_conditions=4,
            runs=1,
            timeout_s=60.0,
            output_dir=str(out),
            videos=0,
        )
    )
    planner = GcsPlanner(SCENE, goal_tolerance=SCENE.success_threshold / np.sqrt(2))
    recs = read_runs(out / "runs.jsonl")
    assert len(recs) == 4 and all(r["policy"] == "gcs-open-loop" for r in recs)  # 4 starts x 1 run, one policy
    for rec in recs:
        assert rec["success"]
        regrets = [c[1] for c in rec["regret_chunks"]]
        assert max(regrets) < 0.5 and min(regrets) > -1.0, regrets
        assert abs(rec["regret"]) < 0.5
        assert rec["first_large_regret_s"] is None
        direct = planner.plan(rec["box_initial"], rec["finger_initial"], method="micp").cost
        assert rec["value_initial"] == pytest.approx(direct, rel=1e-3)
    assert (out / "fig_regret.png").is_file()
    assert "Regret along each policy's own path" in (out / "tables.md").read_text()
