"""One definition of each shared option (issue 66, item 3): the starts, the output and the expert are nested
configs, reached by their flat names (`--seed`, as every command in the docs types them) and by their nested
ones (`--starts.seed`); records keep the flat names they always had."""

from __future__ import annotations

import dataclasses
import json
import re
import shlex
from pathlib import Path

import pytest

from lerobot_gcs_push.cli import COMMANDS, parse
from lerobot_gcs_push.generate import GenerateConfig
from lerobot_gcs_push.generate.config import OutputConfig, recorded_settings
from lerobot_gcs_push.planning.factory import ExpertConfig
from lerobot_gcs_push.scene.options import StartsConfig
from lerobot_gcs_push.settings import flat_names

REPO = Path(__file__).resolve().parents[1]
SHARED = {"starts": StartsConfig, "expert": ExpertConfig, "output": OutputConfig}
# A command's own option of a shared name, and why it is not the shared one.
OWN = {
    ("evaluate", "overwrite"): "deletes a folder of records (--output_dir), which has no repo_id and always continues",
    ("collect", "seed"): "seeds the choice of branch states; collect's starts are the rollouts' states, no sampler's",
    ("plan", "method"): "the planner's own: plan runs no expert, so has none of its other settings (replanning ...)",
}


def test_each_shared_option_is_declared_once():
    """No command config declares a shared option itself: it nests the one config that does."""
    shared = {f.name for cls in SHARED.values() for f in dataclasses.fields(cls)}
    for name, (cls, _, _) in COMMANDS.items():
        nested = {f.name for f in dataclasses.fields(cls) if f.name in SHARED}
        if not nested:
            continue
        own = {f.name for f in dataclasses.fields(cls)} - nested - {o for c, o in OWN if c == name}
        assert not own & shared, (name, own & shared)
        assert set(flat_names(cls)) >= {f.name for n in nested for f in dataclasses.fields(SHARED[n])} - {"mode"}


@pytest.mark.parametrize(
    "flat, nested",
    [
        (["--seed=7", "--sampler=uniform", "--env_id=GcsPushBoxSE2-v0"],
         ["--starts.seed=7", "--starts.sampler=uniform", "--starts.env_id=GcsPushBoxSE2-v0"]),
        (["--repo_id=local/x", "--resume=true"], ["--output.repo_id=local/x", "--output.resume=true"]),
        (["--expert=closed-loop", "--method=micp", "--replan_tolerance=0.05"],
         ["--expert.mode=closed-loop", "--expert.method=micp", "--expert.replan_tolerance=0.05"]),
        (["--expert", "closed-loop", "--seed", "7"], ["--expert.mode", "closed-loop", "--starts.seed", "7"]),
    ],
)  # fmt: skip
def test_flat_and_nested_flags_build_the_same_config(flat, nested):
    assert parse("generate", flat) == parse("generate", nested)


def test_the_python_api_takes_the_flat_names_too():
    cfg = GenerateConfig(seed=7, repo_id="local/x", expert="closed-loop", commands="steer", env_id="gym_pusht/PushT-v0")
    assert cfg == parse(
        "generate",
        [
            "--seed=7",
            "--repo_id=local/x",
            "--expert=closed-loop",
            "--expert.commands=steer",
            "--env_id=gym_pusht/PushT-v0",
        ],
    )
    assert (cfg.starts.seed, cfg.output.repo_id, cfg.expert.mode, cfg.expert.lead()) == (7, "local/x", "closed-loop", 2)
    # A flat option lands on a given nested config (dataclasses.replace passes every field).
    again = dataclasses.replace(cfg, resume=True)
    assert again.output == OutputConfig(repo_id="local/x", resume=True)


def test_each_commands_defaults_hold_however_the_nested_config_is_given():
    """draccus builds a nested config from its class's defaults once any of its options is given: the
    command's own defaults must come through anyway."""
    assert parse("generate", []).starts.sampler == parse("generate", ["--seed=4"]).starts.sampler == "sobol"
    assert parse("generate", ["--sampler=hard"]).starts.seed == 0
    steer = parse("generate", ["--env_id=gym_pusht/PushT-v0", "--expert.commands=steer"])
    assert steer.expert.lead() == 2 and steer.expert.mode == "closed-loop"  # gym-pusht's kind plans closed-loop
    assert parse("generate", ["--repo_id=local/x"]).output.repo_id == "local/x"
    assert parse("generate", ["--resume=true"]).output.repo_id == "local/gcs_push_box"


def test_the_expert_is_reachable_and_checked_from_generate():
    with pytest.raises(ValueError, match="replan_tolerance"):
        parse("generate", ["--expert.replan_tolerance=0"])
    with pytest.raises(ValueError, match="relaxation only"):
        parse("generate", ["--env_id=GcsPushT-v0", "--method=micp"])
    with pytest.raises(ValueError, match="gym-pusht"):
        parse("generate", ["--expert.commands=steer"])  # the box's expert has no pixel commands
    with pytest.raises(ValueError, match="arrive must be >= 0"):
        parse("generate", ["--expert.arrive=-0.1"])


def test_records_keep_their_flat_names_and_gain_only_what_is_set():
    """A dataset's settings read as before for the same flags; an expert setting is recorded once set."""
    before = {  # what meta/gcs_push_settings.json held before the nesting, for `--seed=5 --expert=closed-loop`
        "env_id", "repo_id", "seed", "expert", "method", "sampler", "initial_conditions", "frames",
        "disturbances", "fps", "image_size", "obs_type", "command_noise_px", "max_sim_time_s", "max_attempts_factor",
    }  # fmt: skip
    plain = recorded_settings(parse("generate", ["--seed=5", "--expert=closed-loop"]))
    assert set(plain) == before and (plain["seed"], plain["expert"]) == (5, "closed-loop")
    tuned = recorded_settings(parse("generate", ["--seed=5", "--expert=closed-loop", "--expert.replan_every=3"]))
    assert tuned == plain | {"replan_every": 3}
    pusht = ["--seed=5", "--expert=closed-loop", "--env_id=gym_pusht/PushT-v0"]
    finished = recorded_settings(parse("generate", [*pusht, "--finish_coverage=0.98"]))
    assert finished == recorded_settings(parse("generate", pusht)) | {"finish_coverage": 0.98, "finish_frames": 20}
    arriving = recorded_settings(parse("generate", [*pusht, "--expert.arrive=0.15"]))
    assert arriving == recorded_settings(parse("generate", pusht)) | {"arrive": 0.15}


def test_a_resume_compares_the_expert_settings(tmp_path):
    from lerobot_gcs_push.generate import WorkDir

    work = WorkDir(tmp_path / "w")
    old = recorded_settings(parse("generate", ["--expert=closed-loop"]))
    work.open(old, resume=False)  # a folder written before the expert's settings were reachable
    work.open(old, resume=True)
    with pytest.raises(ValueError, match="replan_every: 5 -> 3"):
        work.open(old | {"replan_every": 3}, resume=True)


def _doc_commands() -> list[tuple[str, str, list[str]]]:
    """Every `gcs-push COMMAND ...` of the README, docs/, configs/README.md and the Makefile, with its
    continuation lines, as (where, command, args): a flag's value may be quoted (`--box='[2, -1.5]'`)."""
    out = []
    for path in [
        REPO / "README.md",
        REPO / "Makefile",
        *sorted((REPO / "docs").glob("*.md")),
        REPO / "configs/README.md",
    ]:
        text = path.read_text().replace("\\\n", " ")
        for line in text.splitlines():
            for m in re.finditer(
                r"gcs-push (plan|generate|evaluate|collect|improve|demo)"
                r"((?: +--[^\s`|#=']+(?:='[^']*'|=[^\s`|#']*)?(?: +'[^']*'| +[^-\s`|#][^\s`|#]*)?)*)",
                line,
            ):
                args = shlex.split(m.group(2).replace("$(DEMO_ARGS)", ""))
                if not args and line[m.end() : m.end() + 1] == "`":  # named in prose, not a command
                    continue
                if "--help" not in args:  # prints and exits: nothing to parse
                    out.append((path.name, m.group(1), args))
    return out


DOC_COMMANDS = _doc_commands()


def test_the_docs_have_commands_to_check():
    assert len(DOC_COMMANDS) >= 10
    assert {c for _, c, _ in DOC_COMMANDS} >= {"plan", "generate", "evaluate", "improve", "demo"}


@pytest.mark.parametrize(
    "where, command, args", DOC_COMMANDS, ids=[f"{w}: {c} {' '.join(a)}" for w, c, a in DOC_COMMANDS]
)
def test_every_documented_command_parses(where, command, args, monkeypatch):
    """Each documented command's flags are known and its values valid; only a file or Ray the machine lacks
    may stop it (a policy folder the docs train first, Ray not installed)."""
    monkeypatch.chdir(REPO)
    try:
        parse(command, args)
    except (ValueError, FileNotFoundError) as err:
        message = str(err)
        # `give --box` is plan's last check, after every flag's: a table's `plan --jsonl=true` names a flag.
        allowed = r"pretrained_model|does not exist|needs Ray|neither a folder|no runs.jsonl|give --box"
        assert re.search(allowed, message), message
        assert "unrecognized" not in message and "Couldn't parse" not in message, message


def test_a_config_file_may_spell_the_options_nested(tmp_path):
    path = tmp_path / "generate.json"
    path.write_text(json.dumps({"starts": {"seed": 9}, "output": {"repo_id": "local/f"}, "episodes": 3}))
    cfg = parse("generate", [f"--config_path={path}", "--expert=closed-loop"])
    assert (cfg.starts.seed, cfg.output.repo_id, cfg.episodes, cfg.expert.mode) == (9, "local/f", 3, "closed-loop")


def test_evaluate_nests_the_starts_and_the_expert():
    flat = parse("evaluate", ["--policies=[gcs-closed-loop]", "--sampler=hard", "--disturbances=true", "--method=micp"])
    nested = parse(
        "evaluate",
        ["--policies=[gcs-closed-loop]", "--starts.sampler=hard", "--starts.disturbances=true", "--expert.method=micp"],
    )
    assert flat == nested and flat.starts.seed == 3000  # the hard set's seed, as before
    assert parse("evaluate", ["--seed=4"]).starts.sampler == "uniform"  # evaluate's default, whatever is given
    with pytest.raises(ValueError, match="--policies"):  # the policies name the experts' modes
        parse("evaluate", ["--policies=[gcs-closed-loop]", "--expert=open-loop"])
    with pytest.raises(ValueError, match="replan_every"):
        parse("evaluate", ["--policies=[gcs-closed-loop]", "--expert.replan_every=0"])


def test_an_evaluation_records_the_expert_settings_it_was_given(tmp_path, monkeypatch):
    """A folder made with other expert settings is refused, not continued; one made without reads as before."""
    from lerobot_gcs_push.evaluation import EvaluateConfig, evaluate

    monkeypatch.setattr("lerobot_gcs_push.evaluation.protocol._run_all", lambda *a: None)  # no runs: settings only
    monkeypatch.setattr("lerobot_gcs_push.evaluation.protocol.summarize", lambda *a, **k: {}, raising=False)
    common = dict(policies=["gcs-closed-loop"], num_initial_conditions=1, runs=1, output_dir=str(tmp_path / "e"))
    try:
        evaluate(EvaluateConfig(**common))
    except Exception:  # the summary of no runs may fail: the settings are written before
        pass
    settings = json.loads((tmp_path / "e" / "settings.json").read_text())
    assert "replan_every" not in settings and "method" not in settings
    with pytest.raises(FileExistsError, match="other initial conditions or settings"):
        evaluate(EvaluateConfig(**common, replan_every=3))


def test_collect_nests_the_output(tmp_path):
    (tmp_path / "runs.jsonl").write_text("")
    rollouts = f"--rollouts=[{tmp_path}]"
    flat = parse("collect", [rollouts, "--repo_id=local/a", "--resume=true", "--seed=2"])
    assert flat == parse("collect", [rollouts, "--output.repo_id=local/a", "--output.resume=true", "--seed=2"])
    assert parse("collect", [rollouts]).output.repo_id == "local/gcs_push_active"
    with pytest.raises(ValueError, match="not both"):
        parse("collect", [rollouts, "--overwrite=true", "--resume=true"])


def test_plan_nests_the_starts(tmp_path):
    """`--env_id` and `--initial_conditions` are the starts' (`--starts.env_id` too); plan samples nothing, so
    the starts' sampler, seed and disturbances are refused by name."""
    from lerobot_gcs_push.cli import PlanConfig

    box = ["--box=[2.0, -1.0]", "--finger=[-3.0, 0.0]"]
    flat = parse("plan", ["--env_id=GcsPushBoxSE2-v0", *box, "--heading=0.5"])
    assert flat == parse("plan", ["--starts.env_id=GcsPushBoxSE2-v0", *box, "--heading=0.5"])
    assert flat.starts.env_id == "GcsPushBoxSE2-v0" and parse("plan", box).starts.env_id == "GcsPushBox-v0"
    assert flat == PlanConfig(box=(2.0, -1.0), finger=(-3.0, 0.0), env_id="GcsPushBoxSE2-v0", heading=0.5)
    path = tmp_path / "ics.json"
    path.write_text(json.dumps([{"box": [2.0, -1.0], "finger": [-3.0, 0.0]}]))
    from_file = parse("plan", [f"--initial_conditions={path}"])
    assert from_file == parse("plan", [f"--starts.initial_conditions={path}"])
    assert from_file.starts.initial_conditions == str(path)
    with pytest.raises(ValueError, match="not both"):
        parse("plan", [f"--initial_conditions={path}", *box])
    with pytest.raises(ValueError, match="drop --sampler, --seed"):
        parse("plan", [*box, "--sampler=hard", "--starts.seed=3"])
    with pytest.raises(ValueError, match="drop --disturbances"):
        parse("plan", [*box, "--disturbances=true"])
    with pytest.raises(ValueError, match="unknown env_id"):
        parse("plan", [*box, "--env_id=GcsPushNothing-v0"])


def test_demo_nests_the_output(tmp_path, monkeypatch, capsys):
    """`--repo_id`, `--root` and `--overwrite` are the output's (`--output.repo_id` too), the default id still
    the protocol's; the dataset demo writes is where they say, and a resume is what demo always does."""
    from lerobot_gcs_push.cli import DemoConfig, run_demo

    flat = parse("demo", ["--repo_id=local/d", "--overwrite=true"])
    assert flat == parse("demo", ["--output.repo_id=local/d", "--output.overwrite=true"])
    assert flat == DemoConfig(repo_id="local/d", overwrite=True) and flat.output.overwrite
    assert parse("demo", []).output.repo_id == "local/gcs_push_box_quick"
    assert parse("demo", ["--protocol=true", "--output.root=/x"]).output.repo_id == "local/gcs_push_box"
    with pytest.raises(ValueError, match="drop --resume"):
        parse("demo", ["--resume=true"])
    made, evaluated = [], []

    def fake_generate(gen):
        made.append(gen)
        gen.output.path().mkdir(parents=True)

    monkeypatch.setattr("lerobot_gcs_push.cli.run_generate", fake_generate)
    monkeypatch.setattr("lerobot_gcs_push.evaluation.evaluate", lambda ev: evaluated.append(ev) or {"tables_md": ""})
    root = tmp_path / "ds"
    run_demo(DemoConfig(root=str(root), policy="", output_dir=str(tmp_path / "out")))
    (gen,) = made
    assert gen.output == OutputConfig(repo_id="local/gcs_push_box_quick", root=str(root), resume=True)
    assert gen.episodes == 20 and evaluated[0].dataset == str(root)
    assert f"--dataset.repo_id=local/gcs_push_box_quick --dataset.root={root}" in capsys.readouterr().out
