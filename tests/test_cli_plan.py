"""`gcs-push plan` on bad input, for every env id: one line on stderr that names the field at fault (the
box, the finger, the heading, the file's entry), plain numbers in it (no `np.float64(...)`), exit code 2,
and nothing planned."""

from __future__ import annotations

import json

import pytest

from lerobot_gcs_push.cli import main
from lerobot_gcs_push.registration import SCENES

ENV_IDS = sorted(SCENES)


def _refused(capsys, *args: str) -> str:
    code = main(["plan", *args])
    out, err = capsys.readouterr()
    assert code == 2 and out == "", (code, out)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "np." not in err and "float64" not in err, err
    return lines[0]


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_a_box_outside_the_workspace_is_blamed_on_the_box(env_id, capsys):
    far = 1e6  # outside every scene's workspace, whatever its units
    line = _refused(capsys, f"--env_id={env_id}", f"--box=[{far}, 1]", "--finger=[0.3, 0.3]")
    assert "box" in line and "outside" in line and "finger" not in line, line
    assert "1000000.0" in line


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_a_finger_outside_the_workspace_is_blamed_on_the_finger(env_id, capsys):
    goal = list(SCENES[env_id].goal)
    line = _refused(capsys, f"--env_id={env_id}", f"--box={goal}", "--finger=[1e6, 0]")
    assert "finger" in line and "outside" in line, line


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("heading", ["nan", "inf", "-inf"])
def test_a_heading_that_is_not_finite_is_refused_naming_the_heading(env_id, heading, capsys):
    goal = list(SCENES[env_id].goal)
    line = _refused(capsys, f"--env_id={env_id}", f"--box={goal}", "--finger=[1e6, 0]", f"--heading={heading}")
    assert "heading" in line and "finite" in line, line


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_a_box_that_is_not_finite_is_refused_naming_the_box(env_id, capsys):
    line = _refused(capsys, f"--env_id={env_id}", "--box=[nan, 0]", "--finger=[0.3, 0.3]")
    assert "box" in line and "finite" in line, line


def test_a_heading_for_a_slider_that_cannot_turn_is_refused(capsys):
    line = _refused(capsys, "--env_id=GcsPushBox-v0", "--box=[1, 1]", "--finger=[3, 3]", "--heading=0.5")
    assert "heading" in line and "cannot rotate" in line, line


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_a_files_bad_entry_is_named_before_anything_is_planned(env_id, tmp_path, capsys):
    scene = SCENES[env_id]
    gx, gy = scene.goal
    clear = scene.slider_extent + scene.finger_radius + 0.01  # beside the slider at any heading
    fine = {"box": [gx, gy], "finger": [gx - clear if gx > 0 else gx + clear, gy]}
    scene.validate_state(fine["box"], fine["finger"])  # the first entry is fine: the second is at fault
    path = tmp_path / "ics.json"
    path.write_text(json.dumps([fine, {"box": [1e6, 1.0], "finger": [0.3, 0.3]}]))
    line = _refused(capsys, f"--env_id={env_id}", f"--initial_conditions={path}")
    assert "entry 1" in line and "box" in line and "outside" in line, line


def test_the_planner_through_contact_prints_plain_numbers():
    """The Python API's own message (a finger inside the slider) lists plain floats."""
    import numpy as np

    from lerobot_gcs_push.contact import ContactPlanner
    from lerobot_gcs_push.planning import PlanningError

    planner = ContactPlanner(SCENES["GcsPushBoxSE2-v0"])
    with pytest.raises(ValueError) as err:
        planner.query(np.array([1.0, 2.0, 0.25]), np.array([1.1, 2.0]))
    assert "np." not in str(err.value) and "[1.0, 2.0, 0.25]" in str(err.value)
    with pytest.raises(ValueError, match="finite"):
        planner.query((1.0, 2.0, float("nan")), (3.0, 2.0))
    with pytest.raises(PlanningError, match="outside the workspace"):
        planner.query((100.0, 2.0, 0.0), (103.0, 2.0))
