"""Issue 48, the demonstration-count table: diffusion policies on 206 / 500 / 1000 optimal gym-pusht
demonstrations, demonstrations only, equal training steps, in stages that survive a fresh machine.

    python experiments/pusht/count_table.py dataset 206   # rebuild local/gcs_pusht_206 from the replay lists
    python experiments/pusht/count_table.py train 206     # train (or resume) to STEPS; kill it any time
    python experiments/pusht/count_table.py validate 206  # the two fixed validation runs -> base_206/validation.json
    python experiments/pusht/count_table.py decide        # the validated bases ranked by the fixed rule

A base is named by its count, with its pool's name before it for a pool other than the first: `steer2_206`
is the first 206 demonstrations of `demos/steer2/`, made from the same starts by the expert steered over two
actions (`ExpertConfig.steer_actions`, 1 when the first pool was made); `count_table.py pool steer2 [SEED ...]`
plans its list for each of the first pool's seeds given (4800 alone by default).

Every choice here was fixed on 2026-12-05 before any policy trained: the pool is the replay lists in
`demos/` in seed order (4800, 4801, 4802, 4803), a count takes its first N episodes; the preset is
`configs/policy/diffusion_pusht_cpu.json` (the box's CPU preset on lerobot/pusht's features); every count
trains STEPS steps with seed 1000. Training exports an fp16 copy of each checkpoint (every 500 steps) to
`base_<N>/partial`, the small state a fresh machine resumes from (`lerobot_gcs_push.improve.training`): commit it
at the end of a session. The datasets are rebuilt from the lists with no planning.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
SEEDS = (4800, 4801, 4802, 4803)
# The pools: where their replay lists are, and the expert settings that made them. The first (made with the
# agent steered over one action) is the count table's; "steer2" replans its first list's starts steered
# over two, for the A/B against base 206 (README.md, "Smoother actions").
POOLS = {"": (HERE / "demos", 1), "steer2": (HERE / "demos" / "steer2", 2)}
BASES = ("206", "500", "1000", "steer2_206")
STEPS = 8000
SEED = 1000
PRESET = REPO / "configs" / "policy" / "diffusion_pusht_cpu.json"


def split(name: str) -> tuple[str, int]:
    """A base's pool and count: "206" -> ("", 206), "steer2_206" -> ("steer2", 206)."""
    pool, _, n = name.rpartition("_")
    return pool, int(n)


def repo_id(name: str) -> str:
    return f"local/gcs_pusht_{name}"


def pool_list(name: str) -> Path:
    """The first episodes of the base's pool as one replay list (in outputs/, rebuilt, never committed)."""
    pool, n = split(name)
    entries = []
    for seed in SEEDS:
        path = POOLS[pool][0] / f"seed{seed}.json"
        if len(entries) >= n:
            break
        if not path.is_file():
            raise SystemExit(f"{path} is missing: the pool has {len(entries)} episodes, {n} asked")
        entries += json.loads(path.read_text())
    if len(entries) < n:
        raise SystemExit(f"the pool has {len(entries)} episodes, {n} asked")
    out = REPO / "outputs" / "pusht" / f"pool_{name}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(entries[:n]))
    return out


def plan_pool(pool: str, seed: int = SEEDS[0]) -> None:
    """Plan a pool's list for one seed from the first pool's starts (their actions dropped), with the
    expert's steering set to the pool's, in the same order and with the same episode count, so its count
    sets hold the same starts but where one expert failed and the other did not. Its replay list lands in
    `POOLS[pool][0]`: commit it."""
    from lerobot_gcs_push.generate import lerobot_home
    from lerobot_gcs_push.planning.factory import ExpertConfig

    folder, steer = POOLS[pool]
    if steer != ExpertConfig().steer_actions:
        raise SystemExit(f"pool {pool!r} is steered over {steer}, the expert over {ExpertConfig().steer_actions}")
    first = json.loads((POOLS[""][0] / f"seed{seed}.json").read_text())
    starts = REPO / "outputs" / "pusht" / f"starts_{seed}.json"
    starts.parent.mkdir(parents=True, exist_ok=True)
    starts.write_text(json.dumps([{"pusht_state": e["pusht_state"]} for e in first]))
    repo = f"local/gcs_pusht_{pool}_s{seed}"
    gcs_push = Path(sys.executable).parent / "gcs-push"
    subprocess.run(
        [str(gcs_push), "generate", "--env_id=gym_pusht/PushT-v0", f"--initial_conditions={starts}",
         f"--episodes={len(first)}", f"--repo_id={repo}", "--expert=closed-loop", "--workers=2", "--resume=true"],
        check=True,
    )  # fmt: skip
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(lerobot_home() / repo / "meta" / "gcs_push_replay.json", folder / f"seed{seed}.json")


def dataset(name: str) -> None:
    from lerobot_gcs_push.generate import lerobot_home

    if (lerobot_home() / repo_id(name) / "meta" / "info.json").is_file():
        print(f"{repo_id(name)} is there")
        return
    gcs_push = Path(sys.executable).parent / "gcs-push"
    cmd = [str(gcs_push), "generate", "--env_id=gym_pusht/PushT-v0", f"--initial_conditions={pool_list(name)}"]
    subprocess.run([*cmd, f"--repo_id={repo_id(name)}", "--workers=2", "--resume=true"], check=True)


def train(n: str) -> Path:
    from lerobot_gcs_push.improve.training import TrainJob
    from lerobot_gcs_push.improve.training import train as run

    dataset(n)
    job = TrainJob(
        config_path=str(PRESET),
        dataset_repo_id=repo_id(n),
        output_dir=REPO / "outputs" / "pusht" / f"train_{n}",
        steps=STEPS,
        seed=SEED,
        partial=HERE / f"base_{n}" / "partial",
    )
    final = run(job, progress_desc=f"base {n}")
    print(final)
    return final


# The validation runs, fixed before any base trained (README.md): LeRobot's own evaluator on 50 episodes of
# seed 4900, and `gcs-push evaluate` beside the expert on 50 of gym-pusht's resets of seed 4901.
LEROBOT_SEED, GCS_SEED, EPISODES = 4900, 4901, 50


def validate(n: str) -> dict:
    """Both validation runs of base `n`'s weights at STEPS (its fp16 export, what would be committed and
    shipped), each skipped when its output is there; their figures in base_<n>/validation.json."""
    base = HERE / f"base_{n}" / "partial"
    step = json.loads((base / "step.json").read_text())["step"]
    if step != STEPS:
        raise SystemExit(f"{base} holds step {step}, not {STEPS}: train it first (count_table.py train {n})")
    out = REPO / "outputs" / "pusht" / f"validate_{n}"
    bin_dir = Path(sys.executable).parent
    lerobot_cmd = [
        str(bin_dir / "lerobot-eval"), f"--policy.path={base}", "--env.type=pusht", f"--eval.n_episodes={EPISODES}",
        "--eval.batch_size=1", f"--seed={LEROBOT_SEED}", "--env.observation_height=96", "--env.observation_width=96",
        "--eval.use_async_envs=false", "--policy.device=cpu", f"--output_dir={out / 'lerobot_eval'}",
    ]  # fmt: skip
    gcs_cmd = [
        str(bin_dir / "gcs-push"), "evaluate", "--env_id=gym_pusht/PushT-v0", f"--policies=[{base},gcs-closed-loop]",
        f"--num_initial_conditions={EPISODES}", "--runs=1", f"--seed={GCS_SEED}", "--workers=2", "--videos=1",
        f"--output_dir={out / 'gcs_evaluate'}",
    ]  # fmt: skip
    env = {**os.environ, "HF_HUB_OFFLINE": "1", "OMP_WAIT_POLICY": "PASSIVE"}
    if not (out / "lerobot_eval" / "eval_info.json").is_file():
        subprocess.run(lerobot_cmd, check=True, env=env)
    subprocess.run(gcs_cmd, check=True, env=env)  # resumes: finished runs are kept
    overall = json.loads((out / "lerobot_eval" / "eval_info.json").read_text())["overall"]
    runs = [json.loads(line) for line in (out / "gcs_evaluate" / "runs.jsonl").read_text().splitlines()]
    mine = {r["initial_condition_index"]: r for r in runs if r["policy"] != "gcs-closed-loop"}
    expert = {r["initial_condition_index"]: r for r in runs if r["policy"] == "gcs-closed-loop"}
    both = [i for i in mine if mine[i]["success"] and expert[i]["success"]]
    result = {
        "base": int(n) if n.isdigit() else n,
        "step": step,
        "lerobot_eval": {k: overall[k] for k in ("pc_success", "avg_max_reward", "avg_sum_reward") if k in overall}
        | {"n_episodes": EPISODES, "seed": LEROBOT_SEED},
        "gcs_push_evaluate": {
            "seed": GCS_SEED,
            "policy_success": sum(r["success"] for r in mine.values()) / len(mine),
            "expert_success": sum(r["success"] for r in expert.values()) / len(expert),
            # Steps to success on the starts both succeeded on: the policy's mean over the expert's.
            "both_succeeded": len(both),
            "policy_steps_mean": _mean_steps([mine[i] for i in both]),
            "expert_steps_mean": _mean_steps([expert[i] for i in both]),
        },
        "commands": [" ".join(c).replace(f"{REPO}/", "") for c in (lerobot_cmd, gcs_cmd)],
    }
    g = result["gcs_push_evaluate"]
    g["steps_ratio"] = g["policy_steps_mean"] / g["expert_steps_mean"] if both else None
    (HERE / f"base_{n}" / "validation.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result, indent=1))
    return result


def ranking(validations: list[dict]) -> list[dict]:
    """The bases best first, by the rule fixed on 2026-12-05 before base 500's validation ran: LeRobot's
    success on seed 4900, then its average max reward, then fewer demonstrations (the cheaper base). The
    first is the base the rounds of active data start from; a base behind one already validated no longer
    needs its weights across machines (its partial leaves the tree)."""
    return sorted(
        validations,
        key=lambda v: (
            -v["lerobot_eval"]["pc_success"],
            -v["lerobot_eval"]["avg_max_reward"],
            split(str(v["base"]))[1],
        ),
    )


def decide() -> list[dict]:
    """Rank the bases validated so far (`ranking`) and print the order."""
    found = [json.loads(p.read_text()) for p in sorted(HERE.glob("base_*/validation.json"))]
    if not found:
        raise SystemExit("no base is validated yet: count_table.py validate N")
    order = ranking(found)
    for v in order:
        e = v["lerobot_eval"]
        print(f"base {v['base']}: success {e['pc_success']:.1f} %, average max reward {e['avg_max_reward']:.3f}")
    return order


def _mean_steps(runs: list[dict]) -> float | None:
    """Mean env steps to success (gym-pusht runs at 10 steps a simulated second)."""
    return sum(round(r["sim_time_s"] * 10) for r in runs) / len(runs) if runs else None


if __name__ == "__main__":
    commands = {"dataset": dataset, "train": train, "validate": validate}
    if sys.argv[1:] == ["decide"]:
        decide()
    elif len(sys.argv) >= 3 and sys.argv[1] == "pool" and sys.argv[2] in POOLS and sys.argv[2]:
        # each seed's list is committed as it lands, so a stopped run loses at most the seed in hand
        for seed in [int(s) for s in sys.argv[3:]] or [SEEDS[0]]:
            if seed not in SEEDS:
                raise SystemExit(f"seed {seed} is not one of the first pool's {SEEDS}")
            plan_pool(sys.argv[2], seed)
    elif len(sys.argv) != 3 or sys.argv[1] not in commands or sys.argv[2] not in BASES:
        raise SystemExit(
            f"usage: count_table.py {'|'.join(commands)} {'|'.join(BASES)}, count_table.py pool "
            f"{'|'.join(p for p in POOLS if p)} [SEED ...], or count_table.py decide"
        )
    else:
        commands[sys.argv[1]](sys.argv[2])
