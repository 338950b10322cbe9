"""`lerobot-train`, run so that a kill costs at most one checkpoint interval, on this machine or another.

LeRobot resumes its own runs (`--resume=true`, optimizer and schedule included) from the checkpoints in
`output_dir`. Those do not travel (the optimizer state is three times the fp16 weights), so every
checkpoint is also exported in fp16 beside the caller's state (`partial`): on a fresh machine training
continues from there for the remaining steps, a warm restart of the schedule, as the rounds' fine-tunes
all were.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from lerobot_gcs_push.checkpoints import export_policy, is_pretrained_dir


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
    lr: float | None = None
    use_amp: bool = True
    device: str = "cpu"
    save_freq: int = 500
    log_freq: int = 50
    # fp16 copy of the newest checkpoint, with the step it holds: the cross-machine resume point.
    partial: Path | None = None


def checkpoint_step(output_dir: Path) -> int:
    """The step of the newest whole checkpoint in a lerobot-train output folder (0 without one)."""
    state = Path(output_dir) / "checkpoints" / "last" / "training_state" / "training_step.json"
    if not state.is_file():
        return 0
    return int(json.loads(state.read_text())["step"])


def partial_step(partial: Path | None) -> int:
    if partial is None or not (partial / "step.json").is_file() or not is_pretrained_dir(partial):
        return 0
    return int(json.loads((partial / "step.json").read_text())["step"])


def train(job: TrainJob, progress_desc: str = "training") -> Path:
    """Run (or resume) the job to `job.steps`; return its final `pretrained_model` directory."""
    from tqdm.auto import tqdm

    out = Path(job.output_dir)
    done = out.with_name(out.name + ".done")
    if done.is_file() and is_pretrained_dir(done.read_text().strip()):
        return Path(done.read_text().strip())
    # Steps done before this folder's run began (on another machine), so its own steps count from there.
    offset_file = out.with_name(out.name + ".offset.json")
    done_here = checkpoint_step(out)
    args = [sys.executable, "-m", "lerobot.scripts.lerobot_train"]
    if done_here > 0:
        offset = json.loads(offset_file.read_text())["offset"] if offset_file.is_file() else 0
        args += [f"--config_path={out}/checkpoints/last/pretrained_model/train_config.json", "--resume=true"]
        start = offset + done_here
        final = out / "checkpoints" / f"{job.steps - offset:06d}" / "pretrained_model"
        if is_pretrained_dir(final):  # killed after its last checkpoint
            done.write_text(str(final) + "\n")
            return final
    else:
        shutil.rmtree(out, ignore_errors=True)  # killed before its first checkpoint: nothing to keep
        init, offset = job.init_policy, partial_step(job.partial)
        if offset > 0:  # another machine's progress: continue from its weights for the rest
            init = str(job.partial)
        out.parent.mkdir(parents=True, exist_ok=True)
        offset_file.write_text(json.dumps({"offset": offset}) + "\n")
        args += [
            f"--config_path={job.config_path}",
            f"--dataset.repo_id={job.dataset_repo_id}",
            f"--output_dir={out}",
            f"--job_name={out.name}",
            f"--steps={job.steps - offset}",
            f"--save_freq={job.save_freq}",
            f"--log_freq={job.log_freq}",
            f"--seed={job.seed + offset}",
            f"--policy.use_amp={str(job.use_amp).lower()}",
            f"--policy.device={job.device}",
            "--num_workers=1",
        ]
        if init:
            args.append(f"--policy.path={init}")
        if job.lr is not None:
            args.append(f"--policy.optimizer_lr={job.lr}")
        start = offset
    final = out / "checkpoints" / f"{job.steps - offset:06d}" / "pretrained_model"
    # OpenMP threads that spin while waiting make training 4-10x slower beside any other work on the
    # cores (configs/README.md, "Shared machines"); passive waiting costs nothing alone.
    env = {"OMP_NUM_THREADS": "2", "OMP_WAIT_POLICY": "PASSIVE"} | os.environ | {"HF_HUB_OFFLINE": "1"}
    log = out.with_name(out.name + ".log")
    log.parent.mkdir(parents=True, exist_ok=True)
    bar = tqdm(total=job.steps, initial=start, desc=progress_desc, unit="step", dynamic_ncols=True)
    exported = checkpoint_step(out) if out.exists() else 0
    with (
        open(log, "a") as logf,
        subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, bufsize=1) as proc,
    ):
        for line in proc.stdout:
            logf.write(line)
            if " step:" in line and " loss:" in line:  # one metrics line per log_freq steps
                bar.update(min(job.log_freq, job.steps - bar.n))
            if job.partial is not None and out.exists():
                step = checkpoint_step(out)
                if step > exported:
                    _export_partial(out, job.partial, offset + step)
                    exported = step
        code = proc.wait()
    if code == 0:
        bar.update(job.steps - bar.n)
    bar.close()
    if code != 0:
        raise RuntimeError(f"lerobot-train exited with {code}; its output is in {log}")
    if not is_pretrained_dir(final):
        raise RuntimeError(f"lerobot-train finished without {final}; its output is in {log}")
    done.write_text(str(final) + "\n")
    return final


def _export_partial(out: Path, partial: Path, step: int) -> None:
    export_policy(out / "checkpoints" / "last" / "pretrained_model", partial, overwrite=True)
    (partial / "step.json").write_text(json.dumps({"step": step}) + "\n")
