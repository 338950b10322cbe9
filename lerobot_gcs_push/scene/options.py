"""Where a command's episodes start (`StartsConfig`): the one definition of `env_id`, `sampler`, `seed`,
`disturbances` and `initial_conditions`, nested in `generate` and `evaluate` as LeRobot nests its configs, and in
`plan` (its env and its file of starts; it refuses the rest). Its options keep their flat names (`--seed`, as well
as `--starts.seed`: `settings.Shared`).

Not imported by `scene/__init__`: it names the registered envs, and `registration` imports the scene."""

from __future__ import annotations

from dataclasses import dataclass

from lerobot_gcs_push.registration import ENV_ID
from lerobot_gcs_push.scene.starts import check_sampler, check_seed
from lerobot_gcs_push.settings import Shared


@dataclass
class StartsConfig(Shared):
    # The registered env: GcsPushBox-v0 (the box that cannot turn), GcsPushBoxSE2-v0 or GcsPushT-v0 (rotating
    # sliders, whose GCS experts plan through contact: --method=relaxation only; they succeed by coverage),
    # or gym_pusht/PushT-v0 (gym-pusht's own env; generate writes it in lerobot/pusht's format, pusht/dataset.py).
    env_id: str = ENV_ID
    # Initial conditions: sobol (space-filling), uniform (the paper's, which samples its evaluation set from
    # the training distribution), hard (the named set of configurations a cloned policy gets wrong) or
    # hard_v2 (adds fingers far from the box, opposite corners among them); see scene/starts.py.
    # Default: sobol for generate, uniform for evaluate.
    sampler: str | None = None
    # The i-th initial condition and episode depend only on (seed, i); evaluate also seeds every run's env
    # with it (disturbances, diffusion noise). Default: 0 for generate; for evaluate the named set of the
    # sampler, 1000 (the paper's protocol set, uniform) or 3000 (the hard set).
    seed: int | None = None
    # The paper's random pushes on the box: generate records under them (use the closed-loop expert);
    # evaluate also runs every closed-loop or learned policy under them.
    disturbances: bool = False
    # A JSON list of {"box": [x, y], "finger": [x, y]} (and "heading" for a rotating slider) to use instead
    # of the sampler, in order (e.g. the policy states that `gcs-push collect` picked).
    initial_conditions: str | None = None

    def __post_init__(self) -> None:
        from lerobot_gcs_push.episodes.rollout import check_env_id

        check_env_id(self.env_id)
        if self.sampler is not None:
            check_sampler(self.sampler)
        if self.seed is not None:
            check_seed(self.seed)

    def fill(self, sampler: str, seed=None) -> None:
        """The command's defaults where none was given (`seed` may be a function of the sampler)."""
        self.sampler = self.sampler if self.sampler is not None else sampler
        if self.seed is None:
            self.seed = check_seed(seed(self.sampler) if callable(seed) else seed)
