"""`lerobot-train`, run so that a kill costs at most one checkpoint interval, on this machine or another.

LeRobot resumes its own runs (`--resume=true`, optimizer and schedule included) from the checkpoints in
`output_dir`. Those do not travel (the optimizer state is three times the fp16 weights), so every
checkpoint is also exported in fp16 beside the caller's state (`partial`). On a fresh machine training
continues from there for the remaining steps, on the tail of the same schedule: no warm-up, the cosine
decaying from the rate the original schedule had reached (a warm restart at the peak rate undoes what
was learned: run 7).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

from lerobot_gcs_push.artifacts.checkpoints import STEP_FILE, export_policy, is_pretrained_dir
from lerobot_gcs_push.files import atomic_path


@dataclass
class TrainJob:
    # The LeRobot preset (a lerobot-train config file).
    config_path: str
    dataset_repo_id: str
    output_dir: Path
    steps: int
    seed: int
    # Fine-tune from these weights; None trains from scratch.
    init_policy: str | None = None
    # Peak learning rate; None keeps the preset's.
    lr: float | None = None
    # bf16 autocast; None: where the device has bf16 units (`bf16_native`). A property of the machine, like
    # the device, not of what is computed: a job resumed on another machine follows that machine.
    use_amp: bool | None = None
    device: str = "cpu"
    save_freq: int = 500
    log_freq: int = 50
    # fp16 copy of the newest checkpoint, with the step it holds: the cross-machine resume point.
    partial: Path | None = None

    def signature(self) -> dict:
        """What the job computes: a folder made by another job is never resumed as this one."""
        skip = ("output_dir", "device", "use_amp", "save_freq", "log_freq", "partial")
        return {k: str(v) if isinstance(v, Path) else v for k, v in asdict(self).items() if k not in skip}


def checkpoint_step(output_dir: Path) -> int:
    """The step of the newest whole checkpoint in a lerobot-train output folder (0 without one): LeRobot
    points `last` at a checkpoint only once it is written."""
    state = Path(output_dir) / "checkpoints" / "last" / "training_state" / "training_step.json"
    if not state.is_file():
        return 0
    return int(json.loads(state.read_text())["step"])


def partial_step(partial: Path | None) -> int:
    if partial is None or not (partial / STEP_FILE).is_file() or not is_pretrained_dir(partial):
        return 0
    return int(json.loads((partial / STEP_FILE).read_text())["step"])


def cosine_lr(step: int, steps: int, peak: float, warmup: int) -> float:
    """The rate of LeRobot's diffusion preset schedule (diffusers' cosine with linear warm-up) at `step`."""
    if step < warmup:
        return peak * step / max(1, warmup)
    return peak * 0.5 * (1 + math.cos(math.pi * (step - warmup) / max(1, steps - warmup)))


def _preset_schedule(job: TrainJob) -> tuple[float, int]:
    from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig

    policy = json.loads(Path(job.config_path).read_text()).get("policy", {})
    peak = job.lr if job.lr is not None else policy.get("optimizer_lr", DiffusionConfig.optimizer_lr)
    return float(peak), int(policy.get("scheduler_warmup_steps", DiffusionConfig.scheduler_warmup_steps))


def bf16_native(device: str, cpuinfo: str = "/proc/cpuinfo") -> bool:
    """Whether bf16 autocast pays on `device`: on a GPU, and on a CPU with bf16 instructions. A CPU without
    them emulates bf16: on an AMD EPYC without avx512_bf16 (2026-12-05) a PushT step took 30 s of CPU
    against about 1 s on one with it (configs/README.md, "bf16 on CPU")."""
    if not device.startswith("cpu"):
        return device.startswith("cuda")
    try:
        flags = Path(cpuinfo).read_text()
    except OSError:
        return False
    return "avx512_bf16" in flags or "amx_bf16" in flags


def train(job: TrainJob, progress_desc: str = "training") -> Path:
    """Run (or resume) the job to `job.steps`; return its final `pretrained_model` directory."""
    from tqdm.auto import tqdm

    out = Path(job.output_dir)
    meta = out.with_name(out.name + ".job.json")  # the job's signature and its offset
    done = out.with_name(out.name + ".done")
    if meta.is_file() and json.loads(meta.read_text())["signature"] != job.signature():
        raise ValueError(
            f"{out} holds a training with other settings (steps, seed, data, starting weights): delete it, "
            "or choose another work_dir"
        )
    if done.is_file() and meta.is_file():
        return Path(done.read_text().strip())
    # Steps done before this folder's run began (on another machine), so its own steps count from there.
    if checkpoint_step(out) > 0 and meta.is_file():
        offset = json.loads(meta.read_text())["offset"]
        args = [f"--config_path={out}/checkpoints/last/pretrained_model/train_config.json", "--resume=true"]
    else:
        shutil.rmtree(out, ignore_errors=True)  # killed before its first checkpoint: nothing to keep
        offset = partial_step(job.partial)
        if offset >= job.steps:  # another machine finished; only its export and clean-up were cut short
            return job.partial
        args = [
            f"--config_path={job.config_path}",
            f"--dataset.repo_id={job.dataset_repo_id}",
            f"--output_dir={out}",
            f"--job_name={out.name}",
            f"--steps={job.steps - offset}",
            f"--save_freq={job.save_freq}",
            f"--log_freq={job.log_freq}",
            f"--seed={job.seed + offset}",
            f"--policy.use_amp={str(bf16_native(job.device) if job.use_amp is None else job.use_amp).lower()}",
            f"--policy.device={job.device}",
            "--num_workers=1",
        ]
        init = str(job.partial) if offset > 0 else job.init_policy
        if init:
            args.append(f"--policy.path={init}")
        if offset > 0:
            peak, warmup = _preset_schedule(job)
            lr = cosine_lr(offset, job.steps, peak, warmup)
            args += ["--policy.scheduler_warmup_steps=0", f"--policy.optimizer_lr={lr:.3e}"]
        elif job.lr is not None:
            args.append(f"--policy.optimizer_lr={job.lr}")
        with atomic_path(meta) as tmp:
            tmp.write_text(json.dumps({"signature": job.signature(), "offset": offset}))
    local_steps = job.steps - offset
    final = out / "checkpoints" / f"{local_steps:06d}" / "pretrained_model"
    if checkpoint_step(out) < local_steps:
        _run(job, args, out, offset, progress_desc, tqdm)
    if checkpoint_step(out) != local_steps or not is_pretrained_dir(final):
        raise RuntimeError(f"lerobot-train finished without its step-{local_steps} checkpoint {final}")
    with atomic_path(done) as tmp:
        tmp.write_text(str(final) + "\n")
    return final


def _run(job: TrainJob, args: list[str], out: Path, offset: int, desc: str, tqdm) -> None:
    # OpenMP threads that spin while waiting make training 4-10x slower beside any other work on the
    # cores (configs/README.md, "Shared machines"); passive waiting costs nothing alone.
    env = {"OMP_NUM_THREADS": "2", "OMP_WAIT_POLICY": "PASSIVE"} | os.environ | {"HF_HUB_OFFLINE": "1"}
    log = out.with_name(out.name + ".log")
    log.parent.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "lerobot.scripts.lerobot_train", *args]
    exported = checkpoint_step(out)
    bar = tqdm(total=job.steps, initial=offset + exported, desc=desc, unit="step", dynamic_ncols=True)
    with (
        open(log, "a", buffering=1) as logf,  # line by line: a long run is followed with tail -f
        subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, bufsize=1) as proc,
    ):
        for line in proc.stdout:
            logf.write(line)
            if " step:" in line and " loss:" in line:  # one metrics line per log_freq steps
                bar.update(min(job.log_freq, job.steps - bar.n))
            step = checkpoint_step(out) if job.partial is not None else 0
            if step > exported:
                _export_partial(out, job.partial, offset + step)
                exported = step
        code = proc.wait()
    bar.update(job.steps - bar.n if code == 0 else 0)
    bar.close()
    if code != 0:
        raise RuntimeError(f"lerobot-train exited with {code}; its output is in {log}")


def _export_partial(out: Path, partial: Path, step: int) -> None:
    # The step travels inside the exported folder, which appears whole or not at all.
    export_policy(out / "checkpoints" / "last" / "pretrained_model", partial, overwrite=True, step=step)
