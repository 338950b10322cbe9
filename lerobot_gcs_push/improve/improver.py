"""The rounds themselves: base demonstrations and training, then per round rollouts, collect, merge,
fine-tune, validation and the decision, each a resumable stage (`State.run_stage`), and the loop over them."""

from __future__ import annotations

import functools
import json
import shutil
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path

from lerobot_gcs_push.checkpoints import export_policy, is_pretrained_dir
from lerobot_gcs_push.improve.config import _BEFORE_FIELDS, STAGES, ImproveConfig, _canonical, _settings
from lerobot_gcs_push.improve.state import STATE_FILE, State
from lerobot_gcs_push.settings import changed, describe


class Improver:
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

    # -- the bookkeeping every stage shares ---------------------------------------------------------

    def stage(self, name: str, run: Callable[[], None]) -> None:
        """Run a stage unless done (`State.run_stage`); `stop_after` ends the run after it."""
        self.state.run_stage(name, run, self.cfg.stop_after)

    def repo(self, what: str) -> str:
        return f"local/{self.cfg.name}_{what}"

    def has(self, what: str) -> bool:
        return (self.home / self.repo(what) / "meta" / "info.json").is_file()

    def seed(self, k: int, offset: int) -> int:
        return self.cfg.seed + 10 * k + offset

    # -- base: demonstrations and a first policy -----------------------------------------------------

    def base_dataset(self) -> None:
        from lerobot_gcs_push.generate import GenerateConfig, generate

        b = self.cfg.base
        if b.lists:  # the demonstrations the policy was trained on, replayed
            generate(
                GenerateConfig(
                    initial_conditions=str(self.base_list()),
                    repo_id=self.repo("base"),
                    env_id=self.cfg.env_id,
                    **self.cfg.fan_out(),
                    resume=True,
                )
            )
            return
        generate(
            GenerateConfig(
                episodes=b.episodes,
                repo_id=self.repo("base"),
                env_id=self.cfg.env_id,
                seed=b.seed,
                sampler=b.sampler,
                **self.cfg.fan_out(),
                resume=True,
            )
        )

    def base_list(self) -> Path:
        """`base.lists` joined in order and cut to `base.episodes`: one replay list in work_dir (rebuilt)."""
        entries: list = []
        for path in self.cfg.base.lists:
            entries += json.loads(Path(path).read_text())
        n = self.cfg.base.episodes
        if len(entries) < n:
            raise ValueError(f"base.lists hold {len(entries)} episodes, base.episodes asks for {n}")
        out = self.work / "base_list.json"
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(entries[:n]))
        return out

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

    # -- a round ---------------------------------------------------------------------------------------

    @property
    def expert(self) -> str:
        """The GCS expert the rounds time the policy against: the paper's open-loop plan for the box; closed
        loop for a slider that turns, whose open-loop plans reach coverage on 1 start of 20 (contact/)."""
        from lerobot_gcs_push.registration import SCENES

        return f"gcs-{SCENES[self.cfg.env_id].kind.default_expert}"

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
                        **self.cfg.fan_out(),
                        videos=0,
                        device=self.cfg.device,
                        output_dir=str(out),
                    )
                )
        self.state.stages[f"r{k}.rollouts"]["scores"] = self.rollout_scores(k)

    def rollout_scores(self, k: int) -> dict:
        """The current policy on round k's rollouts, per sampler: success without and with disturbances,
        regret (the box) or final coverage (a slider that turns), and mean success time over the GCS
        expert's on the same initial conditions."""
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
            # A slider that turns: the goal's final coverage, which moves while success is still nil.
            covered = [r["coverage"] for r in mine if r.get("coverage") is not None and not r["disturbances"]]
            if covered:
                score["coverage_mean"] = float(np.mean(covered))
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

    def replay_file(self, k: int) -> Path:
        """The labelled episodes of round k's states as run (a replay list): what rebuilds them with no
        planning. Rounds collected before it was kept are rebuilt from `states_file` by the expert."""
        return self.state_dir / f"r{k}" / "replay.json"

    def run_collect(self, k: int) -> None:
        from lerobot_gcs_push.generate import GenerateConfig, dataset_root
        from lerobot_gcs_push.generate.replay import REPLAY_META
        from lerobot_gcs_push.improve.collect import CollectConfig, collect

        counts = (self.cfg.round.hard, self.cfg.round.uniform)
        if any(n and not (p / "runs.jsonl").is_file() for n, p in zip(counts, self.rollouts(k))):
            self.run_rollouts(k)  # a fresh machine: the rollouts are seeded, so made again the same
        cfg = CollectConfig(
            rollouts=[str(p) for p in self.rollouts(k) if (p / "runs.jsonl").is_file()],
            repo_id=self.repo(f"r{k}"),
            large_regret_m=self.cfg.round.large_regret_m,
            max_per_run=self.cfg.round.max_per_run,
            seed=self.seed(k, 2),
            **self.cfg.fan_out(),
            resume=True,
        )
        collect(cfg)
        root = dataset_root(GenerateConfig(repo_id=cfg.repo_id))
        self.states_file(k).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(root.with_name(root.name + ".branch_states.json"), self.states_file(k))
        shutil.copyfile(root / REPLAY_META, self.replay_file(k))

    def ensure_states(self, what: str, states: Path, seed: int, expert: str = "closed-loop") -> None:
        """A labelled-state dataset, rebuilt from its kept list on a machine that lacks it."""
        from lerobot_gcs_push.generate import GenerateConfig, generate

        if self.has(what):
            return
        generate(
            GenerateConfig(
                initial_conditions=str(states),
                repo_id=self.repo(what),
                env_id=self.cfg.env_id,
                seed=seed,
                expert=expert,
                **self.cfg.fan_out(),
                resume=True,
            )
        )

    def merged_inputs(self, k: int) -> list[str]:
        priors = [f"prior{i}" for i in range(len(self.cfg.prior_states))]
        return ["base", *priors, *(f"r{j}" for j in range(1, k + 1))]

    def run_merge(self, k: int) -> None:
        from lerobot_gcs_push.generate import merge_datasets

        if not self.has("base"):
            self.base_dataset()
        for i, states in enumerate(self.cfg.prior_states):  # as the hand-run rounds rebuilt them: seed 0
            self.ensure_states(f"prior{i}", Path(states), seed=0)
        for j in range(1, k + 1):  # keep every round's states (round 2 dropped round 1's and forgot it)
            if self.replay_file(j).is_file():
                self.ensure_states(f"r{j}", self.replay_file(j), seed=self.seed(j, 2), expert="replay")
            else:
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

    def validation_sets(self, k: int) -> list[tuple[str, int, int, Path]]:
        """Round k's validation sets that hold starts: (sampler, count, seed offset, output folder)."""
        v = self.cfg.validation
        sets = (("hard", self.cfg.hard_sampler, v.hard, 5), ("uniform", "uniform", v.uniform, 6))
        return [(sampler, n, off, self.work / f"r{k}" / f"validation_{name}") for name, sampler, n, off in sets if n]

    def validation_dirs(self, k: int) -> list[Path]:
        return [out for *_, out in self.validation_sets(k)]

    def run_validation(self, k: int) -> None:
        from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate

        v = self.cfg.validation
        for sampler, n, off, out in self.validation_sets(k):
            evaluate(
                EvaluateConfig(
                    policies=[self.cfg.policy, str(self.candidate(k))],
                    env_id=self.cfg.env_id,
                    sampler=sampler,
                    seed=self.seed(k, off),
                    num_initial_conditions=n,
                    runs=v.runs,
                    timeout_s=self.cfg.round.timeout_s,
                    **self.cfg.fan_out(),
                    videos=0,
                    device=self.cfg.device,
                    output_dir=str(out),
                )
            )

    def run_decision(self, k: int) -> None:
        """Decided once and recorded before the weights move, so a kill anywhere after is finished the same
        way: copy the candidate in if it ships, then let it go."""
        from lerobot_gcs_push.improve.shipping import decide, read_validation, score

        rec = self.state.stages[f"r{k}.decision"]
        if "decision" not in rec:
            if not is_pretrained_dir(self.candidate(k)):
                raise FileNotFoundError(f"round {k}'s candidate {self.candidate(k)} is missing: commit state_dir whole")
            if not all((d / "runs.jsonl").is_file() for d in self.validation_dirs(k)):
                self.run_validation(k)  # a fresh machine: seeded, so made again the same
            recs = read_validation(self.validation_dirs(k))
            v = self.cfg.validation
            decision = decide(
                recs,
                self.cfg.policy,
                str(self.candidate(k)),
                margin=v.margin,
                time_gain=v.time_gain,
                coverage_margin=v.coverage_margin,
            )
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
        from lerobot_gcs_push.improve.curve import CURVE_FILE, plot_curve  # here: `python -m` runs the module

        cfg = self.cfg
        shipped = any(r.get("shipped") for r in self.state.rounds)
        if cfg.from_policy and not is_pretrained_dir(cfg.policy) and not shipped:
            print(f"starting from {cfg.from_policy}: copied to {cfg.policy}")
            export_policy(cfg.from_policy, cfg.policy, overwrite=True)
        # From nothing: a run that began so, or a new run with no policy. A run on its way whose policy
        # folder is missing is refused below, not trained again from nothing.
        if "base.demonstrations" in self.state.stages or (not self.state.stages and not is_pretrained_dir(cfg.policy)):
            if not self.state.stages:
                print(f"no policy at {cfg.policy}: starting from nothing (base demonstrations, then training)")
            self.stage("base.demonstrations", self.base_dataset)
            self.stage("base.train", self.base_train)
        elif not self.state.stages:
            print(f"improving {cfg.policy} in place")
        if not is_pretrained_dir(cfg.policy):
            raise FileNotFoundError(
                f"{cfg.policy} holds no policy although {self.state.path} records this run's stages: commit or "
                "copy the policy folder with the state folder"
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
