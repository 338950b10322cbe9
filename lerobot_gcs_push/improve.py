"""`gcs-push improve`: rounds of active data, from a policy folder or from nothing, until the policy is robust.

A round: roll the current policy out (hard and uniform initial conditions, with and without disturbances,
on seeds no evaluation set uses) -> `collect` branch states labelled by the expert -> merge them with the
base demonstrations and every earlier round's states (LeRobot's aggregation) -> fine-tune the current
weights -> a fresh validation set, decided by the shipping rule (`shipping.py`) -> ship into the policy
folder, or keep the old one. From nothing, base demonstrations and a first training come before round 1.
It stops when the shipped policy meets the targets on its validation set, or on a budget.

Every stage resumes after `kill -9`. What another machine needs to resume is in `state_dir`, small: the
state file (stages done, their wall times, each round's scores and decision), each round's branch-state
list (its dataset is rebuilt from it), and the weights a pending stage needs (the current policy when it
lives there, the candidate awaiting its validation, the newest checkpoint of an unfinished training).
Commit that folder and re-run the same command; the datasets and rollouts in `work_dir` are made again.

Each default is a lesson of the eleven hand-run rounds (experiments/active_data/README.md), named beside it.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import shutil
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from lerobot_gcs_push.checkpoints import export_policy, is_pretrained_dir
from lerobot_gcs_push.files import atomic_path

STATE_FILE = "state.json"


@dataclass
class BaseConfig:
    """From nothing: the demonstrations and first training before round 1 (skipped for an existing policy)."""

    # GCS demonstrations; every round's merge keeps them (1000: the base of every merge since round 1).
    episodes: int = 1000
    sampler: str = "sobol"
    seed: int = 0
    # Steps of batch 32 from scratch: the CPU preset's own schedule. Run 6 reached 0.71 after 9500 steps
    # on demonstrations alone and run 7 0.91 after 18,500; the rounds' states do more per step.
    steps: int = 8000
    # Peak learning rate; None keeps the preset's (2e-4).
    lr: float | None = None


@dataclass
class RoundConfig:
    # Rollouts of the current policy, 1 run each, with and without disturbances: 80 hard (20 of each
    # family) and 20 uniform initial conditions, rounds 10 and 11's mix (rounds 1-9 showed the hard
    # families are where a cloned policy fails; uniform ones keep the common case in the data).
    hard: int = 80
    uniform: int = 20
    disturbances: bool = True
    # Simulated seconds before a rollout counts as failed (every evaluation since run 7).
    timeout_s: float = 60.0
    # Branch from chunks above this regret in successful runs too (round 10: a success's 0.25-0.5 m
    # detours are where the extra time went).
    large_regret_m: float = 0.25
    # Fine-tuning from the current weights: 2500 steps (round 10's 1500 lengthened the path, round 10b's
    # 2500 on the same data shortened it, round 10c's 2000 more did not help), peak lr 1e-4 (run 7: a warm
    # restart at the preset's 2e-4 first undoes what was learned), bf16 on CPU.
    steps: int = 2500
    lr: float = 1e-4


@dataclass
class ValidationConfig:
    # Fresh initial conditions for every decision, none of them used before (round 4's fall on a set
    # that had chosen several times did not repeat on a fresh one): 40 hard and 40 uniform, 3 runs each,
    # without disturbances, as the validation sets of rounds 5-11.
    hard: int = 40
    uniform: int = 40
    runs: int = 3
    # The candidate ships with `margin` more successes in the 240 runs (round 10 shipped on one and lost
    # every test set after), or within the margin with a mean success time `time_gain` lower (round 10b).
    margin: int = 3
    time_gain: float = 0.05


@dataclass
class StopConfig:
    # Targets on the shipped policy's latest validation set (without disturbances).
    hard_success: float = 0.95
    uniform_success: float = 0.98
    # Budgets: rounds, and wall hours summed over every stage (across machines and resumes).
    max_rounds: int = 12
    max_hours: float = 8.0


@dataclass
class ImproveConfig:
    # The policy folder to improve in place: a LeRobot pretrained_model directory, or a path where none is
    # yet (then from nothing: base demonstrations and a first training). Winners are written here.
    policy: str = "outputs/improve/policy"
    # Small, committable state: the state file, branch-state lists, pending weights.
    state_dir: str = "outputs/improve/state"
    # Large, rebuilt on demand: datasets' staging, rollouts, validation runs, training checkpoints.
    work_dir: str = "outputs/improve/work"
    # Prefix of the LeRobot dataset ids in the local cache ($HF_LEROBOT_HOME/local/<name>_...).
    name: str = "improve"
    # The task; a field so that another registered env (a rotating slider) runs the same loop.
    env_id: str = "GcsPushBox-v0"
    # The LeRobot preset that first training and fine-tunes start from.
    train_config: str = "configs/policy/diffusion_cpu.json"
    # Seeds: round k's rollouts use seed + 10k (hard) and + 1 (uniform), its validation sets + 5 and + 6,
    # its training + 9. 6000 and up is clear of every set used so far (test sets 1000-3000, the rounds'
    # rollouts 4000-4091, validation and unseen sets 5001-5027).
    seed: int = 6000
    workers: int = 2
    device: str = "cpu"
    # Training steps between checkpoints: what a kill can cost, and how often the resumable copy is made.
    save_freq: int = 500
    base: BaseConfig = field(default_factory=BaseConfig)
    round: RoundConfig = field(default_factory=RoundConfig)
    validation: ValidationConfig = field(default_factory=ValidationConfig)
    stop: StopConfig = field(default_factory=StopConfig)
    # Stop after the named stage (e.g. r1.collect), for a look before the rest; a re-run continues.
    stop_after: str | None = None

    def __post_init__(self) -> None:
        if self.env_id != "GcsPushBox-v0":
            raise ValueError(
                f"env_id {self.env_id!r}: rounds need the env's GCS expert, which only GcsPushBox-v0 has yet"
            )
        if not Path(self.train_config).is_file():
            raise FileNotFoundError(f"train_config {self.train_config!r} does not exist")
        if Path(self.policy).exists() and not is_pretrained_dir(self.policy):
            raise ValueError(f"{self.policy} exists but is not a LeRobot pretrained_model directory")
        for what, n in (
            ("round.hard + round.uniform", self.round.hard + self.round.uniform),
            ("validation.hard + validation.uniform", self.validation.hard + self.validation.uniform),
            ("base.episodes", self.base.episodes),
            ("round.steps", self.round.steps),
            ("base.steps", self.base.steps),
            ("validation.runs", self.validation.runs),
            ("workers", self.workers),
        ):
            if n < 1:
                raise ValueError(f"{what} must be >= 1, got {n}")
        if self.stop.max_rounds < 0 or not self.stop.max_hours > 0:
            raise ValueError("stop.max_rounds must be >= 0 and stop.max_hours positive")


def _settings(cfg: ImproveConfig) -> dict:
    skip = ("workers", "device", "stop", "stop_after", "state_dir", "work_dir", "save_freq")
    return _settings_of({k: v for k, v in asdict(cfg).items() if k not in skip})


def _settings_of(settings: dict) -> dict:
    # Paths compare as seen from the working directory, however they were typed.
    return {
        k: os.path.relpath(os.path.abspath(v)) if k in ("policy", "train_config") else v for k, v in settings.items()
    }


class StopRequested(Exception):
    """`stop_after` reached: the state is saved and a re-run continues."""


@dataclass
class State:
    path: Path
    stages: dict[str, dict] = field(default_factory=dict)  # name -> {"done", "wall_s", "finished_at"}
    rounds: list[dict] = field(default_factory=list)  # per round: scores, decision, hours at its end
    settings: dict = field(default_factory=dict)

    @classmethod
    def load(cls, path: Path) -> State:
        if not path.is_file():
            return cls(path)
        data = json.loads(path.read_text())
        return cls(path, data["stages"], data["rounds"], data.get("settings", {}))

    def save(self) -> None:
        with atomic_path(self.path) as tmp:
            tmp.write_text(
                json.dumps({"settings": self.settings, "stages": self.stages, "rounds": self.rounds}, indent=1)
            )

    @property
    def hours(self) -> float:
        return sum(s.get("wall_s", 0.0) for s in self.stages.values()) / 3600

    def done(self, name: str) -> bool:
        return bool(self.stages.get(name, {}).get("done"))


class Improver:
    def __init__(self, cfg: ImproveConfig):
        from lerobot_gcs_push.dataset import lerobot_home

        self.cfg = cfg
        self.state_dir, self.work = Path(cfg.state_dir), Path(cfg.work_dir)
        self.state = State.load(self.state_dir / STATE_FILE)
        # The settings that decide what a stage computes may not change under a resumed run. Fields that
        # a later version added are absent from an older state file and compare as equal.
        wanted = _settings(cfg)
        stored = _settings_of(self.state.settings)
        diff = sorted(k for k in stored if k in wanted and stored[k] != wanted[k])
        if diff:
            raise ValueError(
                f"{self.state.path} was made with other settings ({', '.join(diff)}): use the same ones, "
                "or another --state_dir"
            )
        self.state.settings = wanted
        self.home = lerobot_home()

    # -- the bookkeeping every stage shares ---------------------------------------------------------

    def stage(self, name: str, run: Callable[[], None]) -> None:
        """Run a stage unless done; its wall time counts toward the budget also when it is killed
        (a heartbeat adds the seconds spent so far), so hours add up across resumes and machines."""
        if self.state.done(name):
            return
        rec = self.state.stages.setdefault(name, {"done": False, "wall_s": 0.0})
        self.state.save()  # a stage killed in its first seconds is still on record as begun
        print(f"\n== {name} (so far {self.state.hours:.2f} h)", flush=True)
        base, t0 = rec["wall_s"], time.monotonic()
        stop = threading.Event()

        def beat() -> None:
            while not stop.wait(30.0):
                rec["wall_s"] = base + time.monotonic() - t0
                self.state.save()

        thread = threading.Thread(target=beat, daemon=True)
        thread.start()
        try:
            run()
        finally:
            stop.set()
            thread.join()
            rec["wall_s"] = base + time.monotonic() - t0
            self.state.save()
        rec.update(done=True, finished_at=time.strftime("%Y-%m-%dT%H:%M:%S"))
        self.state.save()
        print(f"== {name}: {rec['wall_s'] / 60:.1f} min", flush=True)
        if self.cfg.stop_after == name:
            raise StopRequested(name)

    def repo(self, what: str) -> str:
        return f"local/{self.cfg.name}_{what}"

    def seed(self, k: int, offset: int) -> int:
        return self.cfg.seed + 10 * k + offset

    # -- base: demonstrations and a first policy -----------------------------------------------------

    def base_dataset(self) -> None:
        from lerobot_gcs_push.dataset import GenerateConfig, generate

        b = self.cfg.base
        generate(
            GenerateConfig(
                episodes=b.episodes,
                repo_id=self.repo("base"),
                seed=b.seed,
                sampler=b.sampler,
                workers=self.cfg.workers,
                resume=True,
            )
        )

    def train_to(
        self, dst: Path, *, repo_id: str, steps: int, seed: int, lr: float | None, init: str | None, job: str
    ) -> None:
        from lerobot_gcs_push.training import TrainJob, train

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

    # -- a round ---------------------------------------------------------------------------------------

    def rollouts(self, k: int) -> list[Path]:
        return [self.work / f"r{k}" / f"rollouts_{s}" for s in ("hard", "uniform")]

    def run_rollouts(self, k: int) -> None:
        from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate

        r = self.cfg.round
        for (sampler, n, off), out in zip((("hard", r.hard, 0), ("uniform", r.uniform, 1)), self.rollouts(k)):
            if n:
                evaluate(
                    EvaluateConfig(
                        policies=[self.cfg.policy],
                        sampler=sampler,
                        seed=self.seed(k, off),
                        num_initial_conditions=n,
                        runs=1,
                        disturbances=r.disturbances,
                        timeout_s=r.timeout_s,
                        workers=self.cfg.workers,
                        videos=0,
                        device=self.cfg.device,
                        output_dir=str(out),
                    )
                )

    def states_file(self, k: int) -> Path:
        return self.state_dir / f"r{k}" / "branch_states.json"

    def run_collect(self, k: int) -> None:
        from lerobot_gcs_push.active import CollectConfig, collect
        from lerobot_gcs_push.dataset import GenerateConfig, dataset_root

        cfg = CollectConfig(
            rollouts=[str(p) for p in self.rollouts(k) if (p / "runs.jsonl").is_file()],
            repo_id=self.repo(f"r{k}"),
            large_regret_m=self.cfg.round.large_regret_m,
            seed=self.seed(k, 2),
            workers=self.cfg.workers,
            resume=True,
        )
        collect(cfg)
        root = dataset_root(GenerateConfig(repo_id=cfg.repo_id))
        self.states_file(k).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(root.with_name(root.name + ".branch_states.json"), self.states_file(k))

    def ensure_round_data(self, j: int) -> None:
        """Round j's labelled states, rebuilt from its kept list on a machine that lacks them: the same
        expert, states and seed give the same episodes."""
        from lerobot_gcs_push.dataset import GenerateConfig, generate

        if (self.home / self.repo(f"r{j}") / "meta" / "info.json").is_file():
            return
        generate(
            GenerateConfig(
                initial_conditions=str(self.states_file(j)),
                repo_id=self.repo(f"r{j}"),
                seed=self.seed(j, 2),
                expert="closed-loop",
                workers=self.cfg.workers,
                resume=True,
            )
        )

    def run_merge(self, k: int) -> None:
        from lerobot_gcs_push.dataset import merge_datasets

        if not (self.home / self.repo("base") / "meta" / "info.json").is_file():
            self.base_dataset()
        for j in range(1, k + 1):  # keep every round's states (round 2 dropped round 1's and forgot it)
            self.ensure_round_data(j)
        merge_datasets(
            [self.repo("base")] + [self.repo(f"r{j}") for j in range(1, k + 1)],
            self.repo(f"r{k}_merged"),
            desc=f"r{k} merge",
        )

    def candidate(self, k: int) -> Path:
        return self.state_dir / f"r{k}" / "candidate"

    def run_finetune(self, k: int) -> None:
        if not (self.home / self.repo(f"r{k}_merged") / "meta" / "info.json").is_file():
            self.run_merge(k)  # on a fresh machine: the merge is rebuilt, not committed
        self.train_to(
            self.candidate(k),
            repo_id=self.repo(f"r{k}_merged"),
            steps=self.cfg.round.steps,
            seed=self.seed(k, 9),
            lr=self.cfg.round.lr,
            init=self.cfg.policy,
            job=f"r{k}_finetune",
        )

    def validation_dirs(self, k: int) -> list[Path]:
        return [self.work / f"r{k}" / f"validation_{s}" for s in ("hard", "uniform")]

    def run_validation(self, k: int) -> None:
        from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate

        v = self.cfg.validation
        for (sampler, n, off), out in zip((("hard", v.hard, 5), ("uniform", v.uniform, 6)), self.validation_dirs(k)):
            if n:
                evaluate(
                    EvaluateConfig(
                        policies=[self.cfg.policy, str(self.candidate(k))],
                        sampler=sampler,
                        seed=self.seed(k, off),
                        num_initial_conditions=n,
                        runs=v.runs,
                        timeout_s=self.cfg.round.timeout_s,
                        workers=self.cfg.workers,
                        videos=0,
                        device=self.cfg.device,
                        output_dir=str(out),
                    )
                )

    def run_decision(self, k: int) -> None:
        from lerobot_gcs_push.shipping import decide, read_validation, score

        dirs = [d for d in self.validation_dirs(k) if (d / "runs.jsonl").is_file()]
        recs = read_validation(dirs)
        v = self.cfg.validation
        decision = decide(recs, self.cfg.policy, str(self.candidate(k)), margin=v.margin, time_gain=v.time_gain)
        winner = str(self.candidate(k)) if decision.ship else self.cfg.policy
        by_set = {d.name.removeprefix("validation_"): asdict(score(read_validation([d]), winner)) for d in dirs}
        # Replaced, not appended: a decision killed before its stage was marked done is made again.
        self.state.rounds = [r for r in self.state.rounds if r["round"] != k] + [
            {
                "round": k,
                "shipped": decision.ship,
                "decision": decision.to_json(),
                "winner_by_set": by_set,
                "hours": self.state.hours,
            }
        ]
        print(f"round {k}: {'ships' if decision.ship else 'keeps the current policy'}: {decision.reason}", flush=True)
        if decision.ship and is_pretrained_dir(self.candidate(k)):  # gone if a kill came after the copy
            export_policy(self.candidate(k), self.cfg.policy, dtype="float16", overwrite=True)
        shutil.rmtree(self.candidate(k), ignore_errors=True)  # decided: only the shipped weights stay

    # -- the loop --------------------------------------------------------------------------------------

    def targets_met(self) -> bool:
        if not self.state.rounds:
            return False
        last = self.state.rounds[-1]["winner_by_set"]
        s = self.cfg.stop

        def rate(name: str) -> float:
            rec = last.get(name)
            return rec["successes"] / rec["runs"] if rec else 1.0

        return rate("hard") >= s.hard_success and rate("uniform") >= s.uniform_success

    def run(self) -> dict:
        cfg = self.cfg
        if not is_pretrained_dir(cfg.policy):
            self.stage("base.demonstrations", self.base_dataset)
            self.stage(
                "base.train",
                lambda: self.train_to(
                    Path(cfg.policy),
                    repo_id=self.repo("base"),
                    steps=cfg.base.steps,
                    seed=self.seed(0, 9),
                    lr=cfg.base.lr,
                    init=None,
                    job="base_train",
                ),
            )
        k = len(self.state.rounds) + 1
        while True:
            if self.targets_met():
                why = "targets met on the latest validation set"
                break
            if k > cfg.stop.max_rounds:
                why = f"{cfg.stop.max_rounds} rounds run"
                break
            if self.state.hours >= cfg.stop.max_hours:
                why = f"budget of {cfg.stop.max_hours:g} h spent"
                break
            for name, step in (
                ("rollouts", self.run_rollouts),
                ("collect", self.run_collect),
                ("merge", self.run_merge),
                ("finetune", self.run_finetune),
                ("validation", self.run_validation),
                ("decision", self.run_decision),
            ):
                self.stage(f"r{k}.{name}", functools.partial(step, k))
            k += 1
        print(
            f"\nstopped: {why}; {len(self.state.rounds)} round(s) in {self.state.hours:.2f} h; policy in {cfg.policy}"
        )
        return {"stopped": why, "hours": self.state.hours, "rounds": self.state.rounds}


def improve(cfg: ImproveConfig) -> dict:
    with contextlib.suppress(StopRequested):
        return Improver(cfg).run()
    print(f"stopped after {cfg.stop_after}, as asked; run the same command again to continue")
    return {"stopped": f"after {cfg.stop_after}"}
