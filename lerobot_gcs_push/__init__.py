"""lerobot-gcs-push: optimal GCS pushing demonstrations for LeRobot.

Importing the package registers the Gymnasium envs `GcsPushBox-v0` (the box, yaw locked), `GcsPushBoxSE2-v0`
and `GcsPushT-v0` (rotating sliders). Drake loads only when an env is made.
"""

from lerobot_gcs_push.registration import register_envs as _register_envs
from lerobot_gcs_push.scene import Scene

__all__ = ["Scene"]
__version__ = "0.1.0"

_register_envs()
