"""The state file of an `improve` run: the stages done with their wall times, each round's scores and
decision, the settings it was made with; and the stage runner that keeps it, across kills and machines."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from lerobot_gcs_push.files import atomic_path

STATE_FILE = "state.json"
_SAVE_LOCK = threading.Lock()


class StopRequested(Exception):
    """`stop_after` reached: the state is saved and a re-run continues."""


@dataclass
class State:
    path: Path
    stages: dict[str, dict] = field(default_factory=dict)  # name -> {"done", "wall_s", "finished_at", ...}
    rounds: list[dict] = field(default_factory=list)  # per round: rollout scores, decision, hours at its end
    settings: dict = field(default_factory=dict)
    # The stop rule of the latest invocation (it may change on resume, unlike settings): the curve's targets.
    stop: dict = field(default_factory=dict)

    @classmethod
    def load(cls, path: Path) -> State:
        if not path.is_file():
            return cls(path)
        data = json.loads(path.read_text())
        return cls(path, data["stages"], data["rounds"], data.get("settings", {}), data.get("stop", {}))

    def as_dict(self) -> dict:
        return {"settings": self.settings, "stop": self.stop, "stages": self.stages, "rounds": self.rounds}

    def save(self) -> None:
        with _SAVE_LOCK, atomic_path(self.path) as tmp:  # the heartbeat thread saves too, into the same tmp
            tmp.write_text(json.dumps(self.as_dict(), indent=1))

    @property
    def hours(self) -> float:
        return sum(s.get("wall_s", 0.0) for s in self.stages.values()) / 3600

    def done(self, name: str) -> bool:
        return bool(self.stages.get(name, {}).get("done"))

    def run_stage(self, name: str, run: Callable[[], None], stop_after: str | None = None) -> None:
        """Run a stage unless done; its wall time counts toward the budget also when it is killed
        (a heartbeat adds the seconds spent so far), so hours add up across resumes and machines."""
        if self.done(name):
            return
        rec = self.stages.setdefault(name, {"done": False, "wall_s": 0.0})
        self.save()  # a stage killed in its first seconds is still on record as begun
        print(f"\n== {name} (so far {self.hours:.2f} h)", flush=True)
        base, t0 = rec["wall_s"], time.monotonic()
        stop = threading.Event()

        def beat() -> None:
            while not stop.wait(30.0):
                rec["wall_s"] = base + time.monotonic() - t0
                self.save()

        thread = threading.Thread(target=beat, daemon=True)
        thread.start()
        try:
            run()
        finally:
            stop.set()
            thread.join()
            rec["wall_s"] = base + time.monotonic() - t0
            self.save()
        rec.update(done=True, finished_at=time.strftime("%Y-%m-%dT%H:%M:%S"))
        self.save()
        print(f"== {name}: {rec['wall_s'] / 60:.1f} min", flush=True)
        if stop_after == name:
            raise StopRequested(name)
