"""The Drake simulation of the pushing scene, one concern per module:

- `plant`: the multibody plant (box and finger on prismatic joints, ground and goal visuals);
- `camera`: the top-down camera (intrinsics, render engine and lights, world <-> pixel mapping);
- `collision`: finger-box distance queries on a render-free copy of the plant;
- `controller`: the finger's PID controller on a finger-only control plant;
- `images`: the observation and render sensors of `PushSim`;
- `push_sim`: `PushSim`, the controlled, disturbed, rendered diagram that composes them;
- `spaces`: the env's action and observation spaces;
- `env`: `GcsPushEnv`, the Gymnasium env over it (made by id through `registration`; not imported here).
"""

from lerobot_gcs_push.sim.camera import TopDownCamera
from lerobot_gcs_push.sim.collision import CollisionQuery
from lerobot_gcs_push.sim.push_sim import PushSim

__all__ = ["CollisionQuery", "PushSim", "TopDownCamera"]
