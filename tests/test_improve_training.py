"""`training.train`'s bookkeeping with lerobot-train replaced by a stand-in that records its arguments and
leaves what lerobot-train leaves: what a job resumed on another machine asks LeRobot for, and when it runs
nothing at all. Real lerobot-train runs are in the slow tier (test_lerobot_plugin.py, and the whole
`improve` run in test_improve.py, which resumes a fine-tune the same way)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lerobot_gcs_push.improve import training
from lerobot_gcs_push.improve.training import TrainJob, train

PRESET = Path(__file__).resolve().parents[1] / "configs" / "policy" / "diffusion_cpu.json"


def _pretrained(path: Path, step: int | None = None) -> None:
    path.mkdir(parents=True, exist_ok=True)
    (path / "config.json").write_text("{}")
    (path / "model.safetensors").write_bytes(b"weights")
    if step is not None:
        (path / "step.json").write_text(json.dumps({"step": step}))


@pytest.fixture
def runs(monkeypatch) -> list[list[str]]:
    """The argument lists lerobot-train is started with; each run writes its final checkpoint and `last`."""
    calls = []

    def run(job, args, out, offset, desc, tqdm):
        calls.append(args)
        steps = int(next(a for a in args if a.startswith("--steps=")).split("=")[1])
        ckpt = out / "checkpoints" / f"{steps:06d}"
        _pretrained(ckpt / "pretrained_model")
        (ckpt / "training_state").mkdir()
        (ckpt / "training_state" / "training_step.json").write_text(json.dumps({"step": steps}))
        (out / "checkpoints" / "last").symlink_to(ckpt.name)

    monkeypatch.setattr(training, "_run", run)
    return calls


def _job(tmp_path: Path, **kw) -> TrainJob:
    fields = dict(
        config_path=str(PRESET),
        dataset_repo_id="local/d",
        output_dir=tmp_path / "work" / "job",
        steps=2500,
        seed=7,
        init_policy="/elsewhere/policy",
        lr=2e-4,
        partial=tmp_path / "job.partial",
    )
    return TrainJob(**(fields | kw))


def test_a_job_resumed_from_another_machines_partial_trains_the_rest_on_the_schedules_tail(tmp_path, runs):
    _pretrained(tmp_path / "job.partial", step=1500)  # all a fresh machine has: the fp16 copy at step 1500
    job = _job(tmp_path)
    final = train(job)
    (args,) = runs
    assert final == job.output_dir / "checkpoints" / "001000" / "pretrained_model"
    # By hand: LeRobot's diffusion warm-up is 500 steps, so at step 1500 of 2500 the cosine is half-way down
    # from the peak 2e-4: 1e-4, with no warm-up again; the remaining 1000 steps start from the partial's
    # weights (not the job's initial policy) with the seed moved on by the steps done.
    for arg in ("--steps=1000", "--seed=1507", f"--policy.path={tmp_path / 'job.partial'}",
                "--policy.scheduler_warmup_steps=0", "--policy.optimizer_lr=1.000e-04", "--dataset.repo_id=local/d",
                f"--config_path={PRESET}", f"--output_dir={job.output_dir}"):  # fmt: skip
        assert arg in args, (arg, args)
    assert json.loads(job.output_dir.with_name("job.job.json").read_text())["offset"] == 1500
    assert train(job) == final and len(runs) == 1  # done: nothing runs again
    with pytest.raises(ValueError, match="other settings"):
        train(_job(tmp_path, seed=8))


def test_a_fresh_job_starts_from_its_initial_policy_and_a_finished_partial_runs_nothing(tmp_path, runs):
    job = _job(tmp_path, steps=4)
    train(job)
    (args,) = runs
    assert "--steps=4" in args and "--seed=7" in args and "--policy.path=/elsewhere/policy" in args
    assert "--policy.optimizer_lr=0.0002" in args and not any("warmup" in a for a in args)
    # Another machine trained to the end and was killed before its export: the partial is the result.
    _pretrained(tmp_path / "done.partial", step=4)
    other = _job(tmp_path, steps=4, output_dir=tmp_path / "work" / "other", partial=tmp_path / "done.partial")
    assert train(other) == tmp_path / "done.partial" and len(runs) == 1


def test_bf16_autocast_only_where_the_machine_has_bf16_units(tmp_path, runs):
    from lerobot_gcs_push.improve.training import bf16_native

    plain, bf16 = tmp_path / "plain", tmp_path / "bf16"
    plain.write_text("flags\t\t: fpu sse2 avx2 avx512f\n")
    bf16.write_text("flags\t\t: fpu sse2 avx2 avx512f avx512_bf16\n")
    assert not bf16_native("cpu", str(plain)) and bf16_native("cpu", str(bf16))
    assert bf16_native("cuda:0", str(plain)) and not bf16_native("mps", str(bf16))
    assert not bf16_native("cpu", str(tmp_path / "missing"))
    # The machine decides, so a job moved to another machine is the same job (its signature has no use_amp).
    assert "use_amp" not in _job(tmp_path).signature()
    train(_job(tmp_path, use_amp=False))
    assert "--policy.use_amp=false" in runs[0]
