"""`gcs-push improve`'s settings, nested as LeRobot nests its configs: the base, a round, validation, the
stop rule; each default is a lesson of the eleven hand-run rounds (experiments/active_data/README.md)."""

from __future__ import annotations

import os
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path

from lerobot_gcs_push.artifacts.checkpoints import is_pretrained_dir
from lerobot_gcs_push.artifacts.shipped import shipped_path
from lerobot_gcs_push.episodes.workers import FanOut
from lerobot_gcs_push.registration import ENV_ID

STAGES = ("rollouts", "collect", "merge", "finetune", "validation", "decision")


@dataclass
class BaseConfig:
    """From nothing: the demonstrations and first training before round 1 (skipped for an existing policy)."""

    # GCS demonstrations; every round's merge keeps them (1000: the base of every merge since round 1).
    episodes: int = 1000
    # Their starts (generate's --sampler and --seed), not a nested StartsConfig: the run's env_id serves the
    # rounds too, and the base takes neither disturbances nor initial_conditions (`lists` are replayed).
    sampler: str = "sobol"
    seed: int = 0
    # Steps of batch 32 from scratch: the CPU preset's own schedule, not yet tested as a base for rounds
    # (experiments/improve/from_nothing measures it). On demonstrations alone run 6 reached 0.71 after
    # 9500 steps and run 7 0.91 after 18,500; the rounds' own states are meant to do the rest.
    steps: int = 8000
    # Peak learning rate; None keeps the preset's (2e-4).
    lr: float | None = None
    # Replay lists of the demonstrations an existing policy was trained on (a dataset's
    # meta/gcs_push_replay.json; gym-pusht's pool: experiments/pusht/demos/seed480*.json), in order: every
    # merge then holds the first `episodes` of them, replayed with no planning, instead of `episodes` new
    # ones planned from `sampler` and `seed` (a fresh machine rebuilds 1000 in minutes, not an hour).
    lists: list[str] = field(default_factory=list)


@dataclass
class RoundConfig:
    # Rollouts of the current policy, 1 run each, with and without disturbances: 80 hard (20 of each
    # family) and 20 uniform initial conditions, rounds 10 and 11's mix (rounds 1-9 showed the hard
    # families are where a cloned policy fails; uniform ones keep the common case in the data).
    hard: int = 80
    uniform: int = 20
    disturbances: bool = True
    # Simulated seconds before a rollout counts as failed (every evaluation since run 7); None: the env's
    # own (gym-pusht's 300 steps, 30 s).
    timeout_s: float | None = 60.0
    # Branch from chunks above this regret in successful runs too (rounds 10 and 11: a success's
    # 0.25-0.5 m detours are where the extra time goes; round 11 shortened the path with it).
    large_regret_m: float = 0.25
    # Branch states at most per rollout, spread over its time (collect's `max_per_run`): each is a whole
    # expert episode to label. The box's rounds took 12; gym-pusht's take 4 (configs/improve/pusht.json), so
    # that labelling 100 mostly failed rollouts (about 400 episodes, 40 % of the base's) fits a session.
    max_per_run: int = 12
    # Fine-tuning from the current weights: 2500 steps (round 10's 1500 lengthened the path, round 10b's
    # 2500 on the same data shortened it, round 10c's 2000 more did not help), peak lr 1e-4 (run 7: a warm
    # restart at the preset's 2e-4 first undoes what was learned), bf16 on CPU.
    steps: int = 2500
    lr: float = 1e-4


@dataclass
class ValidationConfig:
    # Fresh initial conditions for every decision, none of them used before (round 4's fall on a set
    # that had chosen several times did not repeat on a fresh one): 40 hard and 40 uniform, 3 runs each,
    # without disturbances, as the validation sets of rounds 6-11.
    hard: int = 40
    uniform: int = 40
    runs: int = 3
    # The candidate ships with `margin` more successes in the 240 runs (round 10 shipped on one and lost
    # every test set after), or within the margin with a mean success time `time_gain` lower (round 10b).
    margin: int = 3
    time_gain: float = 0.05
    # Where neither policy has a success (gym-pusht so far), ship on final coverage: the candidate's mean this
    # much higher and higher on more paired starts than lower (`shipping.coverage_decision`). None: never.
    coverage_margin: float | None = None


@dataclass
class StopConfig:
    # Targets (issue 33's), judged on each round's rollouts: fresh conditions that no choice has used,
    # unlike the validation set that chose the policy. Success on each sampler, with and without
    # disturbances, and mean success time over GCS's on the same conditions.
    hard_success: float = 0.95
    uniform_success: float = 0.98
    time_ratio: float = 1.15
    # Budgets: rounds, and wall hours summed over every stage (across machines and resumes; a kill
    # loses at most the last 30 s of a stage's count). 8 h: the target from nothing.
    max_rounds: int = 12
    max_hours: float = 8.0


@dataclass
class ImproveConfig(FanOut):
    # The policy folder to improve in place: a LeRobot pretrained_model directory, or a path where none is
    # yet (then from nothing: base demonstrations and a first training). Winners are written here.
    policy: str = "outputs/improve/policy"
    # A pretrained_model folder the rounds start from: copied into `policy` (fp16) while that holds none and
    # no round has shipped, so a committed base (experiments/pusht/base_1000/partial) is neither moved nor
    # copied in the repository; on a fresh machine the copy is made again. None: `policy` or from nothing.
    from_policy: str | None = None
    # Small, committable state: the state file, branch-state lists, pending weights.
    state_dir: str = "outputs/improve/state"
    # Large, rebuilt on demand: rollouts, validation runs, training checkpoints.
    work_dir: str = "outputs/improve/work"
    # Prefix of the LeRobot dataset ids in the local cache ($HF_LEROBOT_HOME/local/<name>_...).
    name: str = "improve"
    # Branch-state lists (`collect`'s, e.g. experiments/active_data/round*/branch_states.json) of rounds
    # run before this one, rebuilt and merged with every round's: keep every round's states (round 2
    # dropped round 1's and forgot what it taught). Needed to go on from the shipped policy.
    prior_states: list[str] = field(default_factory=list)
    # The task; a field so that another registered env (a rotating slider) runs the same loop.
    env_id: str = ENV_ID
    # The sampler of the hard rollouts and validation sets. hard_v2 adds to the hard families the one the
    # shipped policy's unseen sets found weak (box and finger in opposite corners, 1 success in 3) and
    # fingers far from the box; runs begun before it existed used `hard`.
    hard_sampler: str = "hard_v2"
    # The LeRobot preset that first training and fine-tunes start from.
    train_config: str = "configs/policy/diffusion_cpu.json"
    # Seeds: round k's rollouts use seed + 10k (hard) and + 1 (uniform), its validation sets + 5 and + 6,
    # its training + 9. 6000 and up is clear of every set used so far (test sets 1000-3000, the rounds'
    # rollouts 4000-4091, validation and unseen sets 5001-5027); another run on the same policy needs
    # another seed for its sets to be fresh.
    seed: int = 6000
    # Torch device of training and rollouts: cpu, cuda, cuda:N or mps.
    device: str = "cpu"
    # Training steps between checkpoints: what a kill can cost, and how often the resumable copy is made.
    save_freq: int = 500
    base: BaseConfig = field(default_factory=BaseConfig)
    round: RoundConfig = field(default_factory=RoundConfig)
    validation: ValidationConfig = field(default_factory=ValidationConfig)
    stop: StopConfig = field(default_factory=StopConfig)
    # Stop after the named stage (base.demonstrations, base.train, or rK.<stage>), for a look before the
    # rest; a re-run continues.
    stop_after: str | None = None

    def __post_init__(self) -> None:
        from lerobot_gcs_push.episodes.rollout import check_env_id
        from lerobot_gcs_push.evaluation import check_device
        from lerobot_gcs_push.registration import SCENES
        from lerobot_gcs_push.scene import check_sampler, check_seed

        scene = SCENES[check_env_id(self.env_id)]
        # A slider that turns has no hard families (they are the box's) and gym-pusht no disturbances:
        # configs/improve/pusht.json sets its rounds up.
        if not scene.kind.hard_starts and (self.round.hard or self.validation.hard):
            raise ValueError(
                f"{self.env_id} has no hard families (they are the box's): set round.hard=0 and validation.hard=0 "
                "(its starts are round.uniform and validation.uniform; see configs/improve/pusht.json)"
            )
        if not scene.kind.disturbable and self.round.disturbances:
            raise ValueError(f"{self.env_id} has no disturbances: set round.disturbances=false")
        check_sampler(self.hard_sampler)
        check_seed(self.seed)
        check_seed(self.base.seed, "base.seed")
        self.train_config = shipped_path(self.train_config)  # the shipped preset, wherever this runs
        # One spelling of each path: the policy's is also its label in every evaluation record.
        for name in ("policy", "state_dir", "work_dir", "train_config"):
            setattr(self, name, _canonical(getattr(self, name)))
        self.prior_states = [_canonical(p) for p in self.prior_states]
        if not Path(self.train_config).is_file():
            raise FileNotFoundError(f"train_config {self.train_config!r} does not exist")
        for p in self.prior_states:
            if not Path(p).is_file():
                raise FileNotFoundError(f"prior_states: {p!r} does not exist")
        self.base.lists = [_canonical(p) for p in self.base.lists]
        for p in self.base.lists:
            if not Path(p).is_file():
                raise FileNotFoundError(f"base.lists: {p!r} does not exist")
        if self.from_policy is not None:
            self.from_policy = _canonical(self.from_policy)
            if not is_pretrained_dir(self.from_policy):
                raise ValueError(f"from_policy {self.from_policy!r} is not a LeRobot pretrained_model directory")
        if Path(self.policy).exists() and not is_pretrained_dir(self.policy):
            raise ValueError(f"{self.policy} exists but is not a LeRobot pretrained_model directory")
        check_device(self.device)
        self.check_fan_out()
        counts = {
            "round.hard": self.round.hard,
            "round.uniform": self.round.uniform,
            "validation.hard": self.validation.hard,
            "validation.uniform": self.validation.uniform,
            "stop.max_rounds": self.stop.max_rounds,
        }
        positive = {
            "round.hard + round.uniform": self.round.hard + self.round.uniform,
            "round.max_per_run": self.round.max_per_run,
            "validation.hard + validation.uniform": self.validation.hard + self.validation.uniform,
            "base.episodes": self.base.episodes,
            "base.steps": self.base.steps,
            "round.steps": self.round.steps,
            "validation.runs": self.validation.runs,
            "validation.margin": self.validation.margin,
            "save_freq": self.save_freq,
            "round.timeout_s": self.round.timeout_s if self.round.timeout_s is not None else 1.0,
            "round.lr": self.round.lr,
            "stop.max_hours": self.stop.max_hours,
            "stop.time_ratio": self.stop.time_ratio,
        }
        for what, n in counts.items():
            if n < 0:
                raise ValueError(f"{what} must be >= 0, got {n}")
        for what, n in positive.items():
            if not n > 0:
                raise ValueError(f"{what} must be positive, got {n}")
        if self.base.lr is not None and not self.base.lr > 0:
            raise ValueError(f"base.lr must be positive, got {self.base.lr}")
        if not 0.0 <= self.validation.time_gain < 1.0:
            raise ValueError(f"validation.time_gain must be a fraction in [0, 1), got {self.validation.time_gain}")
        cm = self.validation.coverage_margin
        if cm is not None and not 0.0 < cm < 1.0:
            raise ValueError(f"validation.coverage_margin must be a fraction in (0, 1), or None, got {cm}")
        if cm is not None and not scene.kind.records_coverage:
            raise ValueError(
                f"validation.coverage_margin needs a slider that turns: {self.env_id}'s runs record no coverage"
            )
        stages = "|".join(STAGES)
        if self.stop_after and not re.fullmatch(
            rf"base\.(demonstrations|train)|r[1-9][0-9]*\.({stages})", self.stop_after
        ):
            raise ValueError(
                f"stop_after {self.stop_after!r}: name a stage, base.demonstrations, base.train or rK.<stage> "
                f"with <stage> one of {', '.join(STAGES)}"
            )


def _canonical(path: str) -> str:
    """Relative to the working directory when inside it (the repository, whose clones differ in
    location), else absolute."""
    p = os.path.abspath(path)
    rel = os.path.relpath(p)
    return p if rel.startswith("..") else rel


# What a state file made before a field existed ran with: resumed, it must keep it (or be refused).
_BEFORE_FIELDS = {"hard_sampler": "hard"}


def _settings(cfg: ImproveConfig) -> dict:
    skip = ("workers", "backend", "ray_address", "device", "stop", "stop_after", "state_dir", "work_dir", "save_freq")
    return {k: v for k, v in asdict(cfg).items() if k not in skip}
