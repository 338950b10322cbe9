"""`gcs-push improve`: the shipping rule against the rounds' own script, and a whole run from nothing
killed with SIGKILL inside each long stage, resumed, and checked file by file."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import gcs_push, kill_when

from lerobot_gcs_push.improve.shipping import decide

ROOT = Path(__file__).resolve().parents[1]
ORACLE = ROOT / "experiments" / "scripts" / "validation_winner.py"


def _runs(policy: str, successes: int, runs: int, mean_time: float, rng) -> list[dict]:
    out = []
    for i in range(runs):
        ok = i < successes
        out.append(
            {
                "policy": policy,
                "disturbances": False,
                "initial_condition_index": i // 3,
                "run": i % 3,
                "success": ok,
                "sim_time_s": float(mean_time + rng.normal(0, 2)) if ok else 60.0,
                "regret": float(rng.exponential(2.0)),
            }
        )
    # A run with disturbances must not count: validation sets are judged without them.
    out.append(out[0] | {"disturbances": True, "success": not out[0]["success"]})
    return out


def _oracle(tmp_path: Path, recs: list[dict], old: str, new: str, *flags: str) -> str:
    d = tmp_path / f"v{len(list(tmp_path.iterdir()))}"
    d.mkdir()
    (d / "runs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    out = subprocess.run([sys.executable, str(ORACLE), *flags, old, new, str(d)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_the_rule_is_the_rounds_rule(tmp_path):
    """`decide` against experiments/scripts/validation_winner.py, the script that made rounds 9-11's
    decisions, over random margins, success counts and times, and on two decisions the rounds made."""
    rng = np.random.default_rng(0)
    for _ in range(30):
        n = 240
        a, b = int(rng.integers(200, n + 1)), int(rng.integers(200, n + 1))
        ta, tb = float(rng.uniform(20, 26)), float(rng.uniform(20, 26))
        recs = _runs("old", a, n, ta, rng) + _runs("new", b, n, tb, rng)
        margin, gain = int(rng.integers(1, 5)), float(rng.choice([0.0, 0.05, 0.1]))
        ours = decide(recs, "old", "new", margin=margin, time_gain=gain)
        theirs = _oracle(tmp_path, recs, "old", "new", f"--margin={margin}", f"--time_gain={gain}")
        assert ("new" if ours.ship else "old") == theirs, (a, b, ta, tb, margin, gain)
        assert ours.candidate.successes == b and ours.current.successes == a
    # Round 10b against round 10 (ninth validation set): one run fewer, 5.6 % faster: ships.
    recs = _runs("r10", 239, 240, 25.35, rng) + _runs("r10b", 238, 240, 23.92, rng)
    assert decide(recs, "r10", "r10b").ship == (23.92 <= 0.95 * 25.35)  # hand-computed: 23.92 < 24.08
    # Round 10 against round 9 under the later rule (seventh set): 237 vs 236, margin 3: round 9 stays.
    recs = _runs("r9", 236, 240, 24.0, rng) + _runs("r10", 237, 240, 25.2, rng)
    assert not decide(recs, "r9", "r10").ship


def test_a_candidate_without_success_never_ships_on_time():
    rng = np.random.default_rng(1)
    recs = _runs("old", 0, 6, 0.0, rng) + _runs("new", 0, 6, 0.0, rng)
    assert not decide(recs, "old", "new", margin=3).ship
    with pytest.raises(ValueError, match="different sets"):
        decide(_runs("old", 1, 6, 20.0, rng) + _runs("new", 1, 3, 20.0, rng), "old", "new")


def test_without_a_success_on_either_side_the_candidate_ships_on_coverage_only_when_asked():
    """Hand-computed: on four paired starts the current policy leaves 0, 0, 0.5, 0.2 of the goal covered and
    the candidate 0.1, 0, 0.6, 0.1: means 0.175 and 0.2 (+0.025), higher on 2 starts, lower on 1."""

    def runs(policy, coverages, success=False):
        return [
            {"policy": policy, "disturbances": False, "initial_condition_index": i, "run": 0, "seed": 100 + i,
             "success": success and i == 0, "sim_time_s": 30.0, "coverage": c}
            for i, c in enumerate(coverages)
        ]  # fmt: skip

    recs = runs("old", [0, 0, 0.5, 0.2]) + runs("new", [0.1, 0, 0.6, 0.1])
    d = decide(recs, "old", "new", coverage_margin=0.02)
    assert d.ship and "+0.025" in d.reason and "higher on 2 starts and lower on 1" in d.reason
    assert d.current.coverage_mean == pytest.approx(0.175) and d.candidate.coverage_mean == pytest.approx(0.2)
    assert not decide(recs, "old", "new", coverage_margin=0.03).ship  # +0.025 < 0.03
    assert not decide(recs, "old", "new").ship  # off (the box's rule): no success, no ship
    # a higher mean from one start, lower on three: kept
    recs = runs("old", [0.1, 0.1, 0.1, 0]) + runs("new", [0, 0, 0, 0.9])
    assert not decide(recs, "old", "new", coverage_margin=0.02).ship
    # a success on one side: coverage is not asked
    recs = runs("old", [0, 0, 0, 0], success=True) + runs("new", [0.9, 0.9, 0.9, 0.9])
    assert not decide(recs, "old", "new", coverage_margin=0.02).ship
    # unpaired starts and missing coverage are refused
    recs = runs("old", [0, 0]) + runs("new", [0.5, 0.5])
    recs[3]["seed"] = 7
    with pytest.raises(ValueError, match="cannot be paired"):
        decide(recs, "old", "new", coverage_margin=0.02)
    recs = runs("old", [0, 0]) + runs("new", [0.5, 0.5])
    del recs[0]["coverage"]
    with pytest.raises(ValueError, match="no final coverage"):
        decide(recs, "old", "new", coverage_margin=0.02)
    with pytest.raises(ValueError, match="coverage_margin"):
        decide(recs, "old", "new", coverage_margin=1.5)


def _info(root: Path) -> dict:
    return json.loads((root / "meta" / "info.json").read_text())


def _lines(path: Path) -> int:
    return len(path.read_text().splitlines()) if path.is_file() else 0


def test_the_tail_of_the_schedule_is_the_presets():
    from lerobot_gcs_push.improve.training import cosine_lr

    # Hand-computed: linear warm-up over 10 steps, then half a cosine to zero at step 110.
    assert cosine_lr(5, 110, 2e-4, 10) == pytest.approx(1e-4)
    assert cosine_lr(10, 110, 2e-4, 10) == pytest.approx(2e-4)
    assert cosine_lr(60, 110, 2e-4, 10) == pytest.approx(1e-4)
    assert cosine_lr(110, 110, 2e-4, 10) == pytest.approx(0.0, abs=1e-12)


def test_a_state_file_resumes_from_a_clone_elsewhere(tmp_path, monkeypatch):
    from lerobot_gcs_push.improve import ImproveConfig, Improver, StopConfig

    # Made in one checkout with absolute paths inside it; the copy moves to another checkout.
    cfg = {"train_config": str(ROOT / "configs" / "policy" / "diffusion_cpu.json"), "work_dir": str(tmp_path / "w")}
    first, second = tmp_path / "a", tmp_path / "b"
    for root in (first, second):
        (root / "state").mkdir(parents=True)
    monkeypatch.chdir(first)
    made = Improver(ImproveConfig(policy=str(first / "pol"), state_dir="state", **cfg))
    made.state.save()
    stored = json.loads((first / "state" / "state.json").read_text())["settings"]
    assert stored["policy"] == "pol"
    shutil.copy(first / "state" / "state.json", second / "state" / "state.json")
    monkeypatch.chdir(second)
    Improver(ImproveConfig(policy="pol", state_dir="state", **cfg))  # the same settings
    # The stop targets may change on resume (not a setting); the state keeps the latest, for the curve.
    looser = Improver(ImproveConfig(policy="pol", state_dir="state", stop=StopConfig(time_ratio=1.3), **cfg))
    looser.state.save()
    assert json.loads((second / "state" / "state.json").read_text())["stop"]["time_ratio"] == 1.3
    with pytest.raises(ValueError, match="policy"):
        Improver(ImproveConfig(policy="other", state_dir="state", **cfg))


def test_a_run_begun_before_hard_v2_keeps_its_hard_sampler(tmp_path, monkeypatch):
    from lerobot_gcs_push.improve import ImproveConfig, Improver

    monkeypatch.chdir(ROOT)
    same = {"policy": str(tmp_path / "pol"), "state_dir": str(tmp_path / "state"), "work_dir": str(tmp_path / "w")}
    Improver(ImproveConfig(**same)).state.save()
    # A state file as written before the field existed (the from-nothing run's, which used `hard`).
    path = tmp_path / "state" / "state.json"
    data = json.loads(path.read_text())
    assert data["settings"].pop("hard_sampler") == "hard_v2"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match="hard_sampler"):
        Improver(ImproveConfig(**same))  # today's default would change what the old run's stages compute
    assert Improver(ImproveConfig(hard_sampler="hard", **same)).cfg.hard_sampler == "hard"
    with pytest.raises(ValueError, match="unknown sampler"):
        ImproveConfig(hard_sampler="hardest")


def _pretrained(path: Path, value: float) -> None:
    """A stand-in LeRobot pretrained_model folder whose one weight tells which training made it."""
    import torch
    from safetensors.torch import save_file

    path.mkdir(parents=True, exist_ok=True)
    (path / "config.json").write_text(json.dumps({"type": "diffusion"}))
    save_file({"w": torch.full((2,), value)}, path / "model.safetensors")


def _forked(fn) -> int:
    """Run `fn` in a forked child; its wait status. A child killed with SIGKILL runs no `finally` and saves
    nothing more, as after an OOM kill."""
    import traceback
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # fork() of a multi-threaded process
        pid = os.fork()
    if pid == 0:
        code = 0
        try:
            fn()
        except BaseException:
            traceback.print_exc()
            code = 1
        os._exit(code)
    return os.waitpid(pid, 0)[1]


def test_the_stage_runner_resumes_after_kill_9_inside_each_stage(tmp_path, monkeypatch):
    """The stage runner of `improve` with each stage's work replaced by a stand-in that writes what the
    runner reads (rollout and validation records, the candidate's weights): SIGKILLed inside every stage
    (and, in the decision, between the recorded decision and the copy of the weights) and resumed, each
    stage finishes exactly once, in order; the scores and the decision are the hand-computed ones; the
    work folder is not needed once the decision is recorded. The whole run, with the real stages, is
    `test_improve_from_nothing_resumes_after_kill_9_inside_each_stage` (slow)."""
    import signal

    import matplotlib.pyplot  # noqa: F401  (imported once here, not again in every forked run)
    import torch  # noqa: F401
    from safetensors.torch import load_file

    import lerobot_gcs_push.improve as imp
    import lerobot_gcs_push.improve.stages as stages

    state, work, policy = tmp_path / "state", tmp_path / "work", tmp_path / "policy"
    log, result = tmp_path / "log.txt", tmp_path / "result.json"
    kill = [None]  # the step the next run is SIGKILLed in, right after it starts

    def enter(step: str) -> None:
        with open(log, "a") as f:
            f.write(f"{step} start\n")
        if kill[0] == step:
            os.kill(os.getpid(), signal.SIGKILL)

    def leave(step: str) -> None:
        with open(log, "a") as f:
            f.write(f"{step} end\n")

    def records(path: Path, recs: list[dict]) -> None:
        path.mkdir(parents=True, exist_ok=True)
        (path / "runs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))

    def run_rollouts(self, k):
        enter(f"r{k}.rollouts")
        me = self.cfg.policy
        if k == 1:  # by hand: 1/2 without and with disturbances; 30 s against GCS's 20 s; regrets 1, 3, 5, 7 m
            recs = [
                {"policy": "gcs-open-loop", "disturbances": False, "success": True, "sim_time_s": 20.0},
                {"policy": me, "disturbances": False, "success": True, "sim_time_s": 30.0, "regret": 1.0},
                {"policy": me, "disturbances": False, "success": False, "sim_time_s": 60.0, "regret": 3.0},
                {"policy": me, "disturbances": True, "success": False, "sim_time_s": 60.0, "regret": 5.0},
                {"policy": me, "disturbances": True, "success": True, "sim_time_s": 40.0, "regret": 7.0},
            ]
        else:  # every run a success, as fast as GCS: the targets are met
            recs = [{"policy": "gcs-open-loop", "disturbances": False, "success": True, "sim_time_s": 20.0}] + [
                {"policy": me, "disturbances": d, "success": True, "sim_time_s": 20.0} for d in (False, True)
            ]
        for folder in self.folders(k):
            records(folder, recs)
        self.state.stages[f"r{k}.rollouts"]["scores"] = self.scores(k)
        leave(f"r{k}.rollouts")

    def run_finetune(self, k):
        enter(f"r{k}.finetune")
        _pretrained(self.candidate(k), float(k))
        leave(f"r{k}.finetune")

    def run_validation(self, k):
        enter(f"r{k}.validation")
        for folder in self.dirs(k):  # the candidate 3 of 3 in each set, the current policy 0
            records(folder, [
                {"policy": p, "disturbances": False, "success": ok, "sim_time_s": 25.0 if ok else 60.0,
                 "initial_condition_index": 0, "run": i}
                for p, ok in ((self.cfg.policy, False), (str(self.finetune.candidate(k)), True)) for i in range(3)
            ])  # fmt: skip
        leave(f"r{k}.validation")

    def plain(step: str, body=lambda self: None):
        def stage(self, *k):
            name = f"r{k[0]}.{step}" if k else step
            enter(name)
            body(self)
            leave(name)

        return stage

    real_export = stages.export_policy

    def export_policy(src, dst, **kw):
        enter("export")
        real_export(src, dst, **kw)
        leave("export")

    monkeypatch.setattr(stages.Base, "dataset", plain("base.demonstrations"))
    monkeypatch.setattr(stages.Base, "train", plain("base.train", lambda self: _pretrained(policy, 0.0)))
    monkeypatch.setattr(stages.Rollouts, "run", run_rollouts)
    monkeypatch.setattr(stages.Collect, "run", plain("collect"))
    monkeypatch.setattr(stages.Merge, "run", plain("merge"))
    monkeypatch.setattr(stages.Finetune, "run", run_finetune)
    monkeypatch.setattr(stages.Validation, "run", run_validation)
    monkeypatch.setattr(stages, "export_policy", export_policy)  # the decision is the real one

    def improve(**kw) -> int:
        cfg = imp.ImproveConfig(
            policy=str(policy), state_dir=str(state), work_dir=str(work), name="t_stages",
            train_config=str(ROOT / "configs" / "policy" / "diffusion_cpu.json"),
            round=imp.RoundConfig(hard=1, uniform=1), validation=imp.ValidationConfig(hard=1, uniform=1, runs=3),
            stop=imp.StopConfig(max_rounds=3), **kw,
        )  # fmt: skip
        return _forked(lambda: result.write_text(json.dumps(imp.improve(cfg))))

    def stages() -> dict:
        return json.loads((state / "state.json").read_text())["stages"]

    for stage, step in [
        ("base.demonstrations", "base.demonstrations"), ("base.train", "base.train"), (None, None),
        ("r1.rollouts", "r1.rollouts"), ("r1.collect", "r1.collect"), ("r1.merge", "r1.merge"),
        ("r1.finetune", "r1.finetune"), ("r1.validation", "r1.validation"), ("r1.decision", "export"),
    ]:  # fmt: skip
        kill[0] = step
        if step is None:  # a run asked to stop after the first training, then continued
            assert improve(stop_after="base.train") == 0
            assert json.loads(result.read_text())["stopped"] == "after base.train"
            assert list(stages()) == ["base.demonstrations", "base.train"] and stages()["base.train"]["done"]
            continue
        status = improve()
        assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL, f"{stage}: {status}"
        st = stages()
        assert stage in st and not st[stage]["done"], f"the kill meant for {stage} came at {st}"
    # Killed between the decision and the copy: the decision is on record, the old weights in place.
    assert stages()["r1.decision"]["decision"]["ship"]
    assert load_file(policy / "model.safetensors")["w"].tolist() == [0.0, 0.0]
    shutil.rmtree(work)  # a fresh machine, with the state and policy folders only
    kill[0] = None
    assert improve() == 0
    assert json.loads(result.read_text())["stopped"] == "targets met on round 2's rollouts"

    saved = json.loads((state / "state.json").read_text())
    names = ["base.demonstrations", "base.train", *(f"r1.{s}" for s in imp.STAGES), "r2.rollouts"]
    assert list(saved["stages"]) == names and all(saved["stages"][n]["done"] for n in names)
    assert all(saved["stages"][n]["wall_s"] > 0 for n in names)
    lines = log.read_text().splitlines()
    for step in [n for n in names if n != "r1.decision"] + ["export"]:  # killed once each but r2's
        assert lines.count(f"{step} end") == 1, step
        assert lines.count(f"{step} start") == (1 if step == "r2.rollouts" else 2), step
    hard = saved["stages"]["r1.rollouts"]["scores"]["hard"]
    assert hard == pytest.approx(
        {"without": 0.5, "with": 0.5, "time_ratio": 1.5, "regret_mean": 4.0, "regret_p95": 6.7}
    )  # p95 of 1, 3, 5, 7 by linear interpolation: 5 + 0.85 * 2
    r1, r2 = saved["rounds"]
    assert r1["round"] == 1 and r1["shipped"] and r1["decision"]["reason"] == "6 more successes (margin 3)"
    assert r1["winner_by_set"]["hard"]["successes"] == 3
    assert r2["round"] == 2 and r2["targets_met"] and not r2["shipped"]
    # Round 1's candidate (weight 1) shipped into the policy folder in fp16, and nothing else is left of it.
    shipped = load_file(policy / "model.safetensors")["w"]
    assert shipped.tolist() == [1.0, 1.0] and str(shipped.dtype) == "torch.float16"
    assert not (state / "r1" / "candidate").exists()
    assert (state / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_improve_from_nothing_resumes_after_kill_9_inside_each_stage(tmp_path):
    """Base demonstrations, first training, and round 1's rollouts, collect, fine-tune and validation,
    each SIGKILLed mid-stage and resumed; after the fine-tune's kill the work folder and the datasets are
    wiped, as on a fresh machine with only the state and policy folders. Nothing is lost or duplicated,
    the rebuilt data equals the first, training continues from the committed checkpoint, and the decision
    is the rule's."""
    home = Path(os.environ["HF_LEROBOT_HOME"])
    state, work, policy = tmp_path / "state", tmp_path / "work", tmp_path / "policy"
    cmd = gcs_push(
        "improve", f"--policy={policy}", f"--state_dir={state}", f"--work_dir={work}", "--name=t_improve",
        "--base.episodes=12", "--base.steps=4", "--save_freq=2", "--round.hard=2", "--round.uniform=1",
        "--round.steps=4", "--round.timeout_s=4", "--validation.hard=2", "--validation.uniform=1",
        "--validation.runs=1", "--stop.max_rounds=1", "--workers=2",
    )  # fmt: skip
    base, r1 = home / "local" / "t_improve_base", home / "local" / "t_improve_r1"
    kills = {
        "base.demonstrations": lambda: any(base.with_name(base.name + ".shards").glob("shard_*")),
        "base.train": lambda: (work / "train" / "base_train" / "checkpoints" / "last").exists(),
        "r1.rollouts": lambda: _lines(work / "r1" / "rollouts_hard" / "runs.jsonl") >= 1,
        "r1.collect": lambda: any(r1.with_name(r1.name + ".work").glob("episode_*.npz")),
        "r1.finetune": lambda: (state / "r1_finetune.partial" / "step.json").is_file(),
        "r1.validation": lambda: _lines(work / "r1" / "validation_hard" / "runs.jsonl") >= 1,
    }
    for stage, ready in kills.items():
        kill_when(cmd, ready, timeout_s=600)
        st = json.loads((state / "state.json").read_text())["stages"]
        assert stage in st and not st[stage]["done"], f"the kill meant for {stage} came at {st}"
        if stage != "r1.finetune":
            continue
        # Every rollout exactly once (GCS beside the policy, which also ran with disturbances), and a
        # labelled dataset from the kept list; then the machine is "replaced".
        for folder, n in (("rollouts_hard", 2 + 4), ("rollouts_uniform", 1 + 2)):
            recs = [json.loads(x) for x in (work / "r1" / folder / "runs.jsonl").read_text().splitlines()]
            keys = {(r["policy"], r["disturbances"], r["initial_condition_index"], r["run"]) for r in recs}
            assert len(recs) == len(keys) == n, folder
        assert _info(base)["total_episodes"] == 12
        states = json.loads((state / "r1" / "branch_states.json").read_text())
        labelled = _info(r1)["total_episodes"]
        assert 0 < labelled <= len(states)
        shutil.rmtree(work)
        for d in home.glob("local/t_improve_*"):
            shutil.rmtree(d) if d.is_dir() else d.unlink()
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=1200)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "stopped: 1 rounds run" in out.stdout

    saved = json.loads((state / "state.json").read_text())
    names = ["base.demonstrations", "base.train"] + [
        f"r1.{s}" for s in ("rollouts", "collect", "merge", "finetune", "validation", "decision")
    ]
    assert list(saved["stages"]) == names and all(saved["stages"][n]["done"] for n in names)
    assert all(saved["stages"][n]["wall_s"] > 0 for n in names)
    assert (state / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"  # round 1's rollouts drawn
    # Rebuilt from the kept list and the base's seed: the same episode counts; the merge holds both.
    assert _info(base)["total_episodes"] == 12 and _info(r1)["total_episodes"] == labelled
    assert _info(home / "local" / "t_improve_r1_merged")["total_episodes"] == 12 + labelled
    # The fine-tune went on from the committed step-2 weights for the remaining 2 steps, not from scratch.
    job = json.loads((work / "train" / "r1_finetune.job.json").read_text())
    assert job["offset"] == 2 and (work / "train" / "r1_finetune" / "checkpoints" / "000002").is_dir()
    assert not (state / "r1_finetune.partial").exists() and not (state / "r1" / "candidate").exists()
    assert (policy / "model.safetensors").is_file() and not (policy / "step.json").exists()
    for folder, n in (("validation_hard", 4), ("validation_uniform", 2)):
        recs = [json.loads(x) for x in (work / "r1" / folder / "runs.jsonl").read_text().splitlines()]
        assert len(recs) == len({(r["policy"], r["initial_condition_index"], r["run"]) for r in recs}) == n
    # The decision is the one the rounds' script gives on the same validation runs, whatever they hold (no
    # early return: the comparison runs with or without successes). The one case where the two rules
    # differ by design: a candidate without success, which the script ships on an infinite mean time
    # (inf <= 0.95 inf) and `decide` keeps out (test_a_candidate_without_success_never_ships_on_time).
    validation = [json.loads(x) for d in ("validation_hard", "validation_uniform")
                  for x in (work / "r1" / d).joinpath("runs.jsonl").read_text().splitlines()]  # fmt: skip
    candidate = str(state / "r1" / "candidate")
    assert {r["policy"] for r in validation} == {str(policy), candidate}  # the script reads both by these names
    by_hand = subprocess.run(
        [sys.executable, str(ORACLE), "--margin=3", "--time_gain=0.05", str(policy), candidate,
         str(work / "r1" / "validation_hard"), str(work / "r1" / "validation_uniform")],
        capture_output=True, text=True, check=True,
    ).stdout.strip()  # fmt: skip
    assert by_hand in (str(policy), candidate)
    wins = sum(bool(r["success"]) for r in validation if r["policy"] == candidate and not r["disturbances"])
    assert saved["rounds"][0]["shipped"] == (by_hand == candidate and wins > 0)


def test_pusht_rounds_time_the_policy_against_the_closed_loop_expert_on_gym_pushts_resets(tmp_path, monkeypatch):
    """configs/improve/pusht.json as `gcs-push improve --config_path` loads it: the rounds' rollouts ask
    `evaluate` for gym-pusht's own resets (no hard families, no disturbances, the env's 30 s), the policy
    beside the closed-loop expert, and score the policy's mean success time over the expert's by hand; the
    validation runs the one set that holds starts, and the decision ships on coverage where none succeeds."""
    import draccus
    from safetensors.torch import load_file

    import lerobot_gcs_push.evaluation as ev
    import lerobot_gcs_push.improve as imp

    monkeypatch.chdir(ROOT)
    _pretrained(tmp_path / "policy", 0.0)
    cfg = draccus.parse(
        imp.ImproveConfig,
        args=[
            "--config_path=configs/improve/pusht.json",
            f"--policy={tmp_path / 'policy'}",
            f"--state_dir={tmp_path / 's'}",
            f"--work_dir={tmp_path / 'w'}",
        ],
    )
    asked = []

    def evaluate(c):
        asked.append(c)
        out = Path(c.output_dir)
        out.mkdir(parents=True)
        recs = [  # the expert 10 s and 20 s; the policy 15 s, and a failure
            {"policy": "gcs-closed-loop", "disturbances": False, "success": True, "sim_time_s": 10.0, "coverage": 1},
            {"policy": "gcs-closed-loop", "disturbances": False, "success": True, "sim_time_s": 20.0, "coverage": 1},
            {"policy": c.policies[1], "disturbances": False, "success": True, "sim_time_s": 15.0, "coverage": 0.96},
            {"policy": c.policies[1], "disturbances": False, "success": False, "sim_time_s": 30.0, "coverage": 0.5},
        ]
        (out / "runs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))

    monkeypatch.setattr(ev, "evaluate", evaluate)
    improver = imp.Improver(cfg)
    improver.state.stages["r1.rollouts"] = {}
    improver.rollouts.run(1)
    (c,) = asked  # the hard set is empty
    assert c.starts.env_id == "gym_pusht/PushT-v0" and c.starts.sampler == "uniform" and c.num_initial_conditions == 100
    assert c.policies == ["gcs-closed-loop", cfg.policy] and not c.starts.disturbances and c.timeout_s == 30.0
    assert not c.regret  # no cost-to-go through contact
    scores = improver.state.stages["r1.rollouts"]["scores"]
    # 15 s over the expert's mean 15 s; the policy's final coverage (0.96 + 0.5) / 2
    assert scores == {"uniform": {"without": 0.5, "time_ratio": 1.0, "coverage_mean": pytest.approx(0.73)}}
    assert not improver.rollouts.targets_met(1)  # 0.5 < 0.95
    # validation: the uniform set alone (the hard one is empty), its own seed, the policy beside the candidate
    asked.clear()
    _pretrained(improver.finetune.candidate(1), 0.1)
    improver.validation.run(1)
    (c,) = asked
    assert c.starts.sampler == "uniform" and c.num_initial_conditions == 100 and c.runs == 1
    assert c.starts.seed == 7016 and c.policies == [cfg.policy, str(improver.finetune.candidate(1))]
    assert Path(c.output_dir) == tmp_path / "w" / "r1" / "validation_uniform"
    assert improver.validation.dirs(1) == [Path(c.output_dir)]
    # decision: neither succeeds; the config's coverage_margin ships the candidate that covers more
    # (0.175 -> 0.2 on four paired starts, higher on 2, lower on 1), and its weights replace the policy's
    cov = {cfg.policy: [0, 0, 0.5, 0.2], str(improver.finetune.candidate(1)): [0.1, 0, 0.6, 0.1]}
    recs = [
        {"policy": p, "disturbances": False, "initial_condition_index": i, "run": 0, "seed": i, "success": False,
         "sim_time_s": 30.0, "coverage": x}
        for p, xs in cov.items() for i, x in enumerate(xs)
    ]  # fmt: skip
    (Path(c.output_dir) / "runs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    improver.state.stages["r1.decision"] = {}
    improver.decision.run(1)
    (r1,) = improver.state.rounds
    assert r1["shipped"] and "neither has a success" in r1["decision"]["reason"]
    assert load_file(Path(cfg.policy) / "model.safetensors")["w"].float().tolist() == pytest.approx([0.1, 0.1], 1e-3)
    assert not improver.finetune.candidate(1).exists()
    assert cfg.validation.coverage_margin == 0.02  # fixed before round 2's validation
    with pytest.raises(ValueError, match="no hard families"):
        imp.ImproveConfig(env_id="gym_pusht/PushT-v0", train_config=cfg.train_config)
    with pytest.raises(ValueError, match="coverage_margin needs a slider that turns"):
        imp.ImproveConfig(train_config=cfg.train_config, validation=imp.ValidationConfig(coverage_margin=0.02))
    with pytest.raises(ValueError, match="no disturbances"):
        imp.ImproveConfig(
            env_id="gym_pusht/PushT-v0",
            train_config=cfg.train_config,
            round=imp.RoundConfig(hard=0),
            validation=imp.ValidationConfig(hard=0),
        )


def test_pusht_rounds_start_from_the_committed_base_and_replay_its_demonstrations(tmp_path, monkeypatch):
    """configs/improve/pusht.json: the rounds start from base 1000's committed weights (copied into the
    policy folder, fp16, never moved), every merge replays the pool that base trained on (the first
    `base.episodes` of `base.lists`, in order, no planning), collect labels at most 4 states a rollout and
    keeps their episodes' replay list, a round's labelled states are rebuilt by replay from it, and a run
    on its way whose policy folder is gone is refused rather than begun again from nothing."""
    import draccus
    import torch
    from safetensors.torch import load_file

    import lerobot_gcs_push.generate as gen
    import lerobot_gcs_push.improve as imp
    from lerobot_gcs_push.improve.state import STATE_FILE, State
    from lerobot_gcs_push.improve.workspace import Workspace

    monkeypatch.chdir(ROOT)
    _pretrained(tmp_path / "base", 0.3)
    (tmp_path / "base" / "step.json").write_text('{"step": 8000}')

    def parse(*extra):
        return draccus.parse(
            imp.ImproveConfig,
            args=[
                "--config_path=configs/improve/pusht.json",
                f"--policy={tmp_path / 'policy'}",
                f"--from_policy={tmp_path / 'base'}",
                f"--state_dir={tmp_path / 's'}",
                f"--work_dir={tmp_path / 'w'}",
                *extra,
            ],
        )

    class Stop(Exception):
        pass

    def stage(self, name, run):
        raise Stop(name)

    monkeypatch.setattr(Workspace, "stage", stage)
    with pytest.raises(Stop, match=r"^r1\.rollouts$"):  # no base stages: straight to round 1
        imp.Improver(parse()).run()
    w = load_file(tmp_path / "policy" / "model.safetensors")["w"]
    assert w.dtype == torch.float16 and torch.equal(w, torch.full((2,), 0.3).half())
    assert not (tmp_path / "policy" / "step.json").exists()

    # collect: 4 states a rollout at most, and the labelled episodes' replay list kept beside the states
    import lerobot_gcs_push.improve.collect as active

    monkeypatch.setenv("HF_LEROBOT_HOME", str(tmp_path / "home"))
    improver = imp.Improver(parse())
    for out in improver.rollouts.folders(1)[1:]:
        out.mkdir(parents=True)
        (out / "runs.jsonl").write_text("")
    asked = []

    def collect(c):
        asked.append(c)
        root = tmp_path / "home" / c.output.repo_id
        (root / "meta").mkdir(parents=True)
        root.with_name(root.name + ".branch_states.json").write_text('["states"]')
        (root / "meta" / "gcs_push_replay.json").write_text('["episodes"]')

    monkeypatch.setattr(active, "collect", collect)
    improver.collect.run(1)
    assert asked[0].max_per_run == 4 and asked[0].rollouts == [str(improver.rollouts.folders(1)[1])]
    assert json.loads(improver.collect.states_file(1).read_text()) == ["states"]
    assert json.loads(improver.collect.replay_file(1).read_text()) == ["episodes"]
    shutil.rmtree(tmp_path / "s" / "r1")

    made = []
    monkeypatch.setattr(gen, "generate", made.append)
    monkeypatch.setattr(gen, "merge_datasets", lambda *a, **k: None)
    lists = [json.loads((ROOT / p).read_text()) for p in parse().base.lists]
    pool = [e for lst in lists for e in lst]
    assert len(lists[0]) < 300 < len(pool)  # the cut below crosses from the first list into the second
    improver = imp.Improver(parse("--base.episodes=300"))
    r1 = tmp_path / "s" / "r1"
    r1.mkdir(parents=True)
    (r1 / "branch_states.json").write_text(json.dumps([{"pusht_state": e["pusht_state"]} for e in pool[:2]]))
    (r1 / "replay.json").write_text(json.dumps(pool[5:7]))
    improver.merge.run(1)
    base, states = made
    assert base.expert.mode == "replay" and base.episodes == 300
    assert json.loads(Path(base.starts.initial_conditions).read_text()) == pool[:300]
    assert states.expert.mode == "replay" and Path(states.starts.initial_conditions) == r1 / "replay.json"
    (r1 / "replay.json").unlink()  # a round collected before the list was kept: labelled again
    made.clear()
    improver.merge.run(1)
    assert made[1].expert.mode == "closed-loop" and Path(made[1].starts.initial_conditions) == r1 / "branch_states.json"
    with pytest.raises(ValueError, match="hold 1000 episodes, base.episodes asks for 1001"):
        imp.Improver(parse("--base.episodes=1001")).base.dataset()

    shutil.rmtree(tmp_path / "policy")  # a fresh clone in which a round had shipped and the policy was not committed
    state = State.load(tmp_path / "s" / STATE_FILE)
    state.stages = {f"r1.{n}": {"done": True, "wall_s": 1.0} for n in imp.STAGES}
    state.rounds = [{"round": 1, "shipped": True}]
    state.save()
    with pytest.raises(FileNotFoundError, match="holds no policy although"):
        imp.Improver(parse()).run()
    assert not (tmp_path / "policy").exists()
