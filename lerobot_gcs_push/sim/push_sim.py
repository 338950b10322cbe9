"""The Drake diagram of the pushing scene (paper section III-C).

A discrete MultibodyPlant (`plant.add_scene_plant`) holds the slider on two damped prismatic joints (and,
for a slider that turns, a damped yaw joint) and a sphere finger on two actuated prismatic joints. The finger
follows a commanded position through the paper's low-level controller:
`StateInterpolatorWithDiscreteDerivative` -> `InverseDynamicsController` (PID) built on a finger-only
control plant. A force disturbance can be applied at the slider's centre (with a torque about it when the
slider turns), and a top-down `RgbdSensor` (`camera.TopDownCamera`) renders the image. Every number
comes from `scene.Scene`.

The diagram is built once per `PushSim`; `reset` only rewrites the context, so thousands of episodes can
reuse it.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from pydrake.systems.framework import DiagramBuilder

from lerobot_gcs_push.scene import Scene
from lerobot_gcs_push.sim.camera import TopDownCamera
from lerobot_gcs_push.sim.collision import CollisionQuery
from lerobot_gcs_push.sim.controller import add_finger_controller
from lerobot_gcs_push.sim.images import SimImages
from lerobot_gcs_push.sim.plant import add_scene_plant

# The diagram's exported inputs.
_COMMAND_INPUT = "finger_command"  # the finger's commanded (x, y)
_FORCE_INPUT = "applied_force"  # generalized forces on the plant's velocities


class PushSim:
    """The simulated pushing scene. Positions are world (x, y) in metres; images are uint8 (H, W, 3), in
    the image convention of `TopDownCamera`.
    """

    def __init__(self, scene: Scene, render_size: tuple[int, int] | None = (384, 384)):
        """`render_size` (rows, cols) is the optional larger image of `render_image`; the observation
        image has the scene camera's size."""
        self.scene = scene
        self.image_size = (scene.camera.height, scene.camera.width)
        self.render_size = tuple(render_size) if render_size is not None else self.image_size
        ticks = scene.disturbances.tick_s / scene.time_step
        if abs(ticks - round(ticks)) > 1e-9 or round(ticks) < 1:
            raise ValueError(
                f"disturbance tick {scene.disturbances.tick_s} s must be a multiple of the plant "
                f"time step {scene.time_step} s"
            )
        self._steps_per_tick = round(ticks)

        builder = DiagramBuilder()
        model = add_scene_plant(builder, scene, visual=True)
        self._model = model
        self.plant = model.plant

        # InverseDynamicsController keeps a reference to the control plant: keep it alive.
        self._interpolator, self._controller, self._control_plant = add_finger_controller(builder, model, scene)
        builder.ExportInput(self._interpolator.get_input_port(), _COMMAND_INPUT)
        builder.ExportInput(self.plant.get_applied_generalized_force_input_port(), _FORCE_INPUT)

        self._images = SimImages(builder, model.scene_graph, scene, self.image_size, self.render_size)
        self.camera = self._images.camera

        self.diagram = builder.Build()
        self._simulator = Simulator(self.diagram)
        # The PID integral is the only continuous state; its derivative is constant between plant steps,
        # so one explicit Euler step per plant step integrates it exactly (and cheaply).
        ResetIntegratorFromFlags(self._simulator, "explicit_euler", scene.time_step)
        self._context = self._simulator.get_mutable_context()
        self._plant_context = self.plant.GetMyMutableContextFromRoot(self._context)
        self._interp_context = self._interpolator.GetMyMutableContextFromRoot(self._context)
        self._controller_context = self._controller.GetMyMutableContextFromRoot(self._context)
        self._images.bind(self._context, self.plant, self._plant_context)

        # Fixed input values are rewritten in place (GetMutableData also invalidates dependents).
        self._command_port = self.diagram.GetInputPort(_COMMAND_INPUT).FixValue(self._context, np.zeros(2))
        nv = self.plant.num_velocities()
        self._force_port = self.diagram.GetInputPort(_FORCE_INPUT).FixValue(self._context, np.zeros(nv))
        self._force_buf = np.zeros(nv)
        # Generalized-force slots of one disturbance row: (fx, fy) on the slider's centre, then its torque.
        self._wrench_index = model.v_box + ([] if model.v_yaw is None else [model.v_yaw])
        self._force_nonzero = False
        # Reset restores the state only: copying the whole context would also copy SceneGraph's
        # parameters, which hold the render engines (milliseconds per reset).
        self._default_xc = self._context.get_continuous_state_vector().CopyToVector()
        self._default_xd = self._context.get_discrete_state().Clone()
        self._default_xa = self._context.get_abstract_state().Clone()
        self._step_count = 0

        self._collision = CollisionQuery(scene)

        self.reset(np.array([0.0, 0.0]), np.array([0.0, -scene.finger_limit]))

    # --- state -------------------------------------------------------------------------------------
    def reset(self, box, finger, heading: float = 0.0) -> None:
        """Place slider (at box, heading) and finger at rest at t = 0; the controller then holds the finger
        where it is."""
        finger = np.asarray(finger, dtype=float)
        self._context.SetTime(0.0)
        self._context.SetContinuousState(self._default_xc)
        self._context.get_mutable_discrete_state().SetFrom(self._default_xd)
        self._context.get_mutable_abstract_state().SetFrom(self._default_xa)
        self.plant.SetPositions(self._plant_context, self._model.positions(box, finger, heading))
        self._interpolator.set_initial_position(self._interp_context, finger)
        self._controller.set_integral_value(self._controller_context, np.zeros(2))
        self._command_port.GetMutableData().get_mutable_value().set_value(finger)
        self._set_force(None)
        self._step_count = 0
        self._simulator.Initialize()

    def step(self, command_xy, duration_s: float, forces: np.ndarray | None = None) -> None:
        """Hold the finger command for `duration_s` of simulated time.

        `forces` is None (no disturbance) or an array (n_ticks, 2) in N of the force on the box centre
        during each disturbance tick (`scene.disturbances.tick_s`) of this step; for a rotating slider,
        (n_ticks, 3): the world force (N) on its centroid and the torque (N*m) about it.
        """
        n_steps = self.steps_in(duration_s)
        self._command_port.GetMutableData().get_mutable_value().set_value(np.asarray(command_xy, dtype=float))
        dt = self.scene.time_step
        if forces is None:
            self._set_force(None)
            self._step_count += n_steps
            self._simulator.AdvanceTo(self._step_count * dt)
            return
        forces = np.asarray(forces, dtype=float)
        expected = (n_steps // self._steps_per_tick, len(self._wrench_index))
        if forces.shape != expected:
            raise ValueError(f"forces must have shape {expected}, got {forces.shape}")
        # Advance once per run of equal forces: most ticks carry no disturbance.
        start = 0
        while start < len(forces):
            end = start + 1
            while end < len(forces) and np.array_equal(forces[end], forces[start]):
                end += 1
            self._set_force(forces[start])
            self._step_count += (end - start) * self._steps_per_tick
            self._simulator.AdvanceTo(self._step_count * dt)
            start = end

    def steps_in(self, duration_s: float) -> int:
        """Number of plant steps in `duration_s`, which must be a whole number of disturbance ticks."""
        ticks = duration_s / self.scene.disturbances.tick_s
        if not ticks >= 1 or abs(ticks - round(ticks)) > 1e-6:
            raise ValueError(
                f"duration {duration_s} s must be a positive multiple of the {self.scene.disturbances.tick_s} s tick"
            )
        return round(ticks) * self._steps_per_tick

    def _set_force(self, force) -> None:
        if force is None or not np.any(force):
            if self._force_nonzero:
                self._force_port.GetMutableData().get_mutable_value().set_value(np.zeros_like(self._force_buf))
                self._force_nonzero = False
            return
        self._force_buf[:] = 0.0
        self._force_buf[self._wrench_index] = force
        self._force_port.GetMutableData().get_mutable_value().set_value(self._force_buf)
        self._force_nonzero = True

    @property
    def time(self) -> float:
        return self._context.get_time()

    def box_position(self) -> np.ndarray:
        return self.plant.GetPositions(self._plant_context)[self._model.q_box]

    def box_heading(self) -> float:
        """The slider's yaw joint angle (radians, not wrapped); 0 for a slider that cannot rotate."""
        if self._model.q_yaw is None:
            return 0.0
        return float(self.plant.GetPositions(self._plant_context)[self._model.q_yaw])

    def finger_position(self) -> np.ndarray:
        return self.plant.GetPositions(self._plant_context)[self._model.q_finger]

    def box_pose(self) -> RigidTransform:
        return self.plant.EvalBodyPoseInWorld(self._plant_context, self._model.box_body)

    def contact_wrench(self) -> np.ndarray:
        """The finger's contact force on the slider (world, N) and its torque about the slider's centre
        (N*m), as the plant's next step applies them: [fx, fy, tau], zero when they do not touch."""
        results = self.plant.get_contact_results_output_port().Eval(self._plant_context)
        slider = self._model.box_body.index()
        centre = self.box_pose().translation()
        out = np.zeros(3)
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)
            # contact_force() acts on body B; the slider is one of the pair.
            f = info.contact_force() if info.bodyB_index() == slider else -info.contact_force()
            r = info.contact_point() - centre
            out += [f[0], f[1], r[0] * f[1] - r[1] * f[0]]
        return out

    # --- geometry ------------------------------------------------------------------------------------
    def signed_distance(self, box, finger, heading: float = 0.0) -> float:
        """`CollisionQuery.signed_distance`: finger-slider distance at the given poses (< 0: overlap)."""
        return self._collision.signed_distance(box, finger, heading)

    def collides(self, box, finger, heading: float = 0.0) -> bool:
        """`CollisionQuery.collides`: whether finger and slider interpenetrate (touching is allowed)."""
        return self._collision.collides(box, finger, heading)

    # --- images --------------------------------------------------------------------------------------
    def image(self) -> np.ndarray:
        return self._images.image()

    def render_image(self) -> np.ndarray:
        """The `render_size` image (for videos); the same view as `image`."""
        return self._images.render_image()

    def world_to_pixel(self, xy, z: float | None = None, size: tuple[int, int] | None = None) -> np.ndarray:
        """`TopDownCamera.world_to_pixel` in an image of `size` (default: the observation image)."""
        return self._camera(size).world_to_pixel(xy, z)

    def pixel_to_world(self, rc, z: float | None = None, size: tuple[int, int] | None = None) -> np.ndarray:
        """`TopDownCamera.pixel_to_world` in an image of `size` (default: the observation image)."""
        return self._camera(size).pixel_to_world(rc, z)

    def _camera(self, size: tuple[int, int] | None) -> TopDownCamera:
        return self.camera if size is None else TopDownCamera(self.scene, size)
