"""How an env's runs are scored, named for the tables and figures: its success rule and a looser measure
beside it."""

from __future__ import annotations

from dataclasses import dataclass

from lerobot_gcs_push.registration import SCENES


@dataclass(frozen=True)
class SuccessMeasures:
    """How an env's runs are scored: the success rule (the env's `is_success`) and a second, looser
    measure beside it, with their names in the tables."""

    title: str  # Table I's title: the success rule
    strict: str  # the success column's header
    loose_key: str  # the record key of the second measure
    loose: str  # its column's header
    per_ic: str  # Table II's title


def success_measures(cfg) -> SuccessMeasures:
    """The box: the paper's radius and a looser one. A rotating slider: coverage of the goal outline,
    and beside it the mean final coverage (how close the failures came)."""
    scene = SCENES[cfg.starts.env_id]
    return SuccessMeasures(*scene.kind.success_measures(scene, cfg.success_thresholds))
