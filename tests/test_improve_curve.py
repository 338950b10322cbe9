"""The curve of an improve run: points placed at the hours the stages before them took, and drawn."""

from __future__ import annotations

import json
from dataclasses import asdict

import matplotlib.image
import numpy as np
import pytest

from lerobot_gcs_push.improve import StopConfig
from lerobot_gcs_push.improve.curve import curve_points, main, plot_curve


def _state() -> dict:
    scores = {"hard": {"without": 0.5, "with": 0.25, "time_ratio": 1.5, "regret_mean": 9.0}}
    # Insertion order is the order the stages ran; r2's rollouts were killed before they were scored.
    return {
        "stages": {
            "base.demonstrations": {"done": True, "wall_s": 1800.0},
            "base.train": {"done": True, "wall_s": 5400.0},
            "r1.rollouts": {"done": True, "wall_s": 900.0, "scores": scores},
            "r1.collect": {"done": True, "wall_s": 900.0},
            "r1.merge": {"done": True, "wall_s": 360.0},
            "r1.finetune": {"done": True, "wall_s": 3240.0},
            "r1.validation": {"done": True, "wall_s": 3600.0},
            "r1.decision": {"done": True, "wall_s": 0.0},
            "r2.rollouts": {"done": True, "wall_s": 720.0, "scores": scores | {"uniform": {"without": 1.0}}},
            "r3.rollouts": {"done": False, "wall_s": 100.0},
        },
        "rounds": [],
    }


def test_points_sit_at_the_hours_spent_before_their_rollouts():
    points = curve_points(_state())
    assert [p["round"] for p in points] == [1, 2]
    # By hand: 0.5 + 1.5 h before round 1's rollouts; then 0.25 + 0.25 + 0.1 + 0.9 + 1.0 h of round 1.
    assert points[0]["hours"] == pytest.approx(2.0)
    assert points[1]["hours"] == pytest.approx(4.5)
    assert points[1]["scores"]["uniform"] == {"without": 1.0}


def test_the_curve_is_drawn_from_a_state_folder(tmp_path, capsys):
    assert plot_curve({"stages": {}}, tmp_path / "none.png") is None
    out = plot_curve(_state() | {"stop": asdict(StopConfig())}, tmp_path / "curve.png")
    assert matplotlib.image.imread(out).shape[:2] == (342, 1170)  # figsize x dpi
    bare = plot_curve(_state(), tmp_path / "bare.png")  # a state file from before the targets were kept
    assert not np.array_equal(matplotlib.image.imread(out), matplotlib.image.imread(bare))  # the targets drawn
    (tmp_path / "state.json").write_text(json.dumps(_state()))
    main([str(tmp_path)])
    printed = capsys.readouterr().out
    assert "round 1 at 2.00 h: hard 0.500 / 0.250, 1.50x, regret 9.0 m" in printed
    assert "round 2 at 4.50 h" in printed
    # gym-pusht's rounds: no regret, the final coverage in its place (in the picture's third panel too)
    pusht = {"uniform": {"without": 0.0, "time_ratio": float("inf"), "coverage_mean": 0.375}}
    state = {"stages": {"r1.rollouts": {"done": True, "wall_s": 60.0, "scores": pusht}}}
    (tmp_path / "state.json").write_text(json.dumps(state))
    main([str(tmp_path)])
    assert "round 1 at 0.00 h: uniform 0.000, infx, final coverage 0.375" in capsys.readouterr().out
    without = {"stages": {"r1.rollouts": state["stages"]["r1.rollouts"] | {"scores": {"uniform": {"without": 0.0}}}}}
    assert not np.array_equal(
        matplotlib.image.imread(tmp_path / "curve.png"),
        matplotlib.image.imread(plot_curve(without, tmp_path / "w.png")),
    )
    with pytest.raises(SystemExit, match="does not exist"):
        main([str(tmp_path / "missing")])
