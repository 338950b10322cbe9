"""lerobot-gcs-push: optimal GCS pushing demonstrations for LeRobot.

Importing the package registers the Gymnasium env `GcsPushBox-v0` (and `gym_gcs_push/GcsPushBox-v0`,
the id LeRobot's env factory asks for).
"""

from lerobot_gcs_push.scene import Scene

__all__ = ["Scene"]
__version__ = "0.1.0"

try:  # the env needs Drake; the planner and scene must stay importable without it
    from lerobot_gcs_push.env import register_envs as _register_envs
except ImportError as _err:  # pragma: no cover - only without drake/gymnasium installed
    import warnings

    warnings.warn(f"GcsPushBox-v0 not registered: {_err}", stacklevel=2)
else:
    _register_envs()
