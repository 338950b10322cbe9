"""The one comparison behind every refused resume (generate's work folder and dataset, improve's state)."""

from lerobot_gcs_push.settings import changed, describe


def test_differences_are_named_leaf_by_leaf():
    held = {"seed": 0, "round": {"hard": 80, "steps": 2500}, "sampler": "sobol"}
    wanted = {"seed": 0, "round": {"hard": 40, "steps": 2500}, "sampler": "sobol"}
    assert changed(held, wanted) == {"round.hard": (80, 40)}
    assert describe(changed(held, wanted)) == "round.hard: 80 -> 40"
    assert changed(held, held) == {}


def test_a_field_newer_than_the_file():
    old = {"seed": 0}  # written before "env_id" existed
    # Unknown to the old file: a difference, unless the file's implicit value is given, or only its own
    # fields are compared.
    assert changed(old, {"seed": 0, "env_id": "GcsPushT-v0"}) == {"env_id": (None, "GcsPushT-v0")}
    assert changed(old, {"seed": 0, "env_id": "GcsPushBox-v0"}, {"env_id": "GcsPushBox-v0"}) == {}
    assert changed(old, {"seed": 0, "env_id": "GcsPushT-v0"}, {"env_id": "GcsPushBox-v0"}) == {
        "env_id": ("GcsPushBox-v0", "GcsPushT-v0")
    }
    assert changed(old, {"seed": 0, "env_id": "GcsPushT-v0"}, only_held=True) == {}
    assert changed(old, {"seed": 1, "env_id": "GcsPushT-v0"}, only_held=True) == {"seed": (0, 1)}


def test_generate_refuses_to_resume_a_work_folder_with_other_settings(tmp_path):
    import pytest

    from lerobot_gcs_push.generate import WorkDir

    work = WorkDir(tmp_path / "run.work")
    work.open({"env_id": "GcsPushBox-v0", "seed": 0}, resume=False)
    with pytest.raises(FileExistsError, match="--resume=true"):
        work.open({"env_id": "GcsPushBox-v0", "seed": 0}, resume=False)
    with pytest.raises(ValueError, match="seed: 0 -> 3"):
        work.open({"env_id": "GcsPushBox-v0", "seed": 3}, resume=True)
    work.open({"env_id": "GcsPushBox-v0", "seed": 0}, resume=True)  # the same settings: resumed
    # A folder written before env_id was recorded ran the box.
    (work.settings_file()).write_text('{"seed": 0}')
    work.open({"env_id": "GcsPushBox-v0", "seed": 0}, resume=True)
    (work.settings_file()).write_text('{"seed": 0}')
    with pytest.raises(ValueError, match="env_id: 'GcsPushBox-v0' -> 'GcsPushT-v0'"):
        work.open({"env_id": "GcsPushT-v0", "seed": 0}, resume=True)
