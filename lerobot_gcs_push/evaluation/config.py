"""What an evaluation runs: its settings (`EvaluateConfig`), the policies it may name, its initial
conditions, and each policy's variants (with and without disturbances) and their labels."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from lerobot_gcs_push.episodes.workers import FanOut
from lerobot_gcs_push.planning.factory import ExpertConfig
from lerobot_gcs_push.registration import SCENES, sample_starts
from lerobot_gcs_push.scene import load_initial_conditions
from lerobot_gcs_push.scene.options import StartsConfig
from lerobot_gcs_push.settings import flat_options

GCS_POLICIES = ("gcs-open-loop", "gcs-closed-loop")
# The named evaluation sets: the paper's protocol set (uniform, seed 1000) and the hard set (seed 3000).
NAMED_SET_SEEDS = {"uniform": 1000, "sobol": 1000, "hard": 3000, "hard_v2": 3000}


def check_policy(policy: str) -> str:
    """`policy` as given (it labels the records), once it names an expert or a pretrained_model folder,
    from the working folder or shipped (`shipped.shipped_path`)."""
    from lerobot_gcs_push.artifacts.checkpoints import is_pretrained_dir
    from lerobot_gcs_push.artifacts.shipped import shipped_path

    if policy not in GCS_POLICIES and not is_pretrained_dir(shipped_path(policy)):
        raise ValueError(
            f"unknown policy {policy!r}: use {' or '.join(GCS_POLICIES)}, or a LeRobot pretrained_model "
            f"directory (config.json and model.safetensors)"
        )
    if policy not in GCS_POLICIES:  # a policy no env observation can feed is refused before any run
        from lerobot_gcs_push.evaluation.learned import policy_obs_type

        policy_obs_type(shipped_path(policy))
    return policy


def check_device(device: str) -> str:
    if device not in ("cpu", "cuda", "mps") and not device.startswith("cuda:"):
        raise ValueError(f"unknown device {device!r}: use cpu, cuda, cuda:N or mps")
    return device


@flat_options
@dataclass
class EvaluateConfig(FanOut):
    # gcs-open-loop, gcs-closed-loop, or LeRobot pretrained_model directories:
    # --policies='[gcs-open-loop,policies/diffusion_cpu]'.
    policies: list[str] = field(default_factory=lambda: ["gcs-open-loop"])
    # Where the runs start: --env_id, --sampler, --seed, --disturbances, --initial_conditions (`--starts.seed`
    # works too); without a list, `num_initial_conditions` are sampled from the env's scene.
    starts: StartsConfig = field(default_factory=StartsConfig)
    # The GCS experts' settings (--method, --expert.replan_tolerance, --expert.commands=steer ...); the
    # policies name their mode (gcs-open-loop, gcs-closed-loop).
    expert: ExpertConfig = field(default_factory=ExpertConfig)
    # How many initial conditions to sample (without --initial_conditions).
    num_initial_conditions: int = 20
    # Regret of each executed chunk against the GCS cost-to-go (planning.factory.chunk_regret); a chunk above
    # `large_regret_m` is a mistake (the GCS experts stay under 0.5 m per chunk, tracking lag included,
    # unless a disturbance strikes). Default: on where the env has a GCS expert (the box).
    regret: bool | None = None
    # Metres of regret that make a chunk a mistake.
    large_regret_m: float = 0.5
    # Runs per initial condition.
    runs: int = 5
    # Where runs.jsonl, tables.md, summary.json, figures and videos go; a re-run continues there, unless
    # a learned policy's weights changed since (then it stops and asks for --overwrite).
    output_dir: str = "outputs/eval"
    # Torch device of learned policies: cpu, cuda, cuda:N or mps.
    device: str = "cpu"
    # FanOut's, but one by default: runs in this process, with no policy loaded per worker (a learned
    # policy takes seconds to load; a short evaluation is over before a pool would be).
    workers: int = 1
    # Simulated seconds before a run counts as failed. Default: the env's own (the paper's 500 for the Drake
    # envs, gym-pusht's 30, its 300 steps).
    timeout_s: float | None = None
    # Success radii (m) of the box centre around the goal: the paper's 0.1 and a looser one. A rotating
    # slider succeeds by the env's coverage instead, and its tables give the mean coverage.
    success_thresholds: tuple[float, float] = (0.1, 0.2)
    # Repo id (or path) of the training dataset, for Fig. 4.
    dataset: str | None = None
    # Videos of run 0 of the first `videos` initial conditions, per policy.
    videos: int = 2
    # Delete an earlier evaluation in output_dir first.
    overwrite: bool = False

    def __post_init__(self) -> None:
        from lerobot_gcs_push.planning.factory import check_cost_to_go

        env_id = self.starts.env_id
        if not self.policies:
            raise ValueError("give at least one policy")
        if self.runs < 1 or self.num_initial_conditions < 1:
            raise ValueError("runs and num_initial_conditions must be >= 1")
        self.check_fan_out()
        if self.timeout_s is None:
            self.timeout_s = SCENES[env_id].timeout_s
        if not 0 < self.timeout_s < float("inf"):
            raise ValueError(f"timeout_s must be positive and finite, got {self.timeout_s}")
        for p in self.policies:
            check_policy(p)
        if self.expert.mode is not None:
            raise ValueError(f"--expert={self.expert.mode}: name the experts in --policies ({', '.join(GCS_POLICIES)})")
        self.expert.check_env(env_id)
        if self.regret is None:
            self.regret = SCENES[env_id].kind.cost_to_go
        elif self.regret:
            check_cost_to_go(env_id, "regret is scored against it: leave --regret unset or false")
        self.starts.fill(sampler="uniform", seed=NAMED_SET_SEEDS.get)
        check_device(self.device)
        if self.dataset is not None:  # read for Fig. 4 only at the end: a typo must not cost the evaluation
            from lerobot_gcs_push.generate import lerobot_home

            if not (Path(self.dataset).is_dir() or (lerobot_home() / self.dataset).is_dir()):
                raise ValueError(
                    f"dataset {self.dataset!r} is neither a folder nor in the LeRobot cache ({lerobot_home()})"
                )


def variants(cfg: EvaluateConfig) -> list[tuple[str, bool]]:
    out = []
    for p in cfg.policies:
        out.append((p, False))
        if cfg.starts.disturbances and p != "gcs-open-loop":
            out.append((p, True))
    return out


def variant_label(policy: str, disturbances: bool) -> str:
    name = policy if policy in GCS_POLICIES else _learned_name(policy)
    return name + (" +dist" if disturbances else "")


def _learned_name(path: str) -> str:
    p = Path(path).resolve()
    parts = [x for x in p.parts[-4:] if x not in ("pretrained_model", "checkpoints")]
    return "dp:" + "/".join(parts[-2:])


def initial_conditions(cfg: EvaluateConfig) -> list[dict]:
    starts = cfg.starts
    scene = SCENES[starts.env_id]
    if starts.initial_conditions:
        ics = load_initial_conditions(starts.initial_conditions, scene)
        for i, ic in enumerate(ics):
            scene.validate_start(ic, f"initial condition {i}")
        return ics
    return [
        ic.to_json()
        for ic in sample_starts(scene, cfg.num_initial_conditions, seed=starts.seed, sampler=starts.sampler)
    ]
