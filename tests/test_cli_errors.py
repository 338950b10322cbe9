"""Bad input to the commands other than `plan` (tests/test_cli_plan.py has that one): one line on stderr
that names the field at fault, exit code 2, and nothing run. In-process through the CLI's own entry point."""

from __future__ import annotations

import pytest

from lerobot_gcs_push.cli import main

CASES = [
    (["generate", "--seed=-1"], "seed"),
    (["generate", "--max_sim_time_s=inf"], "max_sim_time_s"),
    (["generate", "--max_sim_time_s=nan"], "max_sim_time_s"),
    (["generate", "--image_size=0"], "image_size"),
    (["generate", "--episodes=0"], "episodes"),
    (["generate", "--fps=7"], "fps"),
    (["generate", "--expert=replay"], "initial_conditions"),
    (["generate", "--env_id=gym_pusht/PushT"], "env_id"),
    (["evaluate", "--policies=[gcs-closed-loop]", "--seed=-1"], "seed"),
    (["evaluate", "--policies=[gcs-closed-loop]", "--timeout_s=inf"], "timeout_s"),
    (["evaluate", "--policies=[gcs-closed-loop]", "--device=tpu"], "device"),
    (["evaluate", "--policies=[policies/no_such_policy]"], "policies/no_such_policy"),
    (["evaluate", "--env_id=gym_pusht/PushT-v0", "--policies=[gcs-closed-loop]", "--regret=true"], "regret"),
]


@pytest.mark.parametrize("args, field", CASES, ids=[" ".join(a) for a, _ in CASES])
def test_bad_input_is_one_line_naming_the_field(args, field, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing may be written, wherever it would have gone
    code = main(args)
    out, err = capsys.readouterr()
    assert code == 2, (code, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and field in lines[0], err
    assert "Traceback" not in err and "np." not in err, err
    assert not any(tmp_path.iterdir())
