"""LeRobot's DiffusionPolicy on gym-pusht's keypoints, trained on a CPU from replay lists, and saved as a
`pretrained_model` folder that `lerobot-eval --env.type=pusht --env.obs_type=environment_state_agent_pos`
loads as it is.

Why not `lerobot-train`: on one CPU thread its data loader (a LeRobotDataset query per sample) costs as much
as the step of this small model; here every frame sits in memory and a step is the model's alone (about
0.9 M samples an hour on one thread). The model, its normalisation (MIN_MAX from the data's own statistics,
or a fine-tuned base's, `init_from`; keypoints included: LeRobot's diffusion default leaves `ENV` features
unnormalised) and LeRobot's sampling (`n_obs_steps` frames up to t, `horizon` actions from the first of
them, padded at both ends, `drop_n_last_frames` left out) are LeRobot's; the schedule is the preset's
(AdamW, cosine with warm-up), with an EMA of the weights (Chi et al. 2023's, diffusers' power schedule),
which is what is saved.

Nothing is lost to a kill: every `save_every` steps the whole state goes to `output_dir/checkpoint.pt` (fp32,
this machine), and on request (`partial_dir`) to a small fp16 copy another machine resumes from. Each step
draws its batch and its noise from a generator seeded by (seed, step), so a resumed run draws what an
unbroken one would have.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from lerobot_gcs_push.pusht import keypoint_data
from lerobot_gcs_push.pusht.keypoint_data import ACTION, ENV_STATE, STATE

PRESET = "configs/policy/diffusion_pusht_keypoints.json"
CHECKPOINT = "checkpoint.pt"
PARTIAL_WEIGHTS, PARTIAL_STATE = "partial.safetensors", "partial.json"
EPS = 1e-8  # LeRobot's MIN_MAX normaliser's


@dataclass
class KeypointDataConfig:
    # Replay lists (`gcs-push generate`'s meta/gcs_push_replay.json), in order.
    lists: list[str] = field(default_factory=list)
    # The first this many of their episodes; None: all.
    episodes: int | None = None
    # Where the replayed arrays are kept, under the hash of what was replayed.
    cache_dir: str = "outputs/keypoints"
    # Learn each frame's command this many frames later (the episode's last past its end): a proxy for
    # commands that lead further, measured without planning the pool again.
    label_shift: int = 0
    # Frames after each demonstration's success in which the agent is held where it was (`keypoint_data.replay`):
    # what stopping at the goal looks like, which a demonstration that ends at the threshold does not show.
    hold_frames: int = 0


@dataclass
class ScheduleConfig:
    # None: the preset's (lerobot-train's `steps`, `batch_size`; the policy's `optimizer_lr`,
    # `scheduler_warmup_steps`).
    steps: int | None = None
    batch_size: int | None = None
    lr: float | None = None
    warmup_steps: int | None = None
    # EMA of the weights, decay 1 - (1 + step) ** -ema_power up to ema_max (0: no EMA, the weights saved as
    # trained).
    ema_power: float = 0.75
    ema_max: float = 0.9999
    grad_clip_norm: float = 10.0
    save_every: int = 1000


@dataclass
class ModelConfig:
    # The UNet's channels per level (`DiffusionConfig.down_dims`); None: the preset's. Sizes are compared at
    # equal samples without a second preset to keep in step with the first.
    down_dims: list[int] | None = None


@dataclass
class TrainKeypointsConfig:
    data: KeypointDataConfig = field(default_factory=KeypointDataConfig)
    schedule: ScheduleConfig = field(default_factory=ScheduleConfig)
    model: ModelConfig = field(default_factory=ModelConfig)
    # A lerobot-train config (`configs/policy/`): its `policy` is the model, trained the same way by
    # `lerobot-train --config_path=...` on a GPU.
    preset: str = PRESET
    # Where the checkpoint (every `save_every` steps, resumed from), the log and `pretrained_model` go.
    output_dir: str = "outputs/train/pusht_keypoints"
    # Also write the small state another machine resumes from here (fp16), at every save; None: not.
    partial_dir: str | None = None
    # A keypoint policy's pretrained_model folder to fine-tune (a round of expert takeover): the model, its
    # weights and EMA start as the base's, and the data is normalised with the base's statistics (read from
    # its saved preprocessor), not the new data's, so the weights see inputs on the scale they learned. A
    # checkpoint in output_dir still takes precedence (a resumed fine-tune goes on from it). None: from scratch.
    init_from: str | None = None
    seed: int = 1000
    threads: int = 1

    def __post_init__(self) -> None:
        if not self.data.lists:
            raise ValueError("data.lists is empty: give the replay lists to train on")
        for name in ("label_shift", "hold_frames"):
            if getattr(self.data, name) < 0:
                raise ValueError(f"data.{name} must be >= 0, got {getattr(self.data, name)}")
        if self.threads < 1:
            raise ValueError(f"threads must be >= 1, got {self.threads}")
        for name in ("steps", "batch_size", "warmup_steps"):
            value = getattr(self.schedule, name)
            if value is not None and value < (0 if name == "warmup_steps" else 1):
                raise ValueError(f"schedule.{name} must be positive, got {value}")
        if self.schedule.save_every < 1:
            raise ValueError(f"schedule.save_every must be >= 1, got {self.schedule.save_every}")
        if not 0 <= self.schedule.ema_max < 1:
            raise ValueError(f"schedule.ema_max must be in [0, 1), got {self.schedule.ema_max}")
        dims = self.model.down_dims
        if dims is not None and (not dims or min(dims) < 1):
            raise ValueError(f"model.down_dims must be positive channel counts, got {dims}")
        if dims is not None and self.init_from is not None:
            raise ValueError("model.down_dims with init_from: a fine-tune keeps its base's model")
        if self.init_from is not None:  # refused before the replay, which takes minutes
            from lerobot_gcs_push.pusht.keypoint_base import check_base

            check_base(self.init_from)


def policy_config(preset: str):
    """The preset's DiffusionConfig (draccus decodes it as lerobot-train does)."""
    import draccus
    from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig

    from lerobot_gcs_push.artifacts.shipped import shipped_path

    path = Path(shipped_path(preset))  # the shipped preset where it is not under the working folder
    if not path.is_file():
        raise FileNotFoundError(f"no preset at {path}")
    raw = json.loads(path.read_text())
    policy = dict(raw.get("policy", {}))
    if policy.pop("type", "diffusion") != "diffusion":
        raise ValueError(f"{path}: the keypoint trainer trains a diffusion policy")
    return draccus.decode(DiffusionConfig, policy), raw


def stats_of(data: keypoint_data.Episodes) -> dict[str, dict[str, np.ndarray]]:
    """LeRobot's dataset statistics of each feature (min, max, mean, std)."""
    return {k: {"min": v.min(0), "max": v.max(0), "mean": v.mean(0), "std": v.std(0)} for k, v in data.arrays.items()}


def normalise(x: np.ndarray, stats: dict) -> np.ndarray:
    """LeRobot's MIN_MAX: to [-1, 1] between the feature's min and max."""
    return (2 * (x - stats["min"]) / (stats["max"] - stats["min"] + EPS) - 1).astype(np.float32)


class Windows:
    """LeRobot's training samples of the episodes: for each frame t not among an episode's last
    `drop_n_last_frames`, the `n_obs` observations up to t (the first repeated before the start) and the
    `horizon` actions from t - (n_obs - 1), the first observed frame's (`DiffusionConfig.action_delta_indices`:
    at inference LeRobot runs the chunk from its index n_obs - 1, the action at t). Actions outside the
    episode repeat its first or last and are marked as padding, as LeRobotDataset marks them."""

    def __init__(self, data: keypoint_data.Episodes, stats: dict, n_obs: int, horizon: int, drop_last: int):
        import torch

        self.obs = {k: torch.from_numpy(normalise(data.arrays[k], stats[k])) for k in (STATE, ENV_STATE)}
        self.action = torch.from_numpy(normalise(data.arrays[ACTION], stats[ACTION]))
        starts, ends = data.starts(), data.ends
        t = np.concatenate([np.arange(s, max(e - drop_last, s + 1)) for s, e in zip(starts, ends)])
        episode = np.repeat(np.arange(len(ends)), [max(e - drop_last, s + 1) - s for s, e in zip(starts, ends)])
        self.t, self.first, self.last = t, starts[episode], ends[episode] - 1
        self.n_obs, self.horizon = n_obs, horizon

    def __len__(self) -> int:
        return len(self.t)

    def batch(self, rows: np.ndarray) -> dict:
        import torch

        t, first, last = self.t[rows, None], self.first[rows, None], self.last[rows, None]
        obs_i = np.clip(t + np.arange(-self.n_obs + 1, 1), first, last)
        act_i = t + np.arange(-self.n_obs + 1, -self.n_obs + 1 + self.horizon)
        out = {k: v[torch.from_numpy(obs_i)] for k, v in self.obs.items()}
        out[ACTION] = self.action[torch.from_numpy(np.clip(act_i, first, last))]
        out["action_is_pad"] = torch.from_numpy((act_i < first) | (act_i > last))
        return out


def lr_at(step: int, peak: float, warmup: int, total: int) -> float:
    """The preset's schedule: linear warm-up, then cosine to zero at `total` (LeRobot's diffuser cosine)."""
    if step < warmup:
        return peak * step / max(warmup, 1)
    return peak * 0.5 * (1 + math.cos(math.pi * (step - warmup) / max(total - warmup, 1)))


@dataclass
class Start:
    """What a run starts from, before its first step (or the step it resumes at)."""

    pcfg: object  # the DiffusionConfig
    stats: dict  # the normalisation: the data's, or the base's when fine-tuning
    windows: Windows
    policy: object
    ema: object
    opt: object
    step: int
    data: keypoint_data.Episodes


def prepare(cfg: TrainKeypointsConfig, progress: bool = True) -> Start:
    """The model, its EMA and optimiser (from scratch, seeded, or the base's weights), the normalised data,
    and the step to start at (a checkpoint's, which takes precedence over `init_from`)."""
    import torch
    from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy

    torch.set_num_threads(cfg.threads)
    pcfg, _ = policy_config(cfg.preset)
    if cfg.init_from is not None:
        from lerobot_gcs_push.pusht.keypoint_base import base_config

        pcfg = base_config(cfg.init_from)
    if cfg.model.down_dims is not None:
        pcfg.down_dims = tuple(cfg.model.down_dims)
    pcfg.device = "cpu" if pcfg.device in (None, "cuda") and not torch.cuda.is_available() else pcfg.device
    data = keypoint_data.load(cfg.data.lists, cfg.data.episodes, cfg.data.cache_dir, progress, cfg.data.hold_frames)
    data = data.labels_ahead(cfg.data.label_shift)
    if cfg.init_from is None:
        stats = stats_of(data)
    else:
        from lerobot_gcs_push.pusht.keypoint_base import base_stats

        stats = base_stats(cfg.init_from)
    windows = Windows(data, stats, pcfg.n_obs_steps, pcfg.horizon, pcfg.drop_n_last_frames)

    torch.manual_seed(cfg.seed)  # the initial weights
    policy = DiffusionPolicy(pcfg)
    if cfg.init_from is not None:
        from lerobot_gcs_push.pusht.keypoint_base import base_weights

        policy.load_state_dict(base_weights(cfg.init_from))
    ema = DiffusionPolicy(pcfg)
    ema.load_state_dict(policy.state_dict())
    ema.requires_grad_(False)
    opt = torch.optim.AdamW(
        policy.parameters(), lr=pcfg.optimizer_lr, betas=pcfg.optimizer_betas, eps=pcfg.optimizer_eps,
        weight_decay=pcfg.optimizer_weight_decay,
    )  # fmt: skip
    step = _resume(Path(cfg.output_dir), cfg.partial_dir, policy, ema, opt)
    return Start(pcfg, stats, windows, policy, ema, opt, step, data)


def outside_range(windows: Windows) -> dict[str, float]:
    """Per feature, the share of normalised values outside [-1, 1]: data beyond the statistics' extremes
    (a fine-tune's new data against its base's; actions out there are beyond the sampler's clip)."""
    arrays = {**windows.obs, ACTION: windows.action}
    return {k: round(float((v.abs() > 1).float().mean()), 6) for k, v in arrays.items()}


def train(cfg: TrainKeypointsConfig, progress: bool = True, stop_after_s: float | None = None) -> Path | None:
    """Train (or resume) to the schedule's last step; returns the saved `pretrained_model` folder. With
    `stop_after_s`, a stage: after that much wall time the state is saved and None returned (run it again
    to go on)."""
    import torch
    from tqdm.auto import tqdm

    _, raw = policy_config(cfg.preset)
    sch = cfg.schedule
    steps = sch.steps or int(raw.get("steps", 20000))
    batch_size = sch.batch_size or int(raw.get("batch_size", 64))
    run = prepare(cfg, progress)  # the data first: a list that is not there leaves no output folder behind
    out = Path(cfg.output_dir)
    out.mkdir(parents=True, exist_ok=True)
    pcfg, windows, policy, ema, opt, step = run.pcfg, run.windows, run.policy, run.ema, run.opt, run.step
    peak = sch.lr if sch.lr is not None else pcfg.optimizer_lr
    warmup = sch.warmup_steps if sch.warmup_steps is not None else pcfg.scheduler_warmup_steps
    (out / "train_config.json").write_text(json.dumps(asdict(cfg) | {"resolved": {
        "steps": steps, "batch_size": batch_size, "lr": peak, "warmup_steps": warmup,
        "samples": len(windows), "frames": run.data.frames, "episodes": len(run.data),
        "stats_from": cfg.init_from or "data", "outside_stats_range": outside_range(windows)}}, indent=1))  # fmt: skip
    log = (out / "log.jsonl").open("a")
    losses: list[float] = []
    policy.train()
    bar = tqdm(total=steps, initial=step, desc="training", unit="step", disable=not progress)
    t0 = time.perf_counter()
    while step < steps:
        torch.manual_seed(cfg.seed * 1_000_003 + step)  # the batch and the noise: a function of the step
        rows = torch.randint(len(windows), (batch_size,)).numpy()
        loss, _ = policy.forward(windows.batch(rows))
        for group in opt.param_groups:
            group["lr"] = lr_at(step, peak, warmup, steps)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), sch.grad_clip_norm)
        opt.step()
        step += 1
        _ema_update(ema, policy, step, sch.ema_power, sch.ema_max)
        losses.append(loss.item())
        bar.update(1)
        if step % 50 == 0:
            bar.set_postfix(loss=f"{np.mean(losses[-50:]):.4f}")
        stop = stop_after_s is not None and time.perf_counter() - t0 > stop_after_s and step < steps
        if step % sch.save_every == 0 or step == steps or stop:
            record = {
                "step": step,
                "loss": float(np.mean(losses[-sch.save_every :])),
                "lr": lr_at(step, peak, warmup, steps),
                "s_per_step": (time.perf_counter() - t0) / len(losses),
            }
            log.write(json.dumps(record) + "\n")  # fmt: skip
            log.flush()
            _save(out, cfg.partial_dir, step, policy, ema, opt)
        if stop:
            bar.close()
            return None
    bar.close()
    return export(ema, pcfg, run.stats, out / "pretrained_model")


def export(policy, pcfg, stats: dict, folder: Path) -> Path:
    """`policy` saved with its processors (the data's statistics) as a LeRobot `pretrained_model` folder."""
    import torch
    from lerobot.policies.factory import make_pre_post_processors

    tensors = {k: {s: torch.as_tensor(v, dtype=torch.float32) for s, v in d.items()} for k, d in stats.items()}
    pre, post = make_pre_post_processors(pcfg, dataset_stats=tensors)
    folder.mkdir(parents=True, exist_ok=True)
    policy.save_pretrained(folder)
    pre.save_pretrained(folder)
    post.save_pretrained(folder)
    return folder


def _ema_update(ema, policy, step: int, power: float, cap: float) -> None:
    import torch

    decay = 0.0 if power <= 0 else min(cap, 1 - (1 + step) ** -power)
    with torch.no_grad():
        for e, p in zip(ema.parameters(), policy.parameters()):
            e.mul_(decay).add_(p.detach(), alpha=1 - decay)
        for e, p in zip(ema.buffers(), policy.buffers()):
            e.copy_(p)


def _save(out: Path, partial_dir, step: int, policy, ema, opt) -> None:
    import torch

    tmp = out / (CHECKPOINT + ".tmp")
    torch.save({"step": step, "policy": policy.state_dict(), "ema": ema.state_dict(), "opt": opt.state_dict()}, tmp)
    tmp.replace(out / CHECKPOINT)
    if partial_dir:
        _save_partial(Path(partial_dir), step, policy, ema, opt)


def _save_partial(folder: Path, step: int, policy, ema, opt) -> None:
    """The weights and the EMA in fp16, Adam's second moments in bf16 (squared gradients fall below fp16's
    range); its first moments are left out: at beta1 0.95 they rebuild within tens of steps."""
    import torch
    from safetensors.torch import save_file

    folder.mkdir(parents=True, exist_ok=True)
    tensors = {f"policy.{k}": v.half() for k, v in policy.state_dict().items() if v.is_floating_point()}
    tensors |= {f"ema.{k}": v.half() for k, v in ema.state_dict().items() if v.is_floating_point()}
    names = [n for n, _ in policy.named_parameters()]
    for name, p in zip(names, policy.parameters()):
        state = opt.state.get(p)
        if state:
            tensors[f"exp_avg_sq.{name}"] = state["exp_avg_sq"].to(torch.bfloat16)
    adam_step = next((float(s["step"]) for s in opt.state.values() if "step" in s), 0.0)
    tmp = folder / (PARTIAL_WEIGHTS + ".tmp")
    save_file({k: v.contiguous() for k, v in tensors.items()}, tmp)
    tmp.replace(folder / PARTIAL_WEIGHTS)
    (folder / PARTIAL_STATE).write_text(json.dumps({"step": step, "adam_step": adam_step}))


def _resume(out: Path, partial_dir, policy, ema, opt) -> int:
    """The step to go on from: this machine's checkpoint, or the partial where it is further on."""
    import torch

    local = torch.load(out / CHECKPOINT, weights_only=False) if (out / CHECKPOINT).is_file() else None
    partial = Path(partial_dir) / PARTIAL_STATE if partial_dir else None
    partial_step = json.loads(partial.read_text())["step"] if partial is not None and partial.is_file() else -1
    if local is not None and local["step"] >= partial_step:
        policy.load_state_dict(local["policy"])
        ema.load_state_dict(local["ema"])
        opt.load_state_dict(local["opt"])
        return int(local["step"])
    if partial_step < 0:
        return 0
    from safetensors.torch import load_file

    tensors = load_file(Path(partial_dir) / PARTIAL_WEIGHTS)
    for prefix, model in (("policy.", policy), ("ema.", ema)):
        own = model.state_dict()
        model.load_state_dict({k: tensors[prefix + k].float() if prefix + k in tensors else v for k, v in own.items()})
    meta = json.loads(partial.read_text())
    for name, p in policy.named_parameters():
        if f"exp_avg_sq.{name}" in tensors:
            opt.state[p] = {
                "step": torch.tensor(meta["adam_step"]),
                "exp_avg": torch.zeros_like(p),
                "exp_avg_sq": tensors[f"exp_avg_sq.{name}"].float(),
            }
    return int(partial_step)
