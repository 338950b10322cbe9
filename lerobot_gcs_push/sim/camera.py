"""The scene's top-down camera: its intrinsics and pose, the VTK render engine it draws with, and the
mapping between world points and image pixels."""

from __future__ import annotations

import math

import numpy as np
from pydrake.geometry import (
    ClippingRange,
    ColorRenderCamera,
    DepthRange,
    DepthRenderCamera,
    LightParameter,
    MakeRenderEngineVtk,
    RenderCameraCore,
    RenderEngineVtkParams,
    SceneGraph,
)
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import CameraInfo, RgbdSensor

from lerobot_gcs_push.scene import Scene

# One light straight down and one along each horizontal axis: every face of the box, top or side, then
# shows exactly its diffuse colour, instead of the near-black sides a single headlight gives (which
# would look like the black finger).
_LIGHTS = [
    LightParameter(type="directional", frame="world", direction=d, intensity=1.0)
    for d in ([0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0])
]


def make_render_engine(scene: Scene):
    """A VTK engine that clears to the ground colour, lit by `_LIGHTS`."""
    return MakeRenderEngineVtk(
        RenderEngineVtkParams(backend="EGL", default_clear_color=np.array(scene.camera.ground_rgba[:3]), lights=_LIGHTS)
    )


class TopDownCamera:
    """The scene camera at a given image size (rows, cols).

    Image convention (`world_to_pixel`): the camera looks straight down with image right = world +x and
    image up = world +y; the square [-view_half_width, view_half_width]^2 of the motion plane
    (z = box_half) fills the image exactly.
    """

    def __init__(self, scene: Scene, size: tuple[int, int]):
        self.scene = scene
        self.size = tuple(size)

    def camera_info(self) -> CameraInfo:
        """Pinhole intrinsics that map the square [-v, v]^2 of the motion plane exactly onto the whole image.

        The motion plane z = box_half holds the finger's and the box's centres, so a finger anywhere in its
        commandable region is entirely in view (mapping the ground instead would cut it at the edges, since
        perspective magnifies it by h / (h - box_half)).
        """
        height_px, width_px = self.size
        depth, v = self.scene.camera.height_m - self.scene.box_half, self.scene.view_half_width
        # Principal point W/2, not Drake's documented pixel-centre value W/2 - 0.5: RenderEngineVtk renders the
        # optical axis half a pixel up-left of the stated one (measured: a sphere at the origin is centred on
        # (W/2 - 1, H/2 - 1) otherwise); with W/2 it lands on the image centre ((W-1)/2, (H-1)/2), as tested.
        return CameraInfo(
            width_px, height_px, width_px / 2 * depth / v, height_px / 2 * depth / v, width_px / 2, height_px / 2
        )

    def add_sensor(self, builder: DiagramBuilder, scene_graph: SceneGraph, renderer_name: str) -> RgbdSensor:
        """An `RgbdSensor` with this camera's view, rendered by `renderer_name`, wired to `scene_graph`."""
        camera = self.scene.camera
        X_WC = RigidTransform(RollPitchYaw(math.pi, 0, 0), [0, 0, camera.height_m])
        near, far = 0.1 * self.scene.box_size, 2 * camera.height_m
        core = RenderCameraCore(renderer_name, self.camera_info(), ClippingRange(near, far), RigidTransform())
        sensor = builder.AddSystem(
            RgbdSensor(
                scene_graph.world_frame_id(),
                X_WC,
                ColorRenderCamera(core, False),
                DepthRenderCamera(core, DepthRange(near * 1.01, far * 0.99)),
            )
        )
        builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
        return sensor

    def world_to_pixel(self, xy, z: float | None = None) -> np.ndarray:
        """Continuous (row, col) of the world point (x, y, z) in this camera's image.

        Pixel (r, c) has its centre at integer coordinates. In the motion plane z = box_half (default),
            col = (x + v) / (2 v) * W - 0.5,   row = (v - y) / (2 v) * H - 0.5,   v = view_half_width,
        so the square [-v, v]^2 spans the image edge to edge (1 px = 2 v / W m; 0.131 m at 96 px). Points at
        another height are scaled about the image centre by the perspective factor (h - box_half) / (h - z),
        h = camera height: the box's top face (z = box_size) looks 2.6% larger, the ground 2.5% smaller.
        """
        rows, cols = self.size
        v = self.scene.view_half_width
        xy = np.asarray(xy, dtype=float) * self._perspective(z)
        return np.array([(v - xy[..., 1]) / (2 * v) * rows - 0.5, (xy[..., 0] + v) / (2 * v) * cols - 0.5]).T

    def pixel_to_world(self, rc, z: float | None = None) -> np.ndarray:
        """Inverse of `world_to_pixel` at height z (default: the motion plane): (row, col) -> (x, y)."""
        rows, cols = self.size
        v = self.scene.view_half_width
        rc = np.asarray(rc, dtype=float)
        xy = np.array([(rc[..., 1] + 0.5) / cols * 2 * v - v, v - (rc[..., 0] + 0.5) / rows * 2 * v]).T
        return xy / self._perspective(z)

    def _perspective(self, z: float | None) -> float:
        h, half = self.scene.camera.height_m, self.scene.box_half
        return (h - half) / (h - (half if z is None else z))
