"""Issue 46, item 5: the package works from any folder and as a wheel, not only from its checkout.

The shipped policy and configs are named by their repository paths (`policies/diffusion_cpu`); from another
folder they are found beside the installed package (the editable install's checkout) or among a wheel's
data files. A path that exists where the command runs is always taken as given.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from lerobot_gcs_push.artifacts.shipped import shipped_path

REPO = Path(__file__).resolve().parent.parent


def test_shipped_names_resolve_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert Path(shipped_path("policies/diffusion_cpu")) == REPO / "policies" / "diffusion_cpu"
    assert Path(shipped_path("configs/policy/diffusion_cpu.json")) == REPO / "configs" / "policy" / "diffusion_cpu.json"
    # Not shipped: returned unchanged (the caller's error names what the user typed), even where the
    # checkout happens to hold a folder of that name.
    assert shipped_path("policies/no_such_policy") == "policies/no_such_policy"
    assert shipped_path("experiments/active_data") == "experiments/active_data"
    # A folder of that name where the command runs wins over the shipped one.
    (tmp_path / "policies" / "diffusion_cpu").mkdir(parents=True)
    assert shipped_path("policies/diffusion_cpu") == "policies/diffusion_cpu"


def _env(home: Path) -> dict:
    env = {**os.environ, "HF_LEROBOT_HOME": str(home), "HF_HUB_OFFLINE": "1", "MPLBACKEND": "Agg"}
    env.pop("PYTHONPATH", None)
    return env


@pytest.mark.slow
def test_demo_runs_from_a_folder_outside_the_repository(tmp_path):
    """`gcs-push demo` at quick settings, run from an empty folder: the shipped policy beside GCS."""
    bin_dir = Path(sys.executable).parent
    cmd = [str(bin_dir / "gcs-push"), "demo", "--episodes=2", "--num_initial_conditions=1", "--runs=1"]
    proc = subprocess.run(
        [*cmd, "--policy_ics=1", "--workers=1"],
        cwd=tmp_path,
        env=_env(tmp_path / "home"),
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert (tmp_path / "outputs" / "demo" / "policy" / "side_by_side_ic000.mp4").is_file()
    runs = [json.loads(r) for r in (tmp_path / "outputs" / "demo" / "policy" / "runs.jsonl").read_text().splitlines()]
    assert "policies/diffusion_cpu" in {r["policy"] for r in runs}  # labelled as named, loaded from the checkout


@pytest.mark.slow
def test_the_built_wheel_installs_a_working_gcs_push(tmp_path):
    """A wheel built from the repository, installed into a fresh virtual environment (its dependencies
    reached through this one's site-packages, read as a plain path, so this checkout's editable install is
    not): `gcs-push plan` and `gcs-push evaluate` with the shipped policy, from an empty folder."""
    py = sys.executable
    dist, source = tmp_path / "dist", tmp_path / "source"
    # Built from a copy of the tracked tree: the build leaves nothing in the checkout, and nothing
    # untracked there (outputs, an old build/) reaches the wheel.
    tracked = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True, check=True).stdout
    for name in tracked.splitlines():
        (source / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / name, source / name)
    build = subprocess.run(
        [py, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-w", str(dist), str(source)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0, build.stderr[-3000:]
    wheel = next(dist.glob("*.whl"))
    venv = tmp_path / "venv"
    subprocess.run([py, "-m", "venv", "--without-pip", str(venv)], check=True)
    fresh_py = venv / "bin" / "python"
    site = subprocess.run(
        [str(fresh_py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    Path(site, "deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    install = subprocess.run(
        [py, "-m", "pip", "--python", str(fresh_py), "install", "--no-deps", str(wheel)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert install.returncode == 0, install.stderr[-3000:]
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = _env(tmp_path / "home")
    where = subprocess.run(
        [str(fresh_py), "-c", "import lerobot_gcs_push; print(lerobot_gcs_push.__file__)"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert where.startswith(site), where  # the wheel's copy, not the checkout
    gcs = str(venv / "bin" / "gcs-push")
    plan = subprocess.run(
        [gcs, "plan", "--box=[1.0, 0.5]", "--finger=[-1.0, 0.0]"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert plan.returncode == 0 and "cost" in plan.stdout, plan.stderr[-3000:]
    ev = subprocess.run(
        [
            gcs,
            "evaluate",
            "--policies=[policies/diffusion_cpu]",
            "--num_initial_conditions=1",
            "--runs=1",
            "--timeout_s=3",
            "--videos=0",
            "--workers=1",
            "--output_dir=out",
        ],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert ev.returncode == 0, ev.stderr[-3000:]
    runs = [json.loads(r) for r in (work / "out" / "runs.jsonl").read_text().splitlines()]
    assert [r["policy"] for r in runs] == ["policies/diffusion_cpu"]
