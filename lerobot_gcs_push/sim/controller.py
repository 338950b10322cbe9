"""The finger's low-level controller (paper section III-C): `StateInterpolatorWithDiscreteDerivative` ->
`InverseDynamicsController` (PID), built on a finger-only control plant; its gains come from `scene.Scene`."""

from __future__ import annotations

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import StateInterpolatorWithDiscreteDerivative

from lerobot_gcs_push.scene import Scene
from lerobot_gcs_push.sim.plant import ScenePlant, add_finger


def add_finger_controller(
    builder: DiagramBuilder, model: ScenePlant, scene: Scene
) -> tuple[StateInterpolatorWithDiscreteDerivative, InverseDynamicsController, MultibodyPlant]:
    """Add the controller to `builder`, driving `model`'s finger; returns the interpolator (its input is the
    commanded finger (x, y)), the controller and the control plant (which the caller must keep alive)."""
    # The controller sees only the finger: the box's dynamics are an unmodelled disturbance, as in
    # the paper's setup.
    control_plant = MultibodyPlant(time_step=0.0)
    add_finger(control_plant, scene, collision=False, visual=False)
    control_plant.Finalize()
    gains = [np.full(2, g) for g in (scene.kp, scene.ki, scene.kd)]
    controller = builder.AddSystem(InverseDynamicsController(control_plant, *gains, False))
    interpolator = builder.AddSystem(StateInterpolatorWithDiscreteDerivative(2, scene.time_step, True))
    builder.Connect(interpolator.get_output_port(), controller.get_input_port_desired_state())
    builder.Connect(
        model.plant.get_state_output_port(model.finger_instance), controller.get_input_port_estimated_state()
    )
    builder.Connect(controller.get_output_port_control(), model.plant.get_actuation_input_port(model.finger_instance))
    return interpolator, controller, control_plant
