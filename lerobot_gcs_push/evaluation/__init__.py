"""The paper's evaluation protocol (section IV) for any set of policies: records, tables, figures.

In any registered env (`env_id`): the box that cannot turn is scored as in the paper, a rotating slider by
the env's coverage rule, with its heading and pose in the records; the GCS experts and regret are the
box's only, for now.

Policies: `gcs-open-loop` (plan once, execute), `gcs-closed-loop` (replan after disturbances), or a
LeRobot `pretrained_model` directory (loaded through LeRobot's own factory and processors; its action
chunks run exactly as in `lerobot-eval`). With `disturbances`, each closed-loop or learned policy is also
run under the paper's force disturbances.

Every run appends one JSON line to `runs.jsonl` as soon as it ends (with its trajectory saved first), so
an interrupted evaluation keeps its finished runs and continues where it stopped.

The modules: `config` (settings, policies, initial conditions, variants), `runner` (the runs, in worker
processes), `learned` (a LeRobot checkpoint as a policy), `records` (what the folder holds), `tables`
(summary and tables), `protocol` (`evaluate`, which ties them).
"""

from lerobot_gcs_push.evaluation.config import (
    GCS_POLICIES,
    NAMED_SET_SEEDS,
    EvaluateConfig,
    check_device,
    check_policy,
    initial_conditions,
    variant_label,
    variants,
)
from lerobot_gcs_push.evaluation.learned import LearnedPolicy
from lerobot_gcs_push.evaluation.protocol import evaluate
from lerobot_gcs_push.evaluation.records import (
    TIMING_FIELDS,
    Trajectory,
    changed_weights,
    read_runs,
    video_path,
    weights_fingerprint,
)
from lerobot_gcs_push.evaluation.tables import PAPER, summarize

__all__ = [
    "GCS_POLICIES",
    "NAMED_SET_SEEDS",
    "PAPER",
    "TIMING_FIELDS",
    "EvaluateConfig",
    "LearnedPolicy",
    "Trajectory",
    "changed_weights",
    "check_device",
    "check_policy",
    "evaluate",
    "initial_conditions",
    "read_runs",
    "summarize",
    "variant_label",
    "variants",
    "video_path",
    "weights_fingerprint",
]
