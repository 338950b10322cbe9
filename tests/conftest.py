import os
import tempfile

# Tests never reach the network, and figures render off-screen.
os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
# LeRobot reads HF_LEROBOT_HOME once, at import: point it at a private cache before anything imports
# lerobot, so tests never touch (or depend on) the user's real cache.
os.environ["HF_LEROBOT_HOME"] = tempfile.mkdtemp(prefix="gcs_push_lerobot_home_")
