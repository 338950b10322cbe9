"""Is it the demonstrations or the compute? LeRobot's DiffusionPolicy on gym-pusht's *state* (the T's 8
keypoints and the agent), trained on the same optimal demonstrations as the image bases.

The image bases reach no success at 8000 steps of batch 32 (about 2 % of the samples LeRobot's
`diffusion_pusht` saw); a ResNet learning the T's pose from pixels is most of that cost. Without pixels a
step is cheap, so this asks whether a policy imitating these demonstrations succeeds at all once it has
seen enough samples. Not a shipped policy: `lerobot-eval --env.type=pusht` gives pixels.

    python experiments/pusht/state_policy.py [STEPS] [EPISODES] [EVAL_SEED] [EVAL_N]

Replays the first EPISODES (default 1000) demonstrations of `demos/seed4800-4803.json` in gym-pusht with
`obs_type="environment_state_agent_pos"` (each must end at its success, as recorded), trains STEPS
(default 20000) of batch 64 on one thread, and rolls the policy out on EVAL_N (default 50) of gym-pusht's
own resets, seeds EVAL_SEED.. (default 9970, used by no choice); success and max coverage at 5000-step
intervals and at the end, written to outputs/state_policy/result.json (the run of 2026-12-06 with the
defaults: `state_policy.json` beside this file).
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import gym_pusht  # noqa: F401  (registers the env)
import gymnasium as gym
import numpy as np
import torch

from lerobot_gcs_push.pusht.env import GYM_PUSHT_ID, GYM_PUSHT_STEPS
from lerobot_gcs_push.pusht.frame import ARENA_PX, reset_to_state

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
from count_table import SEEDS  # noqa: E402  (the first pool, in its order: base 1000's lists)

LISTS = [HERE / "demos" / f"seed{s}.json" for s in SEEDS]
OUT = Path("outputs/state_policy")
N_OBS, HORIZON, N_ACTION = 2, 16, 8
SCALE = ARENA_PX  # every input and output mapped from gym-pusht's [0, 512] px to [-1, 1]


def make_env():
    return gym.make(GYM_PUSHT_ID, obs_type="environment_state_agent_pos", max_episode_steps=GYM_PUSHT_STEPS)


def observe(obs) -> np.ndarray:
    return np.concatenate([obs["agent_pos"], obs["environment_state"]]).astype(np.float32)


def replay(episodes: int) -> list[tuple[np.ndarray, np.ndarray]]:
    demos = [d for path in LISTS for d in json.loads(path.read_text())][:episodes]
    env, out = make_env(), []
    for k, demo in enumerate(demos):
        obs, _ = env.reset(options={"reset_to_state": reset_to_state(demo["pusht_state"])})
        observations, success = [], False
        for action in demo["actions"]:
            observations.append(observe(obs))
            obs, _, _, _, info = env.step(np.asarray(action, np.float64))
            success = info["is_success"]
        if not success:
            raise SystemExit(f"demonstration {k} did not end at its success on replay")
        out.append((np.stack(observations), np.asarray(demo["actions"], np.float32)))
    return out


def windows(episodes) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """LeRobot's sampling: the observations before t (the first repeated), the actions from t (the last
    repeated and marked as padding), and the last frames no chunk is executed from left out."""
    obs, act, pad = [], [], []
    drop = HORIZON - N_ACTION - N_OBS + 1
    for o, a in episodes:
        n = len(a)
        for t in range(max(n - drop, 1)):
            oi = np.clip(np.arange(t - N_OBS + 1, t + 1), 0, n - 1)
            ai = np.arange(t, t + HORIZON)
            obs.append(o[oi])
            act.append(a[np.clip(ai, 0, n - 1)])
            pad.append(ai >= n)
    norm = lambda x: torch.from_numpy(np.stack(x) / SCALE * 2 - 1).float()  # noqa: E731
    return norm(obs), norm(act), torch.from_numpy(np.stack(pad))


def make_policy():
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig
    from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy

    cfg = DiffusionConfig(
        input_features={
            "observation.state": PolicyFeature(FeatureType.STATE, (2,)),
            "observation.environment_state": PolicyFeature(FeatureType.ENV, (16,)),
        },
        output_features={"action": PolicyFeature(FeatureType.ACTION, (2,))},
        n_obs_steps=N_OBS,
        horizon=HORIZON,
        n_action_steps=N_ACTION,
        down_dims=(64, 128, 256),  # the image preset's
        noise_scheduler_type="DDIM",
        num_train_timesteps=100,
        num_inference_steps=10,
        device="cpu",
    )
    return DiffusionPolicy(cfg)


def evaluate(policy, seed: int, n: int) -> dict:
    policy.eval()
    env, successes, coverage, steps = make_env(), [], [], []
    for k in range(n):
        obs, _ = env.reset(seed=seed + k)
        policy.reset()
        best, done, t = 0.0, False, 0
        while not done:
            x = torch.from_numpy(observe(obs) / SCALE * 2 - 1).float()[None]
            with torch.no_grad():
                a = policy.select_action({"observation.state": x[:, :2], "observation.environment_state": x[:, 2:]})
            obs, reward, terminated, truncated, info = env.step(((a[0].numpy() + 1) / 2 * SCALE).astype(np.float64))
            best, t = max(best, float(reward)), t + 1
            done = terminated or truncated
        successes.append(bool(info["is_success"]))
        coverage.append(best)
        steps.append(t)
    policy.train()
    won = [s for s, ok in zip(steps, successes) if ok]
    return {
        "success": float(np.mean(successes)),
        "avg_max_reward": float(np.mean(coverage)),
        "steps_of_successes_mean": float(np.mean(won)) if won else None,
    }


def main(steps: int = 20000, episodes: int = 1000, eval_seed: int = 9970, eval_n: int = 50) -> None:
    torch.set_num_threads(1)
    torch.manual_seed(0)
    OUT.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    obs, act, pad = windows(replay(episodes))
    print(f"{episodes} demonstrations replayed to success: {len(obs)} samples, {time.perf_counter() - t0:.0f} s")
    policy = make_policy()
    opt = torch.optim.AdamW(policy.parameters(), lr=1e-4, betas=(0.95, 0.999), eps=1e-8, weight_decay=1e-6)
    warm = 500
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda s: s / warm if s < warm else 0.5 * (1 + math.cos(math.pi * (s - warm) / max(steps - warm, 1)))
    )
    gen = torch.Generator().manual_seed(0)
    result = {"steps": steps, "episodes": episodes, "samples": len(obs), "eval_seed": eval_seed, "eval_n": eval_n}
    result["evaluations"], losses, t0 = [], [], time.perf_counter()
    for step in range(1, steps + 1):
        i = torch.randint(len(obs), (64,), generator=gen)
        batch = {
            "observation.state": obs[i][..., :2],
            "observation.environment_state": obs[i][..., 2:],
            "action": act[i],
            "action_is_pad": pad[i],
        }
        loss, _ = policy.forward(batch)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), 10.0)
        opt.step()
        sched.step()
        losses.append(loss.item())
        if step % 500 == 0:
            print(f"step {step}: loss {np.mean(losses[-500:]):.4f}, {time.perf_counter() - t0:.0f} s", flush=True)
        if step % 5000 == 0 or step == steps:
            score = evaluate(policy, eval_seed, eval_n) | {"step": step, "loss": float(np.mean(losses[-500:]))}
            result["evaluations"].append(score)
            print(score, flush=True)
            (OUT / "result.json").write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:5]))
