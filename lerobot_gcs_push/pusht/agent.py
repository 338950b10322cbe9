"""gym-pusht's agent under its PD control, and the target that lands it on a point some actions later.

The agent is a kinematic circle: contact never moves it, only its controller does. Each action holds a
target u for 10 physics substeps of 0.01 s, each `v += (kp (u - p) - kv v) dt; p += v dt` (gym-pusht's
`step`, then pymunk's integration), so one action maps (p, v) to a linear function of (p, v, u) per axis.
Inverted, it gives the target after which the agent stands exactly where a plan wants it: commanded with
the plan's points themselves, the agent trails them by kv / kp = 0.2 s of motion and cuts its corners.
"""

from __future__ import annotations

import numpy as np

KP, KV = 100.0, 20.0  # gym-pusht's PD gains
DT, SUBSTEPS = 0.01, 10  # its physics step and substeps per action (10 actions a second)


def step_map(kp: float = KP, kv: float = KV, dt: float = DT, substeps: int = SUBSTEPS) -> np.ndarray:
    """The 2 x 3 matrix taking (p, v, u) of one axis to (p, v) one action later."""
    m = np.eye(3)  # rows: p, v, u as linear forms of the start's (p, v, u)
    for _ in range(substeps):
        v = m[1] + (kp * (m[2] - m[0]) - kv * m[1]) * dt
        m = np.stack([m[0] + v * dt, v, m[2]])
    return m[:2]


_MAPS = {1: step_map()}


def target_for(position, velocity, goal, actions: int = 1) -> np.ndarray:
    """The target (px) that, held for `actions` actions, puts the agent, at `position` with `velocity`
    (px, px/s), at `goal`. One action amplifies the move 3.4 times and weighs the velocity by 0.10 s; over
    three, 1.24 times and 0.014 s: targets that barely depend on the agent's velocity."""
    if actions not in _MAPS:
        _MAPS[actions] = step_map(substeps=SUBSTEPS * actions)
    (a, b, c) = _MAPS[actions][0]
    return (np.asarray(goal, float) - a * np.asarray(position, float) - b * np.asarray(velocity, float)) / c


COMMANDS = ("position", "steer")


class PixelActions:
    """An expert in metres acting in a target that takes pixel actions (`scene.frame`): its commands are
    mapped to pixels, everything else (its state from `info`, plans, summaries) is the expert's own.

    `commands` says what an action is. "position": the plan's own point `lead_actions` actions on, a smooth
    position path (the plan's timing bounds its acceleration) that the PD agent trails by about kv / kp =
    0.2 s, so that a lead of two actions puts it on the plan; the target never depends on the agent's
    velocity. "steer": the target that, held `lead_actions` actions, puts the agent on the point the plan
    sends that many actions on (`target_for`), re-solved every action: it inverts the PD, so it amplifies
    the intended move and cancels the agent's velocity, which a policy must then read from its frames
    (experiments/pusht/README.md, "Smoother actions" and "Imitable commands")."""

    def __init__(self, expert, frame, commands: str = "position", lead_actions: int = 2):
        if commands not in COMMANDS:
            raise ValueError(f"unknown commands {commands!r}: choose one of {COMMANDS}")
        if lead_actions < 1:
            raise ValueError(f"lead_actions must be >= 1, got {lead_actions}")
        self.expert, self.frame, self.commands, self.lead_actions = expert, frame, commands, lead_actions

    def __getattr__(self, name):
        return getattr(self.expert, name)

    def reset(self, obs, info: dict, seed: int | None = None) -> None:
        self.expert.reset(obs, info, seed)

    def act(self, obs, info: dict) -> np.ndarray:
        command = self.expert.act(obs, info)  # advances the plan (and replans) whatever is sent
        n = self.lead_actions
        point = self.frame.to_px(command if n == 1 else self.expert.ahead(n))
        if self.commands == "position":
            return point
        return target_for(info["pos_agent"], info["vel_agent"], point, n)
