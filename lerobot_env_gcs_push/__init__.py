"""Shim that LeRobot's plugin discovery imports (distribution `lerobot_env_gcs_push`).

It registers the `gcs_push` env config and, through it, the `GcsPushBox-v0` gym env.
"""

import lerobot_gcs_push.lerobot_plugin  # noqa: F401
