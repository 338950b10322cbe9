"""The contact graph and its free-space pieces as data (no solver)."""

from __future__ import annotations

import numpy as np

from lerobot_gcs_push.contact.graph import START, build_graph
from lerobot_gcs_push.contact.model import PushModel
from lerobot_gcs_push.contact.non_collision import free_regions, routes
from lerobot_gcs_push.scene import Scene

SCENE = Scene(rotates=True)
MODEL = PushModel.from_scene(SCENE)


def test_free_pieces_clear_the_slider_and_overlap_at_corners():
    regions = free_regions(MODEL)
    rng = np.random.default_rng(0)
    pts = rng.uniform(-3, 3, size=(4000, 2))
    for reg in regions:
        inside = [p for p in pts if reg.contains(p)]
        assert len(inside) > 100
        for p in inside:
            assert SCENE.shape.signed_distance((0, 0, 0), p) >= SCENE.finger_radius - 1e-9
    for i in range(4):
        j = (i + 1) % 4
        both = [p for p in pts if regions[i].contains(p) and regions[j].contains(p)]
        assert both, (i, j)
        assert not any(regions[i].contains(p) and regions[(i + 2) % 4].contains(p) for p in pts)


def test_routes_go_round_the_near_way():
    assert routes(4, 1, 1) == [(1,)]
    assert routes(4, 0, 1) == [(0, 1)]
    assert routes(4, 0, 3) == [(0, 3)]
    assert sorted(routes(4, 0, 2)) == [(0, 1, 2), (0, 3, 2)]


def test_layered_graph_is_acyclic_with_single_neighbours():
    g = build_graph(MODEL, layers=3)
    assert len(g.contacts) == 12
    per_pair = 4 * (1 + 2 + 2)  # self, two adjacent faces, the opposite face two ways
    assert len(g.frees) == 3 * per_pair
    assert len(g.starts()) == per_pair
    for f, v in enumerate(g.frees):
        succ = g.contacts[g.successor(f)]
        assert succ.layer == v.layer + 1 and succ.face == v.target
        pred = g.predecessor(f)
        assert (pred is None) == (v.layer == START)
    assert all(g.into(c) for c in range(4))  # layer 0 is entered from the start
    assert not g.out_of(g.contact_index(2, 0))  # the last layer only ends the plan


def test_contact_location_pieces_split_every_face():
    g = build_graph(MODEL, layers=2, pieces=2)
    assert len(g.contacts) == 2 * 4 * 2
    for c, v in enumerate(g.contacts):
        assert g.contact_index(v.layer, v.face, v.piece) == c
        for f in g.into(c):
            assert g.successor(f) == c
        for f in g.out_of(c):
            assert g.predecessor(f) == c
    # From the start every (face, piece) is reachable; between layers every piece pair is joined.
    assert len(g.starts()) == 4 * 5 * 2
    assert len(g.frees) == 4 * 5 * 2 + 8 * 5 * 2


def test_ranked_paths_enumerate_every_path_from_the_allowed_start():
    from types import SimpleNamespace

    from lerobot_gcs_push.contact.rounding import ranked_paths

    g = build_graph(MODEL, layers=2)
    flows = SimpleNamespace(
        free_flow=np.zeros(len(g.frees)), contact_flow=np.zeros(len(g.contacts)), target_flow=np.zeros(len(g.contacts))
    )
    hot = next(f for f in g.starts() if g.frees[f].source == 1 and g.frees[f].target == 2)
    flows.free_flow[hot] = 1.0
    paths = ranked_paths(g, flows, allow=np.array([0.0, 1.0, 0.0, 0.0]))
    # From one piece: 5 first free modes, each ending there or going on through one of 5 more.
    assert len(paths) == 5 * (1 + 5) == len(set(paths))
    assert all(g.frees[p.frees[0]].source == 1 for p in paths)
    assert paths[0].frees[0] == hot  # the flow ranks first


def test_tee_pieces_clear_the_tee_and_join_consecutive_faces():
    scene = Scene(slider="tee", rotates=True)
    model = PushModel.from_scene(scene)
    regions = free_regions(model)
    assert len(regions) == 8
    # The four faces meeting the stem-bar corners keep the finger a radius from the concave end.
    concave = [f.index for f in model.faces if f.lam_lo > 0 or f.lam_hi < 1]
    assert len(concave) == 4
    rng = np.random.default_rng(1)
    pts = rng.uniform(-3, 3, size=(6000, 2))
    for reg in regions:
        inside = [p for p in pts if reg.contains(p)]
        assert len(inside) > 50
        for p in inside:
            assert scene.shape.signed_distance((0, 0, 0), p) >= scene.finger_radius - 1e-9
    for i in range(8):
        assert any(regions[i].contains(p) and regions[(i + 1) % 8].contains(p) for p in pts), i
    # Touching a face anywhere in its allowed span is collision-free against the whole T.
    from lerobot_gcs_push.contact.face_contact import finger_body

    for f in model.faces:
        for lam in np.linspace(f.lam_lo, f.lam_hi, 7):
            q = finger_body(f, model, lam)
            assert scene.shape.signed_distance((0, 0, 0), q) >= scene.finger_radius - 1e-9
