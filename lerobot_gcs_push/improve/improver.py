"""The loop of an improve run: the base stages when it starts from nothing, then rounds of its stages
(`stages.py`) until the targets are met, the rounds are run or the hours are spent."""

from __future__ import annotations

import functools

from lerobot_gcs_push.artifacts.checkpoints import export_policy, is_pretrained_dir
from lerobot_gcs_push.improve.config import STAGES, ImproveConfig
from lerobot_gcs_push.improve.stages import Base, Collect, Decision, Finetune, Merge, Rollouts, Validation
from lerobot_gcs_push.improve.workspace import Workspace


class Improver:
    def __init__(self, cfg: ImproveConfig):
        self.cfg = cfg
        self.ws = Workspace(cfg)
        self.state = self.ws.state
        self.base = Base(self.ws)
        self.rollouts = Rollouts(self.ws)
        self.collect = Collect(self.ws, self.rollouts)
        self.merge = Merge(self.ws, self.base, self.collect)
        self.finetune = Finetune(self.ws, self.merge)
        self.validation = Validation(self.ws, self.finetune)
        self.decision = Decision(self.ws, self.validation)

    def run(self) -> dict:
        from lerobot_gcs_push.improve.curve import CURVE_FILE, plot_curve  # here: `python -m` runs the module

        cfg, ws, state = self.cfg, self.ws, self.state
        shipped = any(r.get("shipped") for r in state.rounds)
        if cfg.from_policy and not is_pretrained_dir(cfg.policy) and not shipped:
            print(f"starting from {cfg.from_policy}: copied to {cfg.policy}")
            export_policy(cfg.from_policy, cfg.policy, overwrite=True)
        # From nothing: a run that began so, or a new run with no policy. A run on its way whose policy
        # folder is missing is refused below, not trained again from nothing.
        if "base.demonstrations" in state.stages or (not state.stages and not is_pretrained_dir(cfg.policy)):
            if not state.stages:
                print(f"no policy at {cfg.policy}: starting from nothing (base demonstrations, then training)")
            ws.stage("base.demonstrations", self.base.dataset)
            ws.stage("base.train", self.base.train)
        elif not state.stages:
            print(f"improving {cfg.policy} in place")
        if not is_pretrained_dir(cfg.policy):
            raise FileNotFoundError(
                f"{cfg.policy} holds no policy although {state.path} records this run's stages: commit or "
                "copy the policy folder with the state folder"
            )
        k = 1
        while state.done(f"r{k}.decision"):
            k += 1
        round_stages = (self.collect, self.merge, self.finetune, self.validation, self.decision)
        while True:
            if k > cfg.stop.max_rounds:
                why = f"{cfg.stop.max_rounds} rounds run"
                break
            if state.hours >= cfg.stop.max_hours:
                why = f"budget of {cfg.stop.max_hours:g} h spent"
                break
            ws.stage(f"r{k}.rollouts", functools.partial(self.rollouts.run, k))
            plot_curve(state.as_dict(), ws.state_dir / CURVE_FILE)
            if self.rollouts.targets_met(k):
                self.decision.record(k, shipped=False, decision=None, targets_met=True)
                why = f"targets met on round {k}'s rollouts"
                break
            for name, stage in zip(STAGES[1:], round_stages):
                ws.stage(f"r{k}.{name}", functools.partial(stage.run, k))
            k += 1
        state.save()
        print(f"\nstopped: {why}; {k - 1} round(s) decided in {state.hours:.2f} h; policy in {cfg.policy}")
        return {"stopped": why, "hours": state.hours, "rounds": state.rounds}
