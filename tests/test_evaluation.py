"""The evaluation protocol: records, tables, figures, resumption, and clear errors before any rollout."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import gcs_push, kill_when

from lerobot_gcs_push.evaluation import (
    TIMING_FIELDS,
    EvaluateConfig,
    changed_weights,
    evaluate,
    read_runs,
)
from lerobot_gcs_push.evaluation.tables import _regret_summary

REQUIRED = (
    "policy",
    "disturbances",
    "initial_condition_index",
    "box_initial",
    "finger_initial",
    "run",
    "seed",
    "success",
    "final_distance",
    "sim_time_s",
    "run_time_s",
    "plan_time_s",
)


@pytest.fixture(scope="module")
def ics_file(tmp_path_factory):
    ics = [
        {"box": [2.0, -1.5], "finger": [-2.0, 1.0]},
        {"box": [-3.0, 3.5], "finger": [0.5, -4.0]},
        {"box": [0.6, 2.2], "finger": [3.0, 3.0]},
    ]
    path = tmp_path_factory.mktemp("ics") / "ics.json"
    path.write_text(json.dumps(ics))
    return path


@pytest.fixture(scope="module")
def open_loop(tmp_path_factory, ics_file):
    out = tmp_path_factory.mktemp("eval") / "open_loop"
    summary = evaluate(
        EvaluateConfig(
            policies=["gcs-open-loop"], initial_conditions=str(ics_file), runs=1, output_dir=str(out), videos=1
        )
    )
    return out, summary


def test_gcs_open_loop_succeeds_and_records_are_complete(open_loop, ics_file):
    out, summary = open_loop
    recs = read_runs(out / "runs.jsonl")
    assert len(recs) == 3
    ics = json.loads(ics_file.read_text())
    for rec in recs:
        for key in REQUIRED:
            assert key in rec, key
        assert rec["success"] and rec["final_distance"] <= 0.1
        assert rec["box_initial"] == ics[rec["initial_condition_index"]]["box"]
        assert 0 < rec["sim_time_s"] < 500 and rec["plan_time_s"] > 0
        traj = np.load(out / rec["trajectory"])
        np.testing.assert_allclose(traj["finger"][0], rec["finger_initial"], atol=1e-6)
        # The simulated time is the trajectory's length at the env's 10 Hz.
        assert rec["sim_time_s"] == pytest.approx((len(traj["finger"]) - 1) / 10, abs=1e-6)
    assert summary["variants"]["gcs-open-loop"]["success"] == 1.0


def test_tables_parse_and_hold_the_right_counts(open_loop):
    out, _ = open_loop
    md = (out / "tables.md").read_text()
    table1 = [line for line in md.splitlines() if line.startswith("| gcs-open-loop | ")]
    cells = [c.strip() for c in table1[0].strip("|").split("|")]
    assert cells[1] == "3" and cells[2] == "1.00" and cells[5] == "1.00"  # runs, success, paper's 1.00
    rows2 = [line for line in md.splitlines() if line.startswith("| 0 | ") or line.startswith("| 2 | ")]
    assert len(rows2) == 2 and all("1.00 / 1.00" in r for r in rows2)
    summary = json.loads((out / "summary.json").read_text())
    v = summary["variants"]["gcs-open-loop"]
    assert v["runs"] == 3 and v["success_0.2"] == 1.0
    recs = read_runs(out / "runs.jsonl")
    assert v["success_sim_time_s"] == pytest.approx(np.mean([r["sim_time_s"] for r in recs]))


def test_figures_and_video_are_real_images(open_loop):
    import matplotlib.image as mpimg

    out, _ = open_loop
    for name in ("fig6_success_map.png", "fig7_trajectories.png"):
        img = mpimg.imread(out / name)
        assert img.shape[0] > 200 and img.shape[1] > 200
        assert img[..., :3].std() > 0.05  # not a blank canvas
    videos = list((out / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 5000


def test_an_evaluation_from_before_the_env_was_recorded_resumes_as_the_box(open_loop, ics_file, tmp_path):
    """settings.json without env_id (nor regret settings) was the box with regret on: resumed, not refused;
    the same folder asked for another env is refused."""
    import shutil

    out, _ = open_loop
    legacy = tmp_path / "legacy"
    shutil.copytree(out, legacy)
    settings = json.loads((legacy / "settings.json").read_text())
    assert settings["env_id"] == "GcsPushBox-v0" and settings["regret"] is True
    old = {k: v for k, v in settings.items() if k not in ("env_id", "regret", "large_regret_m")}
    (legacy / "settings.json").write_text(json.dumps(old))
    cfg = dict(policies=["gcs-open-loop"], initial_conditions=str(ics_file), runs=1, videos=0)
    evaluate(EvaluateConfig(**cfg, output_dir=str(legacy)))
    assert read_runs(legacy / "runs.jsonl") == read_runs(out / "runs.jsonl")  # nothing ran again
    assert json.loads((legacy / "settings.json").read_text())["env_id"] == "GcsPushBox-v0"
    policy = str(Path(__file__).resolve().parents[1] / "policies" / "diffusion_cpu")
    with pytest.raises(FileExistsError, match="other initial conditions or settings"):
        evaluate(EvaluateConfig(**(cfg | {"policies": [policy]}), env_id="GcsPushBoxSE2-v0", output_dir=str(legacy)))


def _without_timing(recs):
    return sorted(json.dumps({k: v for k, v in r.items() if k not in TIMING_FIELDS}, sort_keys=True) for r in recs)


@pytest.mark.slow
def test_killed_and_rerun_evaluation_gives_the_same_records(tmp_path, ics_file):
    args = [
        "--policies=[gcs-open-loop,gcs-closed-loop]",
        "--disturbances=true",
        f"--initial_conditions={ics_file}",
        "--runs=1",
        "--videos=0",
    ]
    full = tmp_path / "full"
    subprocess.run(
        gcs_push("evaluate", *args, f"--output_dir={full}"),
        check=True,
        capture_output=True,
    )
    killed = tmp_path / "killed"
    cmd = gcs_push("evaluate", *args, f"--output_dir={killed}")
    runs = killed / "runs.jsonl"
    kill_when(cmd, lambda: runs.exists() and len(read_runs(runs)) >= 2)
    n_before = len(read_runs(runs))
    assert 0 < n_before < 9
    with open(runs, "a") as f:  # a line torn by the kill
        f.write('{"policy": "gcs-open')
    subprocess.run(cmd, check=True, capture_output=True)
    assert _without_timing(read_runs(runs)) == _without_timing(read_runs(full / "runs.jsonl"))
    assert len(read_runs(runs)) == 9  # 3 ICs x (open loop, closed loop, closed loop with disturbances)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--policies=[gcs-teleop]"], "unknown policy"),
        (["--policies=[/nonexistent/pretrained_model]"], "unknown policy"),
        (["--policies=[gcs-open-loop]", "--initial_conditions=/nonexistent.json"], "does not exist"),
        (["--sampler=hardest"], "unknown sampler"),
        (["--runs=0"], "must be >= 1"),
        (["--runs=many"], "runs"),
        (["--device=tpu"], "unknown device"),
        (["--dataset=local/no_such_dataset"], "neither a folder nor in the LeRobot cache"),
    ],
)
def test_bad_input_fails_before_any_rollout(tmp_path, args, needle):
    res = subprocess.run(
        gcs_push("evaluate", *args, f"--output_dir={tmp_path / 'o'}"),
        capture_output=True,
        text=True,
    )
    assert res.returncode != 0 and needle in res.stderr
    assert not (tmp_path / "o" / "runs.jsonl").exists()


def test_malformed_initial_conditions_are_named(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps([{"box": [1, 2]}]))
    res = subprocess.run(
        gcs_push(
            "evaluate", "--policies=[gcs-open-loop]", f"--initial_conditions={bad}", f"--output_dir={tmp_path / 'o'}"
        ),
        capture_output=True,
        text=True,
    )
    assert res.returncode != 0 and "entry 0" in res.stderr
    overlap = tmp_path / "overlap.json"
    overlap.write_text(json.dumps([{"box": [0, 0], "finger": [0.5, 0]}]))
    with pytest.raises(ValueError, match="overlaps"):
        evaluate(EvaluateConfig(initial_conditions=str(overlap), output_dir=str(tmp_path / "o2")))


def test_overwrite_deletes_an_evaluation_never_another_folder(tmp_path):
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "thesis.tex").write_text("x")
    with pytest.raises(FileExistsError, match="holds none"):
        evaluate(EvaluateConfig(num_initial_conditions=1, runs=1, output_dir=str(notes), overwrite=True))
    assert (notes / "thesis.tex").read_text() == "x"


def test_a_chunk_the_planner_cannot_score_is_counted_not_hidden():
    """Two runs by hand: regret 1.5 and 0.5 m (one chunk of the second unscored, NaN)."""
    recs = [
        {"regret": 1.5, "first_large_regret_s": 0.8, "regret_chunks": [[0, 1.0], [8, 0.5]]},
        {"regret": 0.5, "first_large_regret_s": None, "regret_chunks": [[0, 0.5], [8, float("nan")]]},
    ]
    s = _regret_summary(recs, 0.75)
    assert s["unscored_chunks"] == 1 and s["regret_mean"] == 1.0 and s["runs_with_large_regret"] == 0.5
    assert s["chunk_regret_p95"] == pytest.approx(np.percentile([1.0, 0.5, 0.5], 95))


def _marked(mark: str) -> set[int]:
    """Pids of the processes whose environment holds `mark` (inherited by every child)."""
    pids = set()
    for environ in Path("/proc").glob("[0-9]*/environ"):
        try:
            if mark.encode() in environ.read_bytes():
                pids.add(int(environ.parent.name))
        except OSError:  # ended while we looked, or not ours
            continue
    return pids


@pytest.mark.slow
def test_worker_processes_leave_when_the_driver_alone_is_killed(tmp_path):
    """`kill PID` or `timeout` signal the driver only; its workers must not wait forever for jobs."""
    mark = f"GCS_PUSH_TEST_{os.getpid()}_{time.monotonic_ns()}"
    cmd = gcs_push(
        "evaluate", "--policies=[gcs-open-loop]", "--num_initial_conditions=40", "--runs=1", "--workers=2",
        "--videos=0", "--regret=false", f"--output_dir={tmp_path / 'o'}",
    )  # fmt: skip
    driver = subprocess.Popen(
        cmd, env=os.environ | {"GCS_PUSH_TEST_MARK": mark}, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    runs = tmp_path / "o" / "runs.jsonl"
    deadline = time.time() + 180
    while not (runs.exists() and runs.read_text().strip()) and driver.poll() is None and time.time() < deadline:
        time.sleep(0.2)  # a finished run: the workers are up and busy
    children = _marked(mark) - {driver.pid}
    assert driver.poll() is None and len(children) >= 2, "the evaluation ended before it could be killed"
    driver.terminate()
    driver.wait()
    deadline = time.time() + 20
    while (left := _marked(mark)) and time.time() < deadline:
        time.sleep(0.2)
    for pid in left:  # a failing run must not leave them behind either
        os.kill(pid, signal.SIGKILL)
    assert not left, f"{len(left)} of the driver's processes outlived it"


def test_a_policy_retrained_in_place_is_not_resumed(tmp_path):
    """Runs belong to the weights that made them: a policy folder whose model.safetensors changed refuses
    to resume (the old runs would be mixed with the new ones under one label), and --overwrite re-runs."""
    import hashlib
    import shutil

    from safetensors.torch import load_file, save_file

    policy = tmp_path / "policy"
    shutil.copytree(Path(__file__).resolve().parents[1] / "policies" / "diffusion_cpu", policy)
    out = tmp_path / "o"
    cfg = dict(policies=[str(policy)], num_initial_conditions=1, runs=1, timeout_s=1.0, videos=0, output_dir=str(out))

    def fingerprint() -> str:
        return json.loads((out / "settings.json").read_text())["policy_weights"][str(policy)]

    evaluate(EvaluateConfig(**cfg))
    first = read_runs(out / "runs.jsonl")
    assert fingerprint() == hashlib.sha256((policy / "model.safetensors").read_bytes()).hexdigest()[:16]
    evaluate(EvaluateConfig(**cfg))  # the same weights: nothing to run again
    assert read_runs(out / "runs.jsonl") == first
    # A folder from before weights were recorded: evaluate resumes it, the demo (unrecorded_changed) does not.
    settings = json.loads((out / "settings.json").read_text())
    legacy = tmp_path / "legacy"
    legacy.mkdir()
    (legacy / "settings.json").write_text(json.dumps({k: v for k, v in settings.items() if k != "policy_weights"}))
    legacy_cfg = EvaluateConfig(**(cfg | {"output_dir": str(legacy)}))
    assert changed_weights(legacy_cfg) == [] and changed_weights(legacy_cfg, unrecorded_changed=True) == [str(policy)]

    tensors = load_file(policy / "model.safetensors")
    name = next(iter(tensors))
    tensors[name] = tensors[name] + 1
    save_file(tensors, policy / "model.safetensors")
    with pytest.raises(FileExistsError, match="other weights"):
        evaluate(EvaluateConfig(**cfg))
    assert read_runs(out / "runs.jsonl") == first
    evaluate(EvaluateConfig(**cfg, overwrite=True))
    assert len(read_runs(out / "runs.jsonl")) == 1
    assert fingerprint() == hashlib.sha256((policy / "model.safetensors").read_bytes()).hexdigest()[:16]
