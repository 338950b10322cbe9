"""`gcs-push improve`: rounds of active data, from a policy folder or from nothing, until the policy is robust.
For the box, and for sliders that turn (gym-pusht's PushT: `--config_path=configs/improve/pusht.json`),
whose branch states are where coverage stalls rather than chunks of large regret (`stalls.py`).

A round: roll the current policy out beside GCS (hard and uniform initial conditions, with and without
disturbances, on seeds no evaluation set uses) -> stop here if it meets the targets on these fresh
conditions -> `collect` branch states labelled by the expert -> merge them with the base demonstrations
and every earlier round's states (LeRobot's aggregation) -> fine-tune the current weights -> a fresh
validation set, decided by the shipping rule (`shipping.py`) -> ship into the policy folder, or keep the
old one. From nothing, base demonstrations and a first training come before round 1. It also stops on a
budget of rounds or hours.

Every stage resumes after `kill -9`. What another machine needs to resume is small: the policy folder and
`state_dir` (the state file: stages done, their wall times, each round's scores and decision, drawn as
`curve.png` after every round's rollouts; each round's branch-state list; the candidate awaiting its
decision; the newest checkpoint of an unfinished training in fp16). Commit both and re-run the same
command: datasets are rebuilt from the lists (the same expert, states and seeds give the same episodes)
and rollouts or validation runs a later stage needs are made again (seeded, so the same).

Each default is a lesson of the eleven hand-run rounds (experiments/active_data/README.md), named beside it.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import re
import shutil
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from lerobot_gcs_push.checkpoints import export_policy, is_pretrained_dir
from lerobot_gcs_push.files import atomic_path
from lerobot_gcs_push.improve_curve import CURVE_FILE, plot_curve
from lerobot_gcs_push.registration import ENV_ID
from lerobot_gcs_push.settings import changed, describe
from lerobot_gcs_push.shipped import shipped_path

STATE_FILE = "state.json"
_SAVE_LOCK = threading.Lock()
STAGES = ("rollouts", "collect", "merge", "finetune", "validation", "decision")


@dataclass
class BaseConfig:
    """From nothing: the demonstrations and first training before round 1 (skipped for an existing policy)."""

    # GCS demonstrations; every round's merge keeps them (1000: the base of every merge since round 1).
    episodes: int = 1000
    sampler: str = "sobol"
    seed: int = 0
    # Steps of batch 32 from scratch: the CPU preset's own schedule, not yet tested as a base for rounds
    # (experiments/improve/from_nothing measures it). On demonstrations alone run 6 reached 0.71 after
    # 9500 steps and run 7 0.91 after 18,500; the rounds' own states are meant to do the rest.
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
    # Simulated seconds before a rollout counts as failed (every evaluation since run 7); None: the env's
    # own (gym-pusht's 300 steps, 30 s).
    timeout_s: float | None = 60.0
    # Branch from chunks above this regret in successful runs too (rounds 10 and 11: a success's
    # 0.25-0.5 m detours are where the extra time goes; round 11 shortened the path with it).
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
    # without disturbances, as the validation sets of rounds 6-11.
    hard: int = 40
    uniform: int = 40
    runs: int = 3
    # The candidate ships with `margin` more successes in the 240 runs (round 10 shipped on one and lost
    # every test set after), or within the margin with a mean success time `time_gain` lower (round 10b).
    margin: int = 3
    time_gain: float = 0.05


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
class ImproveConfig:
    # The policy folder to improve in place: a LeRobot pretrained_model directory, or a path where none is
    # yet (then from nothing: base demonstrations and a first training). Winners are written here.
    policy: str = "outputs/improve/policy"
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
    workers: int = 2
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
        from lerobot_gcs_push.evaluation import check_device
        from lerobot_gcs_push.registration import SCENES
        from lerobot_gcs_push.rollout import check_env_id
        from lerobot_gcs_push.scene import check_sampler, check_seed

        scene = SCENES[check_env_id(self.env_id)]
        # A slider that turns has no hard families (they are the box's) and gym-pusht no disturbances:
        # configs/improve/pusht.json sets its rounds up.
        if scene.rotates and (self.round.hard or self.validation.hard):
            raise ValueError(
                f"{self.env_id} has no hard families (they are the box's): set round.hard=0 and validation.hard=0 "
                "(its starts are round.uniform and validation.uniform; see configs/improve/pusht.json)"
            )
        if scene.frame is not None and self.round.disturbances:
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
        if Path(self.policy).exists() and not is_pretrained_dir(self.policy):
            raise ValueError(f"{self.policy} exists but is not a LeRobot pretrained_model directory")
        check_device(self.device)
        counts = {
            "round.hard": self.round.hard,
            "round.uniform": self.round.uniform,
            "validation.hard": self.validation.hard,
            "validation.uniform": self.validation.uniform,
            "stop.max_rounds": self.stop.max_rounds,
        }
        positive = {
            "round.hard + round.uniform": self.round.hard + self.round.uniform,
            "validation.hard + validation.uniform": self.validation.hard + self.validation.uniform,
            "base.episodes": self.base.episodes,
            "base.steps": self.base.steps,
            "round.steps": self.round.steps,
            "validation.runs": self.validation.runs,
            "validation.margin": self.validation.margin,
            "workers": self.workers,
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
    skip = ("workers", "device", "stop", "stop_after", "state_dir", "work_dir", "save_freq")
    return {k: v for k, v in asdict(cfg).items() if k not in skip}


class StopRequested(Exception):
    """`stop_after` reached: the state is saved and a re-run continues."""


@dataclass
class State:
    path: Path
    stages: dict[str, dict] = field(default_factory=dict)  # name -> {"done", "wall_s", "finished_at", ...}
    rounds: list[dict] = field(default_factory=list)  # per round: rollout scores, decision, hours at its end
    settings: dict = field(default_factory=dict)
    # The stop rule of the latest invocation (it may change on resume, unlike settings): the curve's targets.
    stop: dict = field(default_factory=dict)

    @classmethod
    def load(cls, path: Path) -> State:
        if not path.is_file():
            return cls(path)
        data = json.loads(path.read_text())
        return cls(path, data["stages"], data["rounds"], data.get("settings", {}), data.get("stop", {}))

    def as_dict(self) -> dict:
        return {"settings": self.settings, "stop": self.stop, "stages": self.stages, "rounds": self.rounds}

    def save(self) -> None:
        with _SAVE_LOCK, atomic_path(self.path) as tmp:  # the heartbeat thread saves too, into the same tmp
            tmp.write_text(json.dumps(self.as_dict(), indent=1))

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

    def has(self, what: str) -> bool:
        return (self.home / self.repo(what) / "meta" / "info.json").is_file()

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
                env_id=self.cfg.env_id,
                seed=b.seed,
                sampler=b.sampler,
                workers=self.cfg.workers,
                resume=True,
            )
        )

    def base_train(self) -> None:
        self.base_dataset()  # returns at once when the cache has it; a fresh machine rebuilds it
        self.train_to(
            Path(self.cfg.policy),
            repo_id=self.repo("base"),
            steps=self.cfg.base.steps,
            seed=self.seed(0, 9),
            lr=self.cfg.base.lr,
            init=None,
            job="base_train",
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
        (dst / "step.json").unlink(missing_ok=True)  # the partial's bookkeeping, not the policy's
        shutil.rmtree(self.state_dir / f"{job}.partial", ignore_errors=True)

    # -- a round ---------------------------------------------------------------------------------------

    @property
    def expert(self) -> str:
        """The GCS expert the rounds time the policy against: the paper's open-loop plan for the box; closed
        loop for a slider that turns, whose open-loop plans reach coverage on 1 start of 20 (contact/)."""
        from lerobot_gcs_push.registration import SCENES

        return "gcs-closed-loop" if SCENES[self.cfg.env_id].rotates else "gcs-open-loop"

    def rollouts(self, k: int) -> list[Path]:
        return [self.work / f"r{k}" / f"rollouts_{s}" for s in ("hard", "uniform")]

    def run_rollouts(self, k: int) -> None:
        from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate

        r = self.cfg.round
        sets = ((self.cfg.hard_sampler, r.hard, 0), ("uniform", r.uniform, 1))
        for (sampler, n, off), out in zip(sets, self.rollouts(k)):
            if n:
                evaluate(
                    EvaluateConfig(
                        # GCS beside, for the time target; `collect` branches from the learned policy only.
                        policies=[self.expert, self.cfg.policy],
                        env_id=self.cfg.env_id,
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
        self.state.stages[f"r{k}.rollouts"]["scores"] = self.rollout_scores(k)

    def rollout_scores(self, k: int) -> dict:
        """The current policy on round k's rollouts, per sampler: success without and with disturbances,
        regret (the box), and mean success time over the GCS expert's on the same initial conditions."""
        import numpy as np

        from lerobot_gcs_push.evaluation import read_runs

        out = {}
        for folder in self.rollouts(k):
            recs = read_runs(folder / "runs.jsonl")
            if not recs:
                continue
            mine = [r for r in recs if r["policy"] == self.cfg.policy]
            gcs = [r["sim_time_s"] for r in recs if r["policy"] == self.expert and r["success"]]
            score = {}
            for dist in (False, True):
                runs = [r for r in mine if r["disturbances"] == dist]
                if runs:
                    score["with" if dist else "without"] = sum(r["success"] for r in runs) / len(runs)
            times = [r["sim_time_s"] for r in mine if r["success"] and not r["disturbances"]]
            score["time_ratio"] = float(np.mean(times) / np.mean(gcs)) if times and gcs else float("inf")
            regrets = [r["regret"] for r in mine if r.get("regret") is not None]
            if regrets:
                score["regret_mean"], score["regret_p95"] = float(np.mean(regrets)), float(np.percentile(regrets, 95))
            out[folder.name.removeprefix("rollouts_")] = score
        return out

    def targets_met(self, k: int) -> bool:
        s, scores = self.cfg.stop, self.state.stages[f"r{k}.rollouts"].get("scores", {})
        need = {"hard": s.hard_success, "uniform": s.uniform_success}
        return bool(scores) and all(
            min(v for key, v in score.items() if key in ("with", "without")) >= need[name]
            and score["time_ratio"] <= s.time_ratio
            for name, score in scores.items()
        )

    def states_file(self, k: int) -> Path:
        return self.state_dir / f"r{k}" / "branch_states.json"

    def run_collect(self, k: int) -> None:
        from lerobot_gcs_push.active import CollectConfig, collect
        from lerobot_gcs_push.dataset import GenerateConfig, dataset_root

        counts = (self.cfg.round.hard, self.cfg.round.uniform)
        if any(n and not (p / "runs.jsonl").is_file() for n, p in zip(counts, self.rollouts(k))):
            self.run_rollouts(k)  # a fresh machine: the rollouts are seeded, so made again the same
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

    def ensure_states(self, what: str, states: Path, seed: int) -> None:
        """A labelled-state dataset, rebuilt from its kept list on a machine that lacks it."""
        from lerobot_gcs_push.dataset import GenerateConfig, generate

        if self.has(what):
            return
        generate(
            GenerateConfig(
                initial_conditions=str(states),
                repo_id=self.repo(what),
                env_id=self.cfg.env_id,
                seed=seed,
                expert="closed-loop",
                workers=self.cfg.workers,
                resume=True,
            )
        )

    def merged_inputs(self, k: int) -> list[str]:
        priors = [f"prior{i}" for i in range(len(self.cfg.prior_states))]
        return ["base", *priors, *(f"r{j}" for j in range(1, k + 1))]

    def run_merge(self, k: int) -> None:
        from lerobot_gcs_push.dataset import merge_datasets

        if not self.has("base"):
            self.base_dataset()
        for i, states in enumerate(self.cfg.prior_states):  # as the hand-run rounds rebuilt them: seed 0
            self.ensure_states(f"prior{i}", Path(states), seed=0)
        for j in range(1, k + 1):  # keep every round's states (round 2 dropped round 1's and forgot it)
            self.ensure_states(f"r{j}", self.states_file(j), seed=self.seed(j, 2))
        merge_datasets([self.repo(w) for w in self.merged_inputs(k)], self.repo(f"r{k}_merged"), desc=f"r{k} merge")

    def candidate(self, k: int) -> Path:
        return self.state_dir / f"r{k}" / "candidate"

    def run_finetune(self, k: int) -> None:
        if not self.has(f"r{k}_merged"):
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
        if k > 1:  # each merge is a full copy: the previous one has served
            shutil.rmtree(self.home / self.repo(f"r{k - 1}_merged"), ignore_errors=True)

    def validation_dirs(self, k: int) -> list[Path]:
        v = self.cfg.validation
        return [self.work / f"r{k}" / f"validation_{s}" for s, n in (("hard", v.hard), ("uniform", v.uniform)) if n]

    def run_validation(self, k: int) -> None:
        from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate

        v = self.cfg.validation
        sets = ((self.cfg.hard_sampler, v.hard, 5), ("uniform", v.uniform, 6))
        for (sampler, n, off), out in zip(sets, self.validation_dirs(k)):
            evaluate(
                EvaluateConfig(
                    policies=[self.cfg.policy, str(self.candidate(k))],
                    env_id=self.cfg.env_id,
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
        """Decided once and recorded before the weights move, so a kill anywhere after is finished the same
        way: copy the candidate in if it ships, then let it go."""
        from lerobot_gcs_push.shipping import decide, read_validation, score

        rec = self.state.stages[f"r{k}.decision"]
        if "decision" not in rec:
            if not is_pretrained_dir(self.candidate(k)):
                raise FileNotFoundError(f"round {k}'s candidate {self.candidate(k)} is missing: commit state_dir whole")
            if not all((d / "runs.jsonl").is_file() for d in self.validation_dirs(k)):
                self.run_validation(k)  # a fresh machine: seeded, so made again the same
            recs = read_validation(self.validation_dirs(k))
            v = self.cfg.validation
            decision = decide(recs, self.cfg.policy, str(self.candidate(k)), margin=v.margin, time_gain=v.time_gain)
            winner = str(self.candidate(k)) if decision.ship else self.cfg.policy
            rec["decision"] = decision.to_json()
            rec["winner_by_set"] = {
                d.name.removeprefix("validation_"): asdict(score(read_validation([d]), winner))
                for d in self.validation_dirs(k)
            }
            self.state.save()
        shipped = rec["decision"]["ship"]
        print(f"round {k}: {'ships' if shipped else 'keeps the current policy'}: {rec['decision']['reason']}")
        if shipped and is_pretrained_dir(self.candidate(k)):  # gone only if a kill came after the copy
            export_policy(self.candidate(k), self.cfg.policy, overwrite=True)
        shutil.rmtree(self.candidate(k), ignore_errors=True)  # decided: only the shipped weights stay
        self.record_round(k, shipped=shipped, decision=rec["decision"], winner_by_set=rec["winner_by_set"])

    def record_round(self, k: int, **what) -> None:
        rollouts = self.state.stages.get(f"r{k}.rollouts", {}).get("scores", {})
        entry = {"round": k, "rollouts": rollouts, **what, "hours": self.state.hours}
        self.state.rounds = [r for r in self.state.rounds if r["round"] != k] + [entry]

    # -- the loop --------------------------------------------------------------------------------------

    def run(self) -> dict:
        cfg = self.cfg
        if "base.demonstrations" in self.state.stages or not is_pretrained_dir(cfg.policy):
            if not self.state.stages:
                print(f"no policy at {cfg.policy}: starting from nothing (base demonstrations, then training)")
            self.stage("base.demonstrations", self.base_dataset)
            self.stage("base.train", self.base_train)
        elif not self.state.stages:
            print(f"improving {cfg.policy} in place")
        if not is_pretrained_dir(cfg.policy):
            raise FileNotFoundError(
                f"{cfg.policy} holds no policy although {self.state.path} says it was trained: commit or copy "
                "the policy folder with the state folder"
            )
        k = 1
        while self.state.done(f"r{k}.decision"):
            k += 1
        while True:
            if k > cfg.stop.max_rounds:
                why = f"{cfg.stop.max_rounds} rounds run"
                break
            if self.state.hours >= cfg.stop.max_hours:
                why = f"budget of {cfg.stop.max_hours:g} h spent"
                break
            self.stage(f"r{k}.rollouts", functools.partial(self.run_rollouts, k))
            plot_curve(self.state.as_dict(), self.state_dir / CURVE_FILE)
            if self.targets_met(k):
                self.record_round(k, shipped=False, decision=None, targets_met=True)
                why = f"targets met on round {k}'s rollouts"
                break
            for name, step in zip(
                STAGES[1:],
                (self.run_collect, self.run_merge, self.run_finetune, self.run_validation, self.run_decision),
            ):
                self.stage(f"r{k}.{name}", functools.partial(step, k))
            k += 1
        self.state.save()
        print(f"\nstopped: {why}; {k - 1} round(s) decided in {self.state.hours:.2f} h; policy in {cfg.policy}")
        return {"stopped": why, "hours": self.state.hours, "rounds": self.state.rounds}


def improve(cfg: ImproveConfig) -> dict:
    with contextlib.suppress(StopRequested):
        return Improver(cfg).run()
    print(f"stopped after {cfg.stop_after}, as asked; run the same command again to continue")
    return {"stopped": f"after {cfg.stop_after}", "rounds": []}
