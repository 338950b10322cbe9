"""The learnability benchmark's pools and its validation judge (`benchmarks/learnability.py`): every pool
decodes to the trainer's config it names, and a validation never reuses the judge's seed or judges a
policy that has not finished."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from benchmarks import learnability as bench


@pytest.mark.parametrize("pool", sorted(bench.POOLS))
def test_every_pool_is_the_trainers_config_at_the_benchmarks_budget(pool):
    spec, cfg = bench.POOLS[pool], bench.train_config(pool)
    assert cfg.data.lists == [str(p) for p in spec.lists] and cfg.data.episodes == spec.episodes
    assert (cfg.data.label_shift, cfg.data.hold_frames) == (spec.label_shift, spec.hold_frames)
    assert cfg.schedule.lr == spec.lr  # None: the preset's
    assert cfg.model.down_dims == (None if spec.down_dims is None else list(spec.down_dims))
    assert (cfg.schedule.steps, cfg.schedule.batch_size, cfg.seed) == (20000, 64, 1000)  # 1.28 M samples


def test_a_validation_needs_another_seed_and_a_finished_policy(tmp_path, monkeypatch):
    with pytest.raises(ValueError, match="judge"):
        bench.validate("position", bench.JUDGE_SEED)
    monkeypatch.setattr(bench, "train_config", lambda pool: SimpleNamespace(output_dir=str(tmp_path / "train")))
    with pytest.raises(FileNotFoundError, match="no finished policy"):
        bench.validate("position", 12100)
