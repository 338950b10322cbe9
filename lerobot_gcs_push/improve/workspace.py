"""What every stage of an improve run shares: its settings (held to the state file's on a resume), its state,
folders, dataset names and seeds, the expert it is timed against, and the training call."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

from lerobot_gcs_push.artifacts.checkpoints import export_policy
from lerobot_gcs_push.improve.config import _BEFORE_FIELDS, ImproveConfig, _canonical, _settings
from lerobot_gcs_push.improve.state import STATE_FILE, State
from lerobot_gcs_push.settings import changed, describe


class Workspace:
    def __init__(self, cfg: ImproveConfig):
        from lerobot_gcs_push.generate import lerobot_home

        self.cfg = cfg
        self.state_dir, self.work = Path(cfg.state_dir), Path(cfg.work_dir)
        self.state = State.load(self.state_dir / STATE_FILE)
        # The settings that decide what a stage computes may not change under a resumed run. Compared leaf
        # by leaf. A field that a later version added is read, for an older state file, as the value that
        # file's run used (`_BEFORE_FIELDS`), so a resume that would change it is refused.
        stored = dict(self.state.settings)
        for k in ("policy", "train_config"):
            if k in stored:
                stored[k] = _canonical(stored[k])
        diff = changed(stored, _settings(cfg), _BEFORE_FIELDS, only_held=True) if stored else {}
        if diff:
            raise ValueError(
                f"{self.state.path} was made with other settings ({describe(diff)}): use the same ones, "
                "or another --state_dir"
            )
        self.state.settings = _settings(cfg)
        self.state.stop = asdict(cfg.stop)
        self.home = lerobot_home()

    def stage(self, name: str, run: Callable[[], None]) -> None:
        """Run a stage unless done (`State.run_stage`); `stop_after` ends the run after it."""
        self.state.run_stage(name, run, self.cfg.stop_after)

    def repo(self, what: str) -> str:
        return f"local/{self.cfg.name}_{what}"

    def has(self, what: str) -> bool:
        return (self.home / self.repo(what) / "meta" / "info.json").is_file()

    def seed(self, k: int, offset: int) -> int:
        return self.cfg.seed + 10 * k + offset

    @property
    def expert(self) -> str:
        """The GCS expert the rounds time the policy against: the paper's open-loop plan for the box; closed
        loop for a slider that turns, whose open-loop plans reach coverage on 1 start of 20 (contact/)."""
        from lerobot_gcs_push.registration import SCENES

        return f"gcs-{SCENES[self.cfg.env_id].kind.default_expert}"

    def evaluate(self, policies: list[str], sampler: str, seed: int, n: int, runs: int, out: Path,
                 disturbances: bool = False) -> None:  # fmt: skip
        """`gcs-push evaluate` of `policies` on n starts, with the run's fan-out, device and timeout."""
        from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate

        evaluate(
            EvaluateConfig(
                policies=policies,
                env_id=self.cfg.env_id,
                sampler=sampler,
                seed=seed,
                num_initial_conditions=n,
                runs=runs,
                disturbances=disturbances,
                timeout_s=self.cfg.round.timeout_s,
                **self.cfg.fan_out(),
                videos=0,
                device=self.cfg.device,
                output_dir=str(out),
            )
        )

    def train_to(
        self, dst: Path, *, repo_id: str, steps: int, seed: int, lr: float | None, init: str | None, job: str
    ) -> None:
        """lerobot-train (resumable, its partial in the state folder), the result exported to `dst`."""
        from lerobot_gcs_push.improve.training import TrainJob, train

        final = train(
            TrainJob(
                config_path=self.cfg.train_config,
                dataset_repo_id=repo_id,
                output_dir=self.work / "train" / job,
                steps=steps,
                seed=seed,
                init_policy=init,
                save_freq=self.cfg.save_freq,
                lr=lr,
                device=self.cfg.device,
                partial=self.state_dir / f"{job}.partial",
            ),
            progress_desc=f"{job} training",
        )
        export_policy(final, dst, overwrite=True)
        shutil.rmtree(self.state_dir / f"{job}.partial", ignore_errors=True)


class Stage:
    """One step of a run; `run` (base: `dataset` and `train`) is what the state file records as done."""

    def __init__(self, ws: Workspace):
        self.ws = ws

    @property
    def cfg(self) -> ImproveConfig:
        return self.ws.cfg

    @property
    def state(self) -> State:
        return self.ws.state
