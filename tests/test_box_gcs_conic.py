"""The planner's conic path (conic.py, conic_gcs.py, micp.py) against the cvxpy programs it is taken
from, against today's reference plan costs, and without compiling anything per query."""

from __future__ import annotations

import json
from pathlib import Path

import cvxpy as cp
import numpy as np
import pytest

from lerobot_gcs_push.box_gcs import GcsPlanner
from lerobot_gcs_push.box_gcs.restriction import Restriction
from lerobot_gcs_push.conic import Infeasible, ParametricConic
from lerobot_gcs_push.conic.certificate import of_solution
from lerobot_gcs_push.conic.solve import solve
from lerobot_gcs_push.scene import Scene, sample_initial_conditions

SCENE = Scene()
REFERENCE = json.loads((Path(__file__).parent / "test_box_gcs_reference_costs.json").read_text())


@pytest.fixture(scope="module")
def planner():
    return GcsPlanner(SCENE)


def _queries(planner, n, seed, sampler="uniform"):
    return [planner.query(ic.box, ic.finger) for ic in sample_initial_conditions(SCENE, n, seed=seed, sampler=sampler)]


def _rel(a, b):
    return abs(a - b) / max(1.0, abs(b))


@pytest.mark.parametrize("sampler", ["uniform", "hard"])
def test_direct_relaxation_equals_cvxpy_solve(planner, sampler):
    """Clarabel on the conic data, forbidden edges dropped, against cvxpy solving the program with their
    flows bounded by 0: the same optimum."""
    prog = planner.program("relaxation")
    for q in _queries(planner, 10, seed=7, sampler=sampler):
        prog.set_query(q.src, q.goal, q.allowed)
        ref = prog.solve()
        mine = planner.conic.relax(q.src, q.goal, q.allowed).flows
        assert _rel(mine.value, ref.value) < 1e-6, (q, mine.value, ref.value)


def test_path_restriction_equals_the_direct_restriction(planner):
    """A path's restriction taken from the relaxation's conic data (y fixed, other edges dropped)
    against restriction.py's own program of that path: same cost, same points, same infeasibility."""
    rng = np.random.default_rng(3)
    paths = planner.graph.simple_paths()
    infeasible = 0
    for q in _queries(planner, 6, seed=8):
        conic = planner.conic.at(q.src, q.goal, q.allowed)
        for k in rng.choice(len(paths), 8, replace=False):
            path = tuple(paths[k])
            ref = Restriction(planner.graph, path).solve(q.src, q.goal)
            mine = planner.conic.restrict(conic, path, q.src, q.goal)
            if not np.isfinite(ref.cost):
                infeasible += 1
                assert not np.isfinite(mine.cost), path
                continue
            assert _rel(mine.cost, ref.cost) < 1e-6, (path, mine.cost, ref.cost)
            assert mine.vertices == ref.vertices
            for v, x in ref.points.items():
                np.testing.assert_allclose(mine.points[v], x, atol=1e-5)
    assert infeasible > 0  # the comparison covered paths that the query rules out


def test_fixing_variables_matches_cvxpy_with_equalities():
    """Conic.fix on a small SOCP: the same optimum as cvxpy with the fixed values as constraints, and
    Infeasible when a fixed value leaves a constant row violated."""
    x, p = cp.Variable(3), cp.Parameter(2)
    prob = cp.Problem(cp.Minimize(cp.norm(x[:2] - p) + x[2]), [x >= -1, x[2] >= x[0], x[1] <= 2])
    data = ParametricConic(prob, [p], {"x": x})
    theta = np.array([0.5, 3.0])
    values = np.full(data.n, np.nan)
    values[data.columns["x"].start] = 0.25
    sol = solve(data.at(theta).fix(values))
    p.value = theta
    ref = cp.Problem(prob.objective, prob.constraints + [x[0] == 0.25]).solve(solver=cp.CLARABEL)
    assert sol.value == pytest.approx(ref, rel=1e-7)
    assert sol.x[data.columns["x"]][0] == 0.25
    values[data.columns["x"].start + 1] = 2.5  # x[1] <= 2 violated
    values[data.columns["x"].start + 2] = 0.0
    with pytest.raises(Infeasible):
        data.at(theta).fix(values)


def test_micp_equals_cvxpy_scip(planner):
    """SCIP on the MICP's conic data against cvxpy's SCIP interface on the same program."""
    prog = planner.program("micp")
    for q in _queries(planner, 3, seed=9):
        prog.set_query(q.src, q.goal, q.allowed)
        ref = prog.solve()
        mine = planner.micp.solve(q.src, q.goal, q.allowed)
        assert _rel(mine.value, ref.value) < 1e-4, (mine.value, ref.value)  # SCIP's tolerances
        np.testing.assert_array_equal(mine.flows > 0.5, ref.flows > 0.5)


@pytest.mark.parametrize("name", sorted(REFERENCE["sets"]))
def test_plan_costs_unchanged_from_the_reference(planner, name):
    """Plan costs recorded from the planner before its conic path existed (cvxpy programs, commit
    745e4fa): relaxation + rounding never costs more, and where it costs less (the flow decomposition's
    candidates find a path the walks missed) it is the MICP's global optimum; the MICP is unchanged."""
    data = REFERENCE["sets"][name]
    goal = REFERENCE["goal"] if name == "goal" else None
    for (box, finger), cost in zip(data["ics"], data["relaxation"]):
        now = planner.plan(box, finger, goal=goal).cost
        assert now <= cost * (1 + 1e-6), (box, finger, now, cost)
        if now < cost * (1 - 1e-6):
            exact = planner.plan(box, finger, goal=goal, method="micp").cost
            assert _rel(now, exact) < 1e-6, (box, finger, now, exact)
    for (box, finger), cost in list(zip(data["ics"], data.get("micp", [])))[:6]:
        assert _rel(planner.plan(box, finger, goal=goal, method="micp").cost, cost) < 1e-6, (box, finger)


def test_a_plan_does_not_depend_on_earlier_plans():
    """The same query on a fresh planner and on one that has planned others first: the same plan, to
    the bit (rounding is seeded by the query, and no solver state carries over)."""
    ics = sample_initial_conditions(SCENE, 16, seed=12, sampler="hard")
    used = GcsPlanner(SCENE)
    for ic in ics[1:]:
        used.plan(ic.box, ic.finger)
    a, b = GcsPlanner(SCENE).plan(ics[0].box, ics[0].finger), used.plan(ics[0].box, ics[0].finger)
    assert a.cost == b.cost and a.modes == b.modes
    np.testing.assert_array_equal(a.finger_path, b.finger_path)


def test_a_fresh_planner_plans_without_compiling(compilations):
    """Everything cvxpy compiles happens in the constructor, and a second planner reads it from the
    cache: no compilation at all, the same plans."""
    costs = {}
    for method in ("relaxation", "micp"):
        p = GcsPlanner(SCENE, method=method)
        built = len(compilations)
        assert built > 0  # the hook sees compilation
        ics = sample_initial_conditions(SCENE, 3 if method == "micp" else 12, seed=21, sampler="hard")
        costs[method] = [p.plan(ic.box, ic.finger).cost for ic in ics]
        assert len(compilations) == built, method
    before = len(compilations)
    for method in ("relaxation", "micp"):
        p = GcsPlanner(SCENE, method=method)
        ics = sample_initial_conditions(SCENE, len(costs[method]), seed=21, sampler="hard")
        assert [p.plan(ic.box, ic.finger).cost for ic in ics] == costs[method]
    assert len(compilations) == before


def test_the_cache_tells_graphs_apart(compilations, tmp_path):
    """Another scene (a longer transition buffer) is another graph: its own conic data, other plans."""
    GcsPlanner(SCENE)
    other = GcsPlanner(Scene(transition_buffer=0.3))
    assert len(list(tmp_path.glob("gcs-relaxation-*.npz"))) == 2
    box, finger = (2.0, -1.0), (-3.0, 0.0)
    assert other.plan(box, finger).cost > GcsPlanner(SCENE).plan(box, finger).cost + 0.1


def _compile_slowly(root: str, builds: str, out) -> None:
    """A process's `cached` call whose build takes a second and leaves a line in `builds`."""
    import os
    import time

    from lerobot_gcs_push.conic import CACHE_ENV, cached

    os.environ[CACHE_ENV] = root

    def build():
        with open(builds, "a") as f:
            f.write(f"{os.getpid()}\n")
        time.sleep(1.0)
        x, p = cp.Variable(), cp.Parameter()
        return ParametricConic(cp.Problem(cp.Minimize(x), [x >= p]), [p], {"x": x})

    out.put(cached("lock-test", b"one program", [], build).at(np.array([2.0])).b.tolist())


def test_processes_that_need_the_same_program_compile_it_once(tmp_path):
    """Two processes started together on an empty cache (two `generate` workers on a fresh machine, each
    of whose T compiles peaks near 12 GB): one builds, the other waits and reads its file."""
    import multiprocessing

    ctx = multiprocessing.get_context("fork")
    out, builds = ctx.Queue(), tmp_path / "builds.txt"
    procs = [ctx.Process(target=_compile_slowly, args=(str(tmp_path), str(builds), out)) for _ in range(2)]
    for proc in procs:
        proc.start()
    results = [out.get(timeout=60) for _ in procs]
    for proc in procs:
        proc.join(timeout=60)
        assert proc.exitcode == 0
    assert len(builds.read_text().split()) == 1
    assert results[0] == results[1]
    assert len(list(tmp_path.glob("lock-test-*.npz"))) == 1


def test_semidefinite_program_and_its_unpacked_values_match_cvxpy(tmp_path):
    """A small SDP with a symmetric matrix variable, a constant in the objective and parameters in A, b
    and c: the conic data taken once (and again from its file), evaluated at a new theta and solved by
    Clarabel directly, gives cvxpy's optimum as its primal and its certified bound, its symmetric matrix
    entry by entry, and with one variable fixed, cvxpy's optimum with that value as a constraint."""
    X, y = cp.Variable((3, 3), symmetric=True), cp.Variable(2)
    C, a, w = cp.Parameter((3, 3)), cp.Parameter(2), cp.Parameter(nonneg=True)
    objective = cp.sum(cp.multiply(C, X)) + w * (y[0] - 2 * y[1]) + 3.0  # y's optimum: (-1, 2), told apart
    cons = [X >> 0, cp.trace(X) == 1 + a[0], X[0, 1] >= a[1] * y[0], y >= -1, y <= 2]
    prob = cp.Problem(cp.Minimize(objective), cons)
    params = [C, a, w]
    built = ParametricConic(prob, params, {"y": y}, unpack=[X, y])
    built.save(tmp_path / "sdp.npz")
    loaded = ParametricConic.load(tmp_path / "sdp.npz")
    rng = np.random.default_rng(3)
    for _ in range(3):
        M = rng.normal(size=(3, 3))
        C.value, a.value, w.value = M + M.T, rng.uniform(0.1, 1, 2), rng.uniform(0.1, 1)
        ref = prob.solve(solver=cp.CLARABEL)
        fixed_ref = cp.Problem(prob.objective, cons + [y[1] == 0.5]).solve(solver=cp.CLARABEL)
        theta = np.concatenate([np.ravel(p.value, order="F") for p in params])
        for data in (built, loaded):
            sol = solve(data.at(theta), tol=1e-9)
            assert sol.value == pytest.approx(ref, rel=1e-6)
            conic = data.at(theta)
            bound = of_solution(conic, sol).bound  # the dual point checked, not Clarabel's dual objective
            assert bound == pytest.approx(ref, rel=1e-6) and bound <= sol.value + 1e-9
            Xv, yv = data.values(sol.x)
            np.testing.assert_allclose(Xv, X.value, atol=1e-3)  # two solvers, two tolerances
            np.testing.assert_array_equal(Xv, Xv.T)
            np.testing.assert_allclose(yv, [-1.0, 2.0], atol=1e-6)
            values = np.full(data.n, np.nan)
            values[data.columns["y"].start + 1] = 0.5
            assert solve(data.at(theta).fix(values), tol=1e-9).value == pytest.approx(fixed_ref, rel=1e-6)


def test_conic_data_refuses_programs_it_would_get_wrong():
    """A program that is not DPP would have its parameters' values baked in; a symmetric Parameter is
    replaced inside cvxpy by one the caller cannot set: both are refused, with the reason."""
    x, p = cp.Variable(2), cp.Parameter(2)
    p.value = np.ones(2)
    with pytest.raises(ValueError, match="not DPP"):
        ParametricConic(cp.Problem(cp.Minimize(cp.sum(x)), [x >= p * p]), [p], {})
    S, P = cp.Variable((2, 2), symmetric=True), cp.Parameter((2, 2), symmetric=True)
    with pytest.raises(ValueError, match="reformulated"):
        ParametricConic(cp.Problem(cp.Minimize(cp.trace(S)), [S >> P]), [P], {})
