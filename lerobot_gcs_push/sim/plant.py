"""The multibody plant of the pushing scene: the slider and a sphere finger, each on two prismatic joints,
with optional visual geometry (ground, goal marker, colours). Every number comes from `scene.Scene`.

The paper's box cannot turn: two damped prismatic joints, a cube. A slider that turns (its kind's `yaw_damping`) adds a
damped revolute joint about its centroid, and its geometry is its shape's convex parts (rectangles) as
boxes of the box's height: with damping b on x, y and `scene.rot_damping` on yaw, its quasi-static motion
v = f / b, omega = tau / b_theta is the planner's ellipsoidal limit surface.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, SceneGraph, Sphere
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    CoulombFriction,
    MultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import (
    FixedOffsetFrame,
    ModelInstanceIndex,
    PrismaticJoint,
    RevoluteJoint,
    RigidBody,
    SpatialInertia,
)
from pydrake.systems.framework import DiagramBuilder

from lerobot_gcs_push.scene import Scene

# Rendering-only sizes, relative to the box so they scale with the scene: the ground slab must extend
# past the view, and the goal marker must be thin enough to read as flat yet sit above the ground.
_GROUND_THICKNESS_REL = 0.1
_GOAL_THICKNESS_REL = 0.002
# The goal outline's line width, in observation pixels: wide enough that a line at any heading covers a
# pixel centre in every row or column it crosses (the outline never breaks up) and reads as goal colour.
_GOAL_LINE_PX = 2.0


@dataclass
class ScenePlant:
    """The finalized plant of `add_scene_plant` and the handles the simulation and its queries need."""

    plant: MultibodyPlant
    scene_graph: SceneGraph
    box_body: RigidBody
    finger_instance: ModelInstanceIndex
    q_box: list[int]  # the box's (x, y) in the plant's position vector
    q_finger: list[int]  # the finger's (x, y) in the plant's position vector
    v_box: list[int]  # the box's (vx, vy) in the velocity vector, where a force on its centre acts
    q_yaw: int | None = None  # a rotating slider's heading in the position vector
    v_yaw: int | None = None  # ... and its rate in the velocity vector, where a torque about its centroid acts

    def positions(self, box, finger, heading: float = 0.0) -> np.ndarray:
        """The plant's position vector with the slider at (x, y, heading) and the finger at (x, y)."""
        q = np.zeros(self.plant.num_positions())
        q[self.q_box] = np.asarray(box, dtype=float)
        q[self.q_finger] = np.asarray(finger, dtype=float)
        if self.q_yaw is not None:
            q[self.q_yaw] = heading
        elif heading != 0.0:
            raise ValueError(f"heading {heading} given, but this scene's slider cannot rotate")
        return q


def add_xy_slider(plant: MultibodyPlant, name: str, body, z: float, damping: float, rot_damping: float | None = None):
    """World -> x joint -> massless carriage -> y joint -> body, with the body's origin at height z; with
    `rot_damping`, a second massless carriage and a yaw joint about the body's origin come before the body.

    The carriages are massless: each joint's articulated inertia is still the body's mass (or, for yaw,
    its inertia about z), so the mass matrix stays regular and the dynamics are those of a rigid body in
    the plane. Returns (x joint, y joint, yaw joint or None).
    """
    instance = body.model_instance()
    carriage = plant.AddRigidBody(f"{name}_carriage", instance, SpatialInertia.Zero())
    base = plant.AddFrame(FixedOffsetFrame(f"{name}_base", plant.world_frame(), RigidTransform([0, 0, z])))
    jx = plant.AddJoint(PrismaticJoint(f"{name}_x", base, carriage.body_frame(), [1, 0, 0], damping=damping))
    if rot_damping is None:
        jy = plant.AddJoint(
            PrismaticJoint(f"{name}_y", carriage.body_frame(), body.body_frame(), [0, 1, 0], damping=damping)
        )
        return jx, jy, None
    turntable = plant.AddRigidBody(f"{name}_turntable", instance, SpatialInertia.Zero())
    jy = plant.AddJoint(
        PrismaticJoint(f"{name}_y", carriage.body_frame(), turntable.body_frame(), [0, 1, 0], damping=damping)
    )
    yaw = plant.AddJoint(
        RevoluteJoint(f"{name}_yaw", turntable.body_frame(), body.body_frame(), [0, 0, 1], damping=rot_damping)
    )
    return jx, jy, yaw


def add_finger(plant: MultibodyPlant, scene: Scene, *, collision: bool, visual: bool):
    """The actuated sphere finger in its own model instance; returns (instance, body, (x joint, y joint))."""
    instance = plant.AddModelInstance("finger")
    body = plant.AddRigidBody(
        "finger", instance, SpatialInertia.SolidSphereWithMass(scene.finger_mass, scene.finger_radius)
    )
    joints = add_xy_slider(plant, "finger", body, scene.box_half, 0.0)[:2]
    for joint in joints:
        plant.AddJointActuator(joint.name(), joint)
    sphere = Sphere(scene.finger_radius)
    if collision:
        friction = CoulombFriction(scene.finger_box_friction, scene.finger_box_friction)
        plant.RegisterCollisionGeometry(body, RigidTransform(), sphere, "finger", friction)
    if visual:
        plant.RegisterVisualGeometry(body, RigidTransform(), sphere, "finger", np.array(scene.camera.finger_rgba))
    return instance, body, joints


def slider_parts(scene: Scene) -> list[tuple[Box, RigidTransform]]:
    """The slider's convex parts as (box geometry, pose in the slider's frame): each part of the shape
    must be an axis-aligned rectangle (the square and the T's bar and stem are), extruded to the box's
    height and centred on the motion plane."""
    out = []
    for i, part in enumerate(scene.shape.parts):
        p = np.asarray(part, float)
        lo, hi = p.min(axis=0), p.max(axis=0)
        on_edges = np.all(np.isclose(p, lo) | np.isclose(p, hi), axis=1)
        if len(p) != 4 or not on_edges.all():
            raise ValueError(f"{scene.shape.name}: part {i} is not an axis-aligned rectangle: {part}")
        w, h = hi - lo
        out.append((Box(w, h, scene.box_size), RigidTransform([*(lo + hi) / 2, 0.0])))
    return out


def slider_inertia(scene: Scene, parts) -> SpatialInertia:
    """The slider's inertia about its centroid: the mass spread uniformly over the parts' area."""
    total = None
    for box, X in parts:
        mass = scene.box_mass * box.width() * box.depth() / scene.shape.area
        part = SpatialInertia.SolidBoxWithMass(mass, box.width(), box.depth(), box.height())
        part = part.Shift(-X.translation())  # about the slider's origin, from the part's centre
        if total is None:
            total = part
        else:
            total += part  # in place: pydrake binds += but not +
    return total


def add_goal_outline(plant: MultibodyPlant, scene: Scene, thickness: float) -> None:
    """The goal pose as a closed outline of thin bars on the ground, one per face of the shape; each bar
    is one line width longer than its edge, so that the corners close."""
    width = _GOAL_LINE_PX * 2 * scene.view_half_width / min(scene.camera.width, scene.camera.height)
    outline = scene.shape.world_outline(scene.goal_pose)
    for i, (a, b) in enumerate(zip(outline, np.roll(outline, -1, axis=0))):
        d = b - a
        X = RigidTransform(RotationMatrix.MakeZRotation(np.arctan2(d[1], d[0])), [*(a + b) / 2, thickness / 2])
        bar = Box(float(np.linalg.norm(d)) + width, width, thickness)
        plant.RegisterVisualGeometry(plant.world_body(), X, bar, f"goal_{i}", np.array(scene.camera.goal_rgba))


def add_scene_plant(builder: DiagramBuilder, scene: Scene, *, visual: bool) -> ScenePlant:
    """The slider, finger, ground and goal in a discrete plant; visual geometry only when `visual`.

    Point contact: the sphere-box pair is resolved exactly by it and it is the cheapest model. Sampled
    output ports are off: nothing reads contact results between steps, and sampling costs ~7% of a step.
    """
    plant, scene_graph = AddMultibodyPlant(
        MultibodyPlantConfig(
            time_step=scene.time_step,
            contact_model="point",
            discrete_contact_approximation="lagged",
            use_sampled_output_ports=False,
        ),
        builder,
    )
    parts = slider_parts(scene)
    box_body = plant.AddRigidBody("box", plant.AddModelInstance("box"), slider_inertia(scene, parts))
    *box_joints, yaw = add_xy_slider(
        plant, "box", box_body, scene.box_half, scene.box_damping, scene.kind.yaw_damping(scene)
    )
    friction = CoulombFriction(scene.finger_box_friction, scene.finger_box_friction)
    # One part keeps the paper's geometry name "box"; a union of parts numbers them.
    names = ["box"] if len(parts) == 1 else [f"box_{i}" for i in range(len(parts))]
    for name, (geometry, X) in zip(names, parts):
        plant.RegisterCollisionGeometry(box_body, X, geometry, name, friction)
    finger_instance, _, finger_joints = add_finger(plant, scene, collision=True, visual=visual)
    if visual:
        camera = scene.camera
        for name, (geometry, X) in zip(names, parts):
            plant.RegisterVisualGeometry(box_body, X, geometry, name, np.array(camera.box_rgba))
        world = plant.world_body()
        side, ground_t = 4 * scene.view_half_width, _GROUND_THICKNESS_REL * scene.box_size
        plant.RegisterVisualGeometry(
            world,
            RigidTransform([0, 0, -ground_t / 2]),
            Box(side, side, ground_t),
            "ground",
            np.array(camera.ground_rgba),
        )
        goal_t = _GOAL_THICKNESS_REL * scene.box_size
        if yaw is not None:  # a pose, not a position: the outline shows the heading to reach
            add_goal_outline(plant, scene, goal_t)
        else:
            plant.RegisterVisualGeometry(
                world,
                RigidTransform([*scene.goal, goal_t / 2]),
                Box(scene.box_size, scene.box_size, goal_t),
                "goal",
                np.array(camera.goal_rgba),
            )
    plant.Finalize()
    n = 2 + scene.kind.pose_size
    assert plant.num_positions() == n and plant.num_velocities() == n
    return ScenePlant(
        plant=plant,
        scene_graph=scene_graph,
        box_body=box_body,
        finger_instance=finger_instance,
        q_box=[j.position_start() for j in box_joints],
        q_finger=[j.position_start() for j in finger_joints],
        v_box=[j.velocity_start() for j in box_joints],
        q_yaw=None if yaw is None else yaw.position_start(),
        v_yaw=None if yaw is None else yaw.velocity_start(),
    )
