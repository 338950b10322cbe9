"""What `gcs-push generate` makes: its settings (`GenerateConfig`) and where the dataset lies."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, fields
from pathlib import Path

from lerobot_gcs_push.episodes.workers import FanOut
from lerobot_gcs_push.generate.hub import check_online
from lerobot_gcs_push.generate.replay import ReplayActions
from lerobot_gcs_push.planning.factory import EXPERT_DEFAULTS, REPLAY, ExpertConfig
from lerobot_gcs_push.registration import ENV_ID, SCENES
from lerobot_gcs_push.scene import Disturbances, Scene, load_initial_conditions
from lerobot_gcs_push.scene.options import StartsConfig
from lerobot_gcs_push.settings import Shared, flat_options, flat_settings

EPISODES_META = "meta/gcs_push_episodes.jsonl"
SETTINGS_META = "meta/gcs_push_settings.json"  # the settings a finished dataset was made with (see _finished)
# Settings a dataset or work folder made before the field existed holds implicitly (the expert's beyond its
# mode and method: recorded only where set, `recorded_settings`).
_IMPLICIT_SETTINGS = {"env_id": ENV_ID, **EXPERT_DEFAULTS}


@dataclass
class OutputConfig(Shared):
    """The dataset a command writes: the one definition of `repo_id`, `root`, `overwrite` and `resume`, nested
    as `output` in `generate`, `collect` and `demo` (their flat names work too: `--repo_id`, `--output.repo_id`)."""

    # LeRobot dataset id, "owner/name". Default: the command's (local/gcs_push_box for generate,
    # local/gcs_push_active for collect, by --protocol for demo).
    repo_id: str | None = None
    # Dataset folder; default: $HF_LEROBOT_HOME/<repo_id>, where LeRobot looks first.
    root: str | None = None
    # Replace an existing dataset (and an interrupted run's work).
    overwrite: bool = False
    # Continue an interrupted run, keeping its finished episodes (and shards, and labelled states).
    resume: bool = False

    def __post_init__(self) -> None:
        if self.overwrite and self.resume:
            raise ValueError("choose one of overwrite and resume, not both")
        if self.repo_id is not None and "/" not in self.repo_id:
            raise ValueError(f"repo_id must look like 'owner/name', got {self.repo_id!r}")

    def fill(self, repo_id: str) -> None:
        """The command's default id where none was given."""
        self.repo_id = self.repo_id or repo_id

    def path(self) -> Path:
        """The dataset's folder."""
        return Path(self.root).expanduser() if self.root else lerobot_home() / self.repo_id


@flat_options
@dataclass
class GenerateConfig(FanOut):
    # Where the episodes start: --env_id, --sampler, --seed, --disturbances, --initial_conditions
    # (`--starts.seed` works too): an --initial_conditions list's entries are tried once each, in order,
    # until `episodes` succeed, and failures are left out.
    starts: StartsConfig = field(default_factory=StartsConfig)
    # The GCS expert that acts: --expert (its mode), --method, and its replanning settings
    # (--expert.replan_tolerance, --expert.commands=steer for gym-pusht ...).
    expert: ExpertConfig = field(default_factory=ExpertConfig)
    # The dataset written: --repo_id, --root, --overwrite, --resume.
    output: OutputConfig = field(default_factory=OutputConfig)
    # Successful demonstrations to write (failed rollouts are left out). Default: 100 from the sampler,
    # or as many as --initial_conditions has entries.
    episodes: int | None = None
    # Stop once this many frames are written (an equal-cost control); episodes is then an upper bound.
    frames: int | None = None
    # Env steps (frames) per simulated second.
    fps: int = Scene.fps
    # Observation image side, pixels.
    image_size: int = 96
    # gym-pusht only: pixels_agent_pos (lerobot/pusht's features: the image) or environment_state_agent_pos
    # (the T's 8 keypoints as observation.environment_state in its place, for keypoint policies), as
    # LeRobot's `--env.obs_type`. The Drake scenes write pixels_agent_pos.
    obs_type: str = "pixels_agent_pos"
    # gym-pusht only: DART's noise (Laskey et al. 2017), the std in px of a Gaussian draw added to each
    # target the env runs, while the dataset records the expert's own target; the replay list holds both
    # and the draws' seed. 0: none.
    command_noise_px: float = 0.0
    # gym-pusht only: the demonstration goes on past gym-pusht's success (coverage 0.95) until the T covers
    # this share of the goal, or finish_frames steps after the first success (then at the next success):
    # a policy that imitates the finish roughly still lands past the threshold (`pusht.finish`). None:
    # gym-pusht's own end. The replay list keeps each episode's setting.
    finish_coverage: float | None = None
    finish_frames: int = 20
    # Simulated seconds before a rollout counts as failed. Default: the env's (500 s, the paper's; 30 s, that
    # is 300 steps, for gym-pusht, so its episodes succeed within gym-pusht's own limit).
    max_sim_time_s: float | None = None
    # Upload with LeRobot's push_to_hub (needs the network and a token).
    push_to_hub: bool = False
    # Show a progress bar.
    progress: bool = True
    # Give up after episodes * factor initial conditions.
    max_attempts_factor: float = 2.0
    # Initial conditions per job, at most; each job writes one shard, merged at the end.
    shard_size: int = 10

    def __post_init__(self) -> None:
        starts, expert, env_id = self.starts, self.expert, self.starts.env_id
        starts.fill(sampler="sobol", seed=0)
        self.output.fill("local/gcs_push_box")
        scene = SCENES[env_id]
        ics = load_initial_conditions(starts.initial_conditions, scene) if starts.initial_conditions else None
        if self.episodes is None:
            self.episodes = len(ics) if ics else 100
        if self.episodes < 1:
            raise ValueError(f"episodes must be >= 1, got {self.episodes}")
        self.check_fan_out()
        kind = scene.kind
        replayable = bool(ics) and all("actions" in ic for ic in ics)
        if expert.mode is None:
            expert.mode = REPLAY if replayable else kind.default_expert
        if expert.mode == REPLAY:
            if not ics:
                raise ValueError("--expert=replay runs the actions of an --initial_conditions list: pass one")
            missing = next((i for i, ic in enumerate(ics) if "actions" not in ic), None)
            if missing is not None:
                raise ValueError(f'--expert=replay: initial condition {missing} has no "actions"')
            for i, ic in enumerate(ics):  # refused here, not by a worker midway through the run
                try:
                    ReplayActions().load(ic["actions"])
                except (ValueError, TypeError) as err:
                    raise ValueError(f"--expert=replay: initial condition {i}: {err}") from None
            if starts.disturbances:
                raise ValueError("--expert=replay repeats undisturbed episodes: drop --disturbances")
            if self.command_noise_px:
                raise ValueError("--expert=replay repeats each entry's own command noise: drop --command_noise_px")
            if self.finish_coverage is not None:
                raise ValueError("--expert=replay ends each entry where its 'finish' did: drop --finish_coverage")
            for i, ic in enumerate(ics):
                if "command_noise" in ic and "labels" not in ic:
                    raise ValueError(f'--expert=replay: initial condition {i} has "command_noise" but no "labels"')
        expert.check_env(env_id)
        if self.max_sim_time_s is None:
            self.max_sim_time_s = scene.timeout_s
        if self.image_size < 1:
            raise ValueError(f"image_size must be >= 1, got {self.image_size}")
        if scene.kind.lerobot_pusht_data:
            from lerobot_gcs_push.pusht.dataset import check_obs_type

            check_obs_type(self.obs_type)
            if not (math.isfinite(self.command_noise_px) and self.command_noise_px >= 0):
                raise ValueError(f"command_noise_px must be a finite std >= 0 px, got {self.command_noise_px}")
            if self.finish_coverage is not None:
                from lerobot_gcs_push.pusht.finish import Finish

                Finish(self.finish_coverage, self.finish_frames)  # refused here, with its reason
        elif self.command_noise_px:
            raise ValueError(f"command_noise_px is gym-pusht's (its targets are px); {env_id} takes none")
        elif self.finish_coverage is not None:
            raise ValueError(f"finish_coverage is gym-pusht's (its success is coverage > 0.95); {env_id} takes none")
        elif self.obs_type != "pixels_agent_pos":
            raise ValueError(f"{env_id} writes obs_type pixels_agent_pos only, got {self.obs_type!r}")
        if not 0 < self.max_sim_time_s < float("inf"):  # inf would roll a failing start out forever
            raise ValueError(f"max_sim_time_s must be positive and finite, got {self.max_sim_time_s}")
        per_s = round(1 / Disturbances.tick_s)
        if self.fps <= 0 or per_s % self.fps:  # an env step is a whole number of disturbance ticks
            raise ValueError(f"fps must divide {per_s}, got {self.fps}")
        if ics:  # refused before any worker starts, each entry named
            for i, ic in enumerate(ics):
                scene.validate_start(ic, f"initial condition {i}")
        if self.frames is not None and self.frames < 1:
            raise ValueError(f"frames must be >= 1, got {self.frames}")
        if self.shard_size < 1:
            raise ValueError(f"shard_size must be >= 1, got {self.shard_size}")
        if self.push_to_hub:  # refused now, not after the whole generation
            check_online()


def recorded_settings(cfg: GenerateConfig) -> dict:
    """What a dataset and its work folder record it was made with (its settings under their flat names,
    `settings.flat_settings`); where and how the jobs run may change on --resume, what they compute may not.
    The expert's settings beyond its mode and method, and the finish, only where set: a dataset made without
    them records what it always did (`_IMPLICIT_SETTINGS` holds their defaults for the comparison)."""
    skip = (
        *(f.name for f in fields(ExpertConfig)),
        "workers",
        "overwrite",
        "resume",
        "progress",
        "push_to_hub",
        "episodes",
        "root",
        "backend",
        "ray_address",
        "shard_size",
    )
    flat = flat_settings(cfg)
    out = {k: v for k, v in flat.items() if k not in (*skip, "finish_coverage", "finish_frames")}
    if cfg.finish_coverage is not None:  # as the expert's: only where set, so older folders resume
        out |= {"finish_coverage": cfg.finish_coverage, "finish_frames": cfg.finish_frames}
    return out | {"method": cfg.expert.method} | cfg.expert.non_defaults()


def lerobot_home() -> Path:
    env = os.environ.get("HF_LEROBOT_HOME")
    if env:
        return Path(env).expanduser()
    from lerobot.utils.constants import HF_LEROBOT_HOME

    return Path(HF_LEROBOT_HOME)


def dataset_root(cfg: GenerateConfig) -> Path:
    return cfg.output.path()
