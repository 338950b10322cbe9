"""Finger-box distance queries by Drake's geometry, on their own render-free copy of the scene plant."""

from __future__ import annotations

from pydrake.systems.framework import DiagramBuilder

from lerobot_gcs_push.scene import Scene
from lerobot_gcs_push.sim.plant import add_scene_plant


class CollisionQuery:
    """Signed distance and interpenetration of finger and box at arbitrary positions.

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

    def signed_distance(self, box, finger) -> float:
        """Drake's signed distance between finger and box geometry at the given positions (< 0: overlap)."""
        self._model.plant.SetPositions(self._plant_context, self._model.positions(box, finger))
        query = self._port.Eval(self._plant_context)
        pairs = query.ComputeSignedDistancePairwiseClosestPoints()
        assert len(pairs) == 1, "the scene has exactly one collision pair: finger-box"
        return float(pairs[0].distance)

    def collides(self, box, finger) -> bool:
        """Whether finger and box geometries interpenetrate (touching is allowed), by Drake's query."""
        return self.signed_distance(box, finger) < 0.0
