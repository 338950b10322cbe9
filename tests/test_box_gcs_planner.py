"""The GCS planner against independent evidence: brute force over mode sequences, hand-computed plans,
and geometric validity of every plan."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from conftest import gcs_push

from lerobot_gcs_push.box_gcs import GcsPlanner, brute_force, build_graph
from lerobot_gcs_push.box_gcs.restriction import RestrictionCache
from lerobot_gcs_push.planning import APPROACH, FREE, PUSH, RETREAT, PlanningError, Speeds
from lerobot_gcs_push.scene import Scene, sample_initial_conditions

SCENE = Scene()


@pytest.fixture(scope="module")
def planner():
    p = GcsPlanner(SCENE)
    p.program("micp")
    return p


@pytest.fixture(scope="module")
def ics():
    return sample_initial_conditions(SCENE, 20, seed=2024)


@pytest.fixture(scope="module")
def solved(planner, ics):
    out = []
    for ic in ics:
        out.append(
            (ic, planner.plan(ic.box, ic.finger, method="relaxation"), planner.plan(ic.box, ic.finger, method="micp"))
        )
    return out


def test_micp_equals_brute_force_and_rounding_is_within_1pct(planner, solved):
    cache = RestrictionCache(planner.graph)
    for ic, rel, micp in solved:
        bf = brute_force(planner.graph, np.r_[ic.box, ic.finger], SCENE.goal_array, cache)
        assert micp.cost == pytest.approx(bf.cost, rel=1e-5, abs=1e-5), ic
        assert rel.cost <= micp.cost * 1.01 + 1e-6, ic
        assert rel.cost >= micp.cost - 1e-5  # rounding returns a feasible plan: never below the optimum
        assert np.isfinite(rel.lower_bound) and rel.lower_bound <= micp.cost + 1e-5


@pytest.mark.slow
def test_branch_graph_loses_nothing_against_general_layers():
    """The default graph allows one push per axis. The general graph (any face on each of two pushes,
    box positions free) must not find anything cheaper: brute force over all its mode sequences."""
    general = build_graph(SCENE, "layers", 2)
    branches = build_graph(SCENE, "branches")
    cg, cb = RestrictionCache(general), RestrictionCache(branches)
    for ic in sample_initial_conditions(SCENE, 3, seed=5):
        src = np.r_[ic.box, ic.finger]
        best_general = brute_force(general, src, SCENE.goal_array, cg).cost
        best_branch = brute_force(branches, src, SCENE.goal_array, cb).cost
        assert best_branch == pytest.approx(best_general, rel=1e-5, abs=1e-5)


def test_hand_computed_single_push():
    """Box at (-2, 0), finger right behind its left approach point: one push of 2 m along +x.
    Path: 0.5 m of free motion to the approach point, 0.2 in, 2.0 pushing, 0.2 out."""
    p = GcsPlanner(SCENE)
    da = SCENE.approach_distance
    plan = p.plan([-2.0, 0.0], [-2.0 - da - 0.5, 0.0])
    assert plan.cost == pytest.approx(0.5 + 0.2 + 2.0 + 0.2, abs=1e-5)
    assert plan.modes == ["free:L", "push:L"]
    np.testing.assert_allclose(plan.slider_final, [0.0, 0.0], atol=1e-6)


def test_hand_computed_two_pushes_around_a_corner():
    """Box at (-2, -3), finger at its left approach point. Push +x by 2 m, retreat, go round the
    bottom-left... no: round to the bottom face: from (-da, 0) relative to the box, via the corner
    (-da, -da), to (0, -da): 2 * da. Then push +y by 3 m. Total 0.2+2+0.2 + 2*da + 0.2+3+0.2."""
    p = GcsPlanner(SCENE)
    da = SCENE.approach_distance
    plan = p.plan([-2.0, -3.0], [-2.0 - da, -3.0])
    assert plan.cost == pytest.approx(0.4 + 2.0 + 2 * da + 0.4 + 3.0, abs=1e-5)
    assert plan.modes[0] in ("free:L", "push:L")
    assert plan.num_pushes == 2


def test_plans_are_geometrically_valid(solved):
    for ic, rel, _ in solved:
        fw, bw, kinds = rel.finger_path, rel.slider_poses, rel.segment_kinds
        np.testing.assert_allclose(fw[0], ic.finger, atol=1e-9)
        np.testing.assert_allclose(bw[-1], SCENE.goal, atol=1e-5)
        for k, kind in enumerate(kinds):
            a, b = fw[k], fw[k + 1]
            box_a, box_b = bw[k], bw[k + 1]
            # Dense samples along the segment never penetrate the box (the box moves only in pushes).
            for s in np.linspace(0, 1, 41):
                f = a + s * (b - a)
                box = box_a + s * (box_b - box_a)
                assert SCENE.finger_box_gap(box, f) >= -1e-6, (ic, kind)
            if kind == PUSH:
                # Contact only at a face centre, moving along the face normal with the box.
                r = a - box_a
                assert np.isclose(np.abs(r).max(), SCENE.contact_distance, atol=1e-6)
                assert np.isclose(np.abs(r).min(), 0.0, atol=1e-6)
                np.testing.assert_allclose(b - a, box_b - box_a, atol=1e-6)
                assert np.dot(b - a, -r) >= -1e-9  # pushes away from the finger
            else:
                np.testing.assert_allclose(box_a, box_b, atol=1e-9)
            if kind == FREE and k > 0:
                # Off the first segment, free motion keeps the buffer: no grazing of a face.
                gap_b = SCENE.finger_box_gap(box_b, b)
                assert gap_b >= SCENE.transition_buffer - 1e-6
        assert kinds.count(APPROACH) == kinds.count(PUSH) == kinds.count(RETREAT) <= 2


def test_box_at_goal_gives_a_plan_without_push():
    plan = GcsPlanner(SCENE).plan(SCENE.goal, [2.0, 2.0])
    assert plan.cost == 0 and plan.num_pushes == 0 and plan.modes == []
    assert len(plan.commands(10)) == 1


def test_finger_in_the_corner_nook_escapes_first():
    """Diagonally off a box corner the finger is clear of the box but in no free region."""
    box = np.array([2.0, 1.0])
    finger = box + np.array([0.75, 0.75])  # 0.05 m clear of the corner
    assert SCENE.finger_box_gap(box, finger) > 0
    plan = GcsPlanner(SCENE).plan(box, finger)
    assert plan.modes[0] == "escape"
    np.testing.assert_allclose(plan.slider_final, SCENE.goal, atol=1e-5)


@pytest.mark.parametrize(
    "box, finger, needle",
    [
        ([0.0, 0.0], [0.5, 0.0], "overlaps"),
        ([9.0, 0.0], [0.0, 3.0], "outside the box workspace"),
        ([0.0, 0.0], [0.0, 7.0], "outside the finger workspace"),
        ([np.nan, 0.0], [0.0, 3.0], "finite"),
    ],
)
def test_bad_input_is_named(box, finger, needle):
    with pytest.raises(ValueError, match=needle):
        GcsPlanner(SCENE, compile_now=False).plan(box, finger)


def test_two_cycle_constraints_are_valid_and_do_not_cut_the_optimum(planner, ics):
    """The optional two-cycle cuts must keep the MICP optimum and give a bound between the plain
    relaxation's and the optimum."""
    from lerobot_gcs_push.box_gcs.gcs import GcsProgram

    plain, cuts = GcsProgram(planner.graph), GcsProgram(planner.graph, two_cycles=True)
    exact = GcsProgram(planner.graph, integer=True, two_cycles=True)
    for ic in ics[:4]:
        src = np.r_[ic.box, ic.finger]
        allowed = planner.graph.edge_allowed(SCENE.goal_array - np.array(ic.box), 0.0)
        vals = []
        for prog in (plain, cuts, exact):
            prog.set_query(src, SCENE.goal_array, allowed)
            vals.append(prog.solve().value)
        opt = planner.plan(ic.box, ic.finger, method="micp").cost
        assert vals[0] - 1e-5 <= vals[1] <= opt + 1e-5
        assert vals[2] == pytest.approx(opt, rel=1e-4)


def test_solver_failure_names_solver_and_status(planner):
    prog = planner.program("relaxation")
    src = np.r_[[0.0, 2.0], [0.0, 4.0]]
    prog.set_query(src, np.zeros(2), np.zeros(len(planner.graph.edges)))  # every push edge disabled
    with pytest.raises(PlanningError, match=r"CLARABEL.*infeasible"):
        prog.solve()


def test_time_parameterisation_respects_speeds(solved):
    speeds = Speeds()
    _, plan, _ = solved[0]
    sched = plan.schedule(10, speeds)
    steps = np.linalg.norm(np.diff(np.vstack([plan.finger_path[:1], sched.commands]), axis=0), axis=1)
    assert steps.max() <= speeds.free / 10 + 1e-9
    np.testing.assert_allclose(sched.commands[-1], plan.finger_path[-1])
    assert plan.duration(speeds) == pytest.approx(len(sched) / 10, abs=0.1)


def test_cli_plan_json_lines(tmp_path):
    ics = [{"box": [1.0, 2.0], "finger": [-3.0, 0.0], "note": "ignored"}, {"box": [-2.0, -1.0], "finger": [3.0, 3.0]}]
    f = tmp_path / "ics.json"
    f.write_text(json.dumps(ics))
    out = subprocess.run(
        gcs_push("plan", f"--initial_conditions={f}", "--jsonl=true"),
        capture_output=True,
        text=True,
        check=True,
    ).stdout.splitlines()
    objs = [json.loads(line) for line in out if line.startswith("{")]
    assert len(objs) == 2
    for o in objs:
        for key in ("cost", "lower_bound", "solve_time_s", "method", "modes", "finger_path", "slider_final"):
            assert key in o
        np.testing.assert_allclose(o["slider_final"], [0, 0], atol=1e-5)
        assert set(o["segment_kinds"]) <= {"free", "approach", "push", "retreat"}
    assert objs[0]["finger_path"][0] == [-3.0, 0.0]


def test_cli_plan_rejects_overlap():
    res = subprocess.run(
        gcs_push("plan", "--box=[0,0]", "--finger=[0.4,0]"),
        capture_output=True,
        text=True,
        check=False,
    )
    assert res.returncode != 0 and "overlaps" in res.stderr
