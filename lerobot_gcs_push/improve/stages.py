"""The stages of an improve run, one object each over the run's `Workspace`: the base (demonstrations and a
first policy), then per round the rollouts, collect, merge, fine-tune, validation and the decision. Each
stage's `run` is resumable as a whole (`State.run_stage`); what a later stage needs from an earlier one on a
fresh machine is made again (seeded, so the same) or rebuilt from the lists the state folder keeps."""

from __future__ import annotations

import json
import shutil
from dataclasses import asdict
from pathlib import Path

from lerobot_gcs_push.artifacts.checkpoints import export_policy, is_pretrained_dir
from lerobot_gcs_push.improve.workspace import Stage, Workspace


class Base(Stage):
    """The demonstrations (generated, or `base.lists` replayed) and the policy trained on them."""

    def dataset(self) -> None:
        from lerobot_gcs_push.generate import GenerateConfig, generate

        b, ws = self.cfg.base, self.ws
        if b.lists:  # the demonstrations the policy was trained on, replayed
            generate(
                GenerateConfig(
                    initial_conditions=str(self.list()),
                    repo_id=ws.repo("base"),
                    env_id=self.cfg.env_id,
                    **self.cfg.fan_out(),
                    resume=True,
                )
            )
            return
        generate(
            GenerateConfig(
                episodes=b.episodes,
                repo_id=ws.repo("base"),
                env_id=self.cfg.env_id,
                seed=b.seed,
                sampler=b.sampler,
                **self.cfg.fan_out(),
                resume=True,
            )
        )

    def list(self) -> Path:
        """`base.lists` joined in order and cut to `base.episodes`: one replay list in work_dir (rebuilt)."""
        entries: list = []
        for path in self.cfg.base.lists:
            entries += json.loads(Path(path).read_text())
        n = self.cfg.base.episodes
        if len(entries) < n:
            raise ValueError(f"base.lists hold {len(entries)} episodes, base.episodes asks for {n}")
        out = self.ws.work / "base_list.json"
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(entries[:n]))
        return out

    def train(self) -> None:
        self.dataset()  # returns at once when the cache has it; a fresh machine rebuilds it
        b = self.cfg.base
        self.ws.train_to(Path(self.cfg.policy), repo_id=self.ws.repo("base"), steps=b.steps,
                         seed=self.ws.seed(0, 9), lr=b.lr, init=None, job="base_train")  # fmt: skip


class Rollouts(Stage):
    """The current policy beside the GCS expert on round k's hard and uniform starts, and its scores."""

    def folders(self, k: int) -> list[Path]:
        return [self.ws.work / f"r{k}" / f"rollouts_{s}" for s in ("hard", "uniform")]

    def run(self, k: int) -> None:
        r, ws = self.cfg.round, self.ws
        sets = ((self.cfg.hard_sampler, r.hard, 0), ("uniform", r.uniform, 1))
        for (sampler, n, off), out in zip(sets, self.folders(k)):
            if n:  # GCS beside, for the time target; `collect` branches from the learned policy only
                ws.evaluate([ws.expert, self.cfg.policy], sampler, ws.seed(k, off), n, 1, out, r.disturbances)
        self.state.stages[f"r{k}.rollouts"]["scores"] = self.scores(k)

    def scores(self, k: int) -> dict:
        """The current policy on round k's rollouts, per sampler: success without and with disturbances,
        regret (the box) or final coverage (a slider that turns), and mean success time over the GCS
        expert's on the same initial conditions."""
        import numpy as np

        from lerobot_gcs_push.evaluation import read_runs

        out = {}
        for folder in self.folders(k):
            recs = read_runs(folder / "runs.jsonl")
            if not recs:
                continue
            mine = [r for r in recs if r["policy"] == self.cfg.policy]
            gcs = [r["sim_time_s"] for r in recs if r["policy"] == self.ws.expert and r["success"]]
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


class Collect(Stage):
    """The expert from the branch states of round k's rollouts (`collect.py`), its states and episodes kept."""

    def __init__(self, ws: Workspace, rollouts: Rollouts):
        super().__init__(ws)
        self.rollouts = rollouts

    def states_file(self, k: int) -> Path:
        return self.ws.state_dir / f"r{k}" / "branch_states.json"

    def replay_file(self, k: int) -> Path:
        """The labelled episodes of round k's states as run (a replay list): what rebuilds them with no
        planning. Rounds collected before it was kept are rebuilt from `states_file` by the expert."""
        return self.ws.state_dir / f"r{k}" / "replay.json"

    def run(self, k: int) -> None:
        from lerobot_gcs_push.generate import GenerateConfig, dataset_root
        from lerobot_gcs_push.generate.replay import REPLAY_META
        from lerobot_gcs_push.improve.collect import CollectConfig, collect

        counts, folders = (self.cfg.round.hard, self.cfg.round.uniform), self.rollouts.folders(k)
        if any(n and not (p / "runs.jsonl").is_file() for n, p in zip(counts, folders)):
            self.rollouts.run(k)  # a fresh machine: the rollouts are seeded, so made again the same
        cfg = CollectConfig(
            rollouts=[str(p) for p in folders if (p / "runs.jsonl").is_file()],
            repo_id=self.ws.repo(f"r{k}"),
            large_regret_m=self.cfg.round.large_regret_m,
            max_per_run=self.cfg.round.max_per_run,
            seed=self.ws.seed(k, 2),
            **self.cfg.fan_out(),
            resume=True,
        )
        collect(cfg)
        root = dataset_root(GenerateConfig(repo_id=cfg.output.repo_id))
        self.states_file(k).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(root.with_name(root.name + ".branch_states.json"), self.states_file(k))
        shutil.copyfile(root / REPLAY_META, self.replay_file(k))


class Merge(Stage):
    """The base, the prior states and every round's labelled states so far, as one dataset."""

    def __init__(self, ws: Workspace, base: Base, collect: Collect):
        super().__init__(ws)
        self.base, self.collect = base, collect

    def ensure_states(self, what: str, states: Path, seed: int, expert: str = "closed-loop") -> None:
        """A labelled-state dataset, rebuilt from its kept list on a machine that lacks it."""
        from lerobot_gcs_push.generate import GenerateConfig, generate

        if self.ws.has(what):
            return
        generate(
            GenerateConfig(
                initial_conditions=str(states),
                repo_id=self.ws.repo(what),
                env_id=self.cfg.env_id,
                seed=seed,
                expert=expert,
                **self.cfg.fan_out(),
                resume=True,
            )
        )

    def inputs(self, k: int) -> list[str]:
        priors = [f"prior{i}" for i in range(len(self.cfg.prior_states))]
        return ["base", *priors, *(f"r{j}" for j in range(1, k + 1))]

    def run(self, k: int) -> None:
        from lerobot_gcs_push.generate import merge_datasets

        ws, collect = self.ws, self.collect
        if not ws.has("base"):
            self.base.dataset()
        for i, states in enumerate(self.cfg.prior_states):  # as the hand-run rounds rebuilt them: seed 0
            self.ensure_states(f"prior{i}", Path(states), seed=0)
        for j in range(1, k + 1):  # keep every round's states (round 2 dropped round 1's and forgot it)
            if collect.replay_file(j).is_file():
                self.ensure_states(f"r{j}", collect.replay_file(j), seed=ws.seed(j, 2), expert="replay")
            else:
                self.ensure_states(f"r{j}", collect.states_file(j), seed=ws.seed(j, 2))
        merge_datasets([ws.repo(w) for w in self.inputs(k)], ws.repo(f"r{k}_merged"), desc=f"r{k} merge")


class Finetune(Stage):
    """The current policy fine-tuned on round k's merge: the candidate."""

    def __init__(self, ws: Workspace, merge: Merge):
        super().__init__(ws)
        self.merge = merge

    def candidate(self, k: int) -> Path:
        return self.ws.state_dir / f"r{k}" / "candidate"

    def run(self, k: int) -> None:
        ws = self.ws
        if not ws.has(f"r{k}_merged"):
            self.merge.run(k)  # on a fresh machine: the merge is rebuilt, not committed
        r = self.cfg.round
        ws.train_to(self.candidate(k), repo_id=ws.repo(f"r{k}_merged"), steps=r.steps, seed=ws.seed(k, 9),
                    lr=r.lr, init=self.cfg.policy, job=f"r{k}_finetune")  # fmt: skip
        if k > 1:  # each merge is a full copy: the previous one has served
            shutil.rmtree(ws.home / ws.repo(f"r{k - 1}_merged"), ignore_errors=True)


class Validation(Stage):
    """The current policy beside the candidate on round k's validation sets."""

    def __init__(self, ws: Workspace, finetune: Finetune):
        super().__init__(ws)
        self.finetune = finetune

    def sets(self, k: int) -> list[tuple[str, int, int, Path]]:
        """Round k's validation sets that hold starts: (sampler, count, seed offset, output folder)."""
        v = self.cfg.validation
        sets = (("hard", self.cfg.hard_sampler, v.hard, 5), ("uniform", "uniform", v.uniform, 6))
        return [(sampler, n, off, self.ws.work / f"r{k}" / f"validation_{name}") for name, sampler, n, off in sets if n]

    def dirs(self, k: int) -> list[Path]:
        return [out for *_, out in self.sets(k)]

    def run(self, k: int) -> None:
        policies = [self.cfg.policy, str(self.finetune.candidate(k))]
        for sampler, n, off, out in self.sets(k):
            self.ws.evaluate(policies, sampler, self.ws.seed(k, off), n, self.cfg.validation.runs, out)


class Decision(Stage):
    """Whether round k's candidate ships, decided once and recorded before the weights move, so a kill
    anywhere after is finished the same way: copy the candidate in if it ships, then let it go."""

    def __init__(self, ws: Workspace, validation: Validation):
        super().__init__(ws)
        self.validation, self.finetune = validation, validation.finetune

    def run(self, k: int) -> None:
        from lerobot_gcs_push.improve.shipping import decide, read_validation, score

        candidate, dirs = self.finetune.candidate(k), self.validation.dirs(k)
        rec = self.state.stages[f"r{k}.decision"]
        if "decision" not in rec:
            if not is_pretrained_dir(candidate):
                raise FileNotFoundError(f"round {k}'s candidate {candidate} is missing: commit state_dir whole")
            if not all((d / "runs.jsonl").is_file() for d in dirs):
                self.validation.run(k)  # a fresh machine: seeded, so made again the same
            v = self.cfg.validation
            decision = decide(read_validation(dirs), self.cfg.policy, str(candidate), margin=v.margin,
                              time_gain=v.time_gain, coverage_margin=v.coverage_margin)  # fmt: skip
            winner = str(candidate) if decision.ship else self.cfg.policy
            rec["decision"] = decision.to_json()
            rec["winner_by_set"] = {
                d.name.removeprefix("validation_"): asdict(score(read_validation([d]), winner)) for d in dirs
            }
            self.state.save()
        shipped = rec["decision"]["ship"]
        print(f"round {k}: {'ships' if shipped else 'keeps the current policy'}: {rec['decision']['reason']}")
        if shipped and is_pretrained_dir(candidate):  # gone only if a kill came after the copy
            export_policy(candidate, self.cfg.policy, overwrite=True)
        shutil.rmtree(candidate, ignore_errors=True)  # decided: only the shipped weights stay
        self.record(k, shipped=shipped, decision=rec["decision"], winner_by_set=rec["winner_by_set"])

    def record(self, k: int, **what) -> None:
        rollouts = self.state.stages.get(f"r{k}.rollouts", {}).get("scores", {})
        entry = {"round": k, "rollouts": rollouts, **what, "hours": self.state.hours}
        self.state.rounds = [r for r in self.state.rounds if r["round"] != k] + [entry]
