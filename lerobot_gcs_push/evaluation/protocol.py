"""`evaluate`: the runs an evaluation owes (every variant on every initial condition, `runs` times),
those already in its folder kept, the rest run, then the summary, tables and figures."""

from __future__ import annotations

import json
from pathlib import Path

from lerobot_gcs_push.evaluation.config import GCS_POLICIES, EvaluateConfig, initial_conditions, variants
from lerobot_gcs_push.evaluation.records import _key, changed_weights, read_runs, weights_fingerprint
from lerobot_gcs_push.evaluation.runner import _run_all
from lerobot_gcs_push.evaluation.tables import summarize
from lerobot_gcs_push.files import atomic_path
from lerobot_gcs_push.registration import ENV_ID


def evaluate(cfg: EvaluateConfig) -> dict:
    out = Path(cfg.output_dir)
    ics = initial_conditions(cfg)
    settings = {
        "initial_conditions": ics,
        "seed": cfg.starts.seed,
        "runs": cfg.runs,
        "timeout_s": cfg.timeout_s,
        "success_thresholds": list(cfg.success_thresholds),
        "regret": cfg.regret,
        "large_regret_m": cfg.large_regret_m,
        "env_id": cfg.starts.env_id,
        # The experts' settings where set (issue 66 made them reachable): a folder made without reads as before.
        **cfg.expert.non_defaults(always=("mode",)),
    }
    runs_path = out / "runs.jsonl"
    if cfg.overwrite and out.exists():
        import shutil

        if not ((out / "runs.jsonl").is_file() or (out / "settings.json").is_file()) and any(out.iterdir()):
            raise FileExistsError(
                f"--overwrite replaces an evaluation, and {out} holds none (no runs.jsonl): choose another --output_dir"
            )
        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)
    settings_path = out / "settings.json"
    stored = json.loads(settings_path.read_text()) if settings_path.exists() else None
    # Folders written before weights were recorded hold none: their runs are taken as they are.
    weights = stored.pop("policy_weights", {}) if stored else {}
    # Folders written before these settings were recorded were made with the box and its regret on.
    implicit = {"regret": True, "large_regret_m": EvaluateConfig.large_regret_m, "env_id": ENV_ID}
    if stored is not None and implicit | stored != settings:
        raise FileExistsError(
            f"{out} holds an evaluation with other initial conditions or settings; "
            f"pass --overwrite=true or choose another --output_dir"
        )
    changed = changed_weights(cfg)
    if changed:
        raise FileExistsError(
            f"{out} holds runs of {', '.join(changed)} made with other weights (model.safetensors changed "
            f"since); pass --overwrite=true or choose another --output_dir"
        )
    weights |= {p: weights_fingerprint(p) for p in cfg.policies if p not in GCS_POLICIES}
    with atomic_path(settings_path) as tmp:
        tmp.write_text(json.dumps(settings | {"policy_weights": weights}, indent=1))

    records = read_runs(runs_path)
    # Rewrite without any torn last line, so that appends start on a fresh line.
    with atomic_path(runs_path) as tmp:  # a kill here must not cost the finished runs
        tmp.write_text("".join(json.dumps(r) + "\n" for r in records))
    done = {_key(r) for r in records}
    jobs = []
    for policy, dist in variants(cfg):
        for i, ic in enumerate(ics):
            for r in range(cfg.runs):
                if (policy, dist, i, r) not in done:
                    jobs.append(
                        {
                            "policy": policy,
                            "disturbances": dist,
                            "ic_index": i,
                            "run": r,
                            "ic": ic,
                            "video": r == 0 and i < cfg.videos,
                        }
                    )
    _run_all(cfg, out, jobs, runs_path)
    records = [r for r in read_runs(runs_path) if (r["policy"], r["disturbances"]) in set(variants(cfg))]
    summary = summarize(cfg, records, ics)
    with atomic_path(out / "summary.json") as tmp:
        tmp.write_text(json.dumps({k: v for k, v in summary.items() if k != "tables_md"}, indent=1))
    with atomic_path(out / "tables.md") as tmp:
        tmp.write_text(summary["tables_md"])
    from lerobot_gcs_push.evaluation.figures import make_figures

    summary["figures"] = make_figures(cfg, out, records, ics)
    return summary
