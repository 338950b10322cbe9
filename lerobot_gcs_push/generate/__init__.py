"""Demonstrations: sample initial conditions, plan with GCS, roll out in the env, write a LeRobotDataset.

Shards: the initial conditions are cut into contiguous ranges, each run by one job on a worker (a local
process or a Ray actor: see `workers`), which writes that range's successful episodes as a LeRobotDataset of
its own, the shard, beside the dataset (`<root>.shards/shard_<first index>`). The driver merges the shards
with LeRobot's aggregation into a staging folder, moved into place only once it is complete, so the cache
never holds a half-written dataset.

Crash safety: a job saves each finished episode as one compressed file in a work folder beside the dataset
(`<root>.work/`), and a shard appears by atomic rename, whole or not at all. A job run again (Ray retries the
job of a worker that died; `resume` repeats an interrupted run) keeps the finished shards and episodes and
never leaves half a shard. `overwrite` starts again.

Determinism: the i-th initial condition and its episode seed depend only on (seed, i), and the dataset is the
first `episodes` successful rollouts in index order, so its contents do not depend on the backend, `workers`
or `shard_size`.
"""

from lerobot_gcs_push.generate.config import EPISODES_META, SETTINGS_META, GenerateConfig, dataset_root, lerobot_home
from lerobot_gcs_push.generate.frames import FEATURE_KEYS, EpisodeFrames, features, read_episode_metadata
from lerobot_gcs_push.generate.generator import GenerateReport, generate, merge_datasets
from lerobot_gcs_push.generate.workdir import WorkDir

__all__ = [
    "EPISODES_META",
    "FEATURE_KEYS",
    "SETTINGS_META",
    "EpisodeFrames",
    "GenerateConfig",
    "GenerateReport",
    "WorkDir",
    "dataset_root",
    "features",
    "generate",
    "lerobot_home",
    "merge_datasets",
    "read_episode_metadata",
]
