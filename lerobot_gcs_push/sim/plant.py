"""The multibody plant of the pushing scene: a non-rotating box and a sphere finger, each on two prismatic
joints, with optional visual geometry (ground, goal marker, colours). Every number comes from `scene.Scene`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, SceneGraph, Sphere
from pydrake.math import RigidTransform
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    CoulombFriction,
    MultibodyPlant,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import FixedOffsetFrame, ModelInstanceIndex, PrismaticJoint, RigidBody, SpatialInertia
from pydrake.systems.framework import DiagramBuilder

from lerobot_gcs_push.scene import Scene

# Rendering-only sizes, relative to the box so they scale with the scene: the ground slab must extend
# past the view, and the goal marker must be thin enough to read as flat yet sit above the ground.
_GROUND_THICKNESS_REL = 0.1
_GOAL_THICKNESS_REL = 0.002


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

    def positions(self, box, finger) -> np.ndarray:
        """The plant's position vector with the box and the finger at the given (x, y)."""
        q = np.zeros(4)
        q[self.q_box] = np.asarray(box, dtype=float)
        q[self.q_finger] = np.asarray(finger, dtype=float)
        return q


def add_xy_slider(plant: MultibodyPlant, name: str, body, z: float, damping: float):
    """World -> x joint -> massless carriage -> y joint -> body, with the body's origin at height z.

    The carriage is massless: the x joint's articulated inertia is still the body's mass, so the mass
    matrix stays regular and the dynamics are those of a point mass in the plane.
    """
    instance = body.model_instance()
    carriage = plant.AddRigidBody(f"{name}_carriage", instance, SpatialInertia.Zero())
    base = plant.AddFrame(FixedOffsetFrame(f"{name}_base", plant.world_frame(), RigidTransform([0, 0, z])))
    jx = plant.AddJoint(PrismaticJoint(f"{name}_x", base, carriage.body_frame(), [1, 0, 0], damping=damping))
    jy = plant.AddJoint(
        PrismaticJoint(f"{name}_y", carriage.body_frame(), body.body_frame(), [0, 1, 0], damping=damping)
    )
    return jx, jy


def add_finger(plant: MultibodyPlant, scene: Scene, *, collision: bool, visual: bool):
    """The actuated sphere finger in its own model instance; returns (instance, body, (x joint, y joint))."""
    instance = plant.AddModelInstance("finger")
    body = plant.AddRigidBody(
        "finger", instance, SpatialInertia.SolidSphereWithMass(scene.finger_mass, scene.finger_radius)
    )
    joints = add_xy_slider(plant, "finger", body, scene.box_half, 0.0)
    for joint in joints:
        plant.AddJointActuator(joint.name(), joint)
    sphere = Sphere(scene.finger_radius)
    if collision:
        friction = CoulombFriction(scene.finger_box_friction, scene.finger_box_friction)
        plant.RegisterCollisionGeometry(body, RigidTransform(), sphere, "finger", friction)
    if visual:
        plant.RegisterVisualGeometry(body, RigidTransform(), sphere, "finger", np.array(scene.camera.finger_rgba))
    return instance, body, joints


def add_scene_plant(builder: DiagramBuilder, scene: Scene, *, visual: bool) -> ScenePlant:
    """The box, finger, ground and goal in a discrete plant; visual geometry only when `visual`.

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
    box_body = plant.AddRigidBody(
        "box",
        plant.AddModelInstance("box"),
        SpatialInertia.SolidBoxWithMass(scene.box_mass, scene.box_size, scene.box_size, scene.box_size),
    )
    box_joints = add_xy_slider(plant, "box", box_body, scene.box_half, scene.box_damping)
    cube = Box(scene.box_size, scene.box_size, scene.box_size)
    friction = CoulombFriction(scene.finger_box_friction, scene.finger_box_friction)
    plant.RegisterCollisionGeometry(box_body, RigidTransform(), cube, "box", friction)
    finger_instance, _, finger_joints = add_finger(plant, scene, collision=True, visual=visual)
    if visual:
        camera = scene.camera
        plant.RegisterVisualGeometry(box_body, RigidTransform(), cube, "box", np.array(camera.box_rgba))
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
        plant.RegisterVisualGeometry(
            world,
            RigidTransform([*scene.goal, goal_t / 2]),
            Box(scene.box_size, scene.box_size, goal_t),
            "goal",
            np.array(camera.goal_rgba),
        )
    plant.Finalize()
    assert plant.num_positions() == 4 and plant.num_velocities() == 4
    return ScenePlant(
        plant=plant,
        scene_graph=scene_graph,
        box_body=box_body,
        finger_instance=finger_instance,
        q_box=[j.position_start() for j in box_joints],
        q_finger=[j.position_start() for j in finger_joints],
        v_box=[j.velocity_start() for j in box_joints],
    )
