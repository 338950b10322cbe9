"""Finger-slider distance queries by Drake's geometry, on their own render-free copy of the scene plant."""

from __future__ import annotations

from pydrake.systems.framework import DiagramBuilder

from lerobot_gcs_push.scene import Scene
from lerobot_gcs_push.sim.plant import add_scene_plant


class CollisionQuery:
    """Signed distance and interpenetration of finger and slider at arbitrary poses.

    The queries use a second, render-free copy of the simulation's plant: checking a candidate never
    disturbs the simulation, and its context is cheap.
    """

    def __init__(self, scene: Scene):
        builder = DiagramBuilder()
        self._model = add_scene_plant(builder, scene, visual=False)
        self._diagram = builder.Build()  # the contexts below refer to it
        self._root = self._diagram.CreateDefaultContext()
        self._plant_context = self._model.plant.GetMyMutableContextFromRoot(self._root)
        self._port = self._model.plant.get_geometry_query_input_port()
        self._n_parts = len(scene.shape.parts)

    def signed_distance(self, box, finger, heading: float = 0.0) -> float:
        """Drake's signed distance between the finger and the slider at (box, heading) (< 0: overlap).

        The slider is a union of convex parts, one collision pair each with the finger: the finger
        overlaps the union exactly when it overlaps a part, and outside it the nearest part is the union's
        distance, so the minimum over the pairs is the union's distance wherever its sign matters.
        """
        self._model.plant.SetPositions(self._plant_context, self._model.positions(box, finger, heading))
        query = self._port.Eval(self._plant_context)
        pairs = query.ComputeSignedDistancePairwiseClosestPoints()
        assert len(pairs) == self._n_parts, "the scene's collision pairs are finger-part, one per slider part"
        return float(min(p.distance for p in pairs))

    def collides(self, box, finger, heading: float = 0.0) -> bool:
        """Whether finger and slider geometries interpenetrate (touching is allowed), by Drake's query."""
        return self.signed_distance(box, finger, heading) < 0.0
