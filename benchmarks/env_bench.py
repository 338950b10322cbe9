"""Speed of `GcsPushBox-v0` (96x96 pixels, fps 10) and the finger's tracking while pushing.

`run()` returns medians over repeats; nothing is printed. Workloads of `steps` env steps each:
  - push: the finger pushes the box along +x at 0.2 m/s (contact every plant step: the slowest case);
  - free: the finger circles far from the box (no contact);
  - random: a new uniformly random target every second (the finger mostly travels, sometimes hits).
`env_steps_per_s` is the push workload, i.e. the worst case; `env_steps_per_cpu_s` gives each workload
per second of this process's CPU time, the rate on an otherwise idle machine.

Tracking: the finger starts touching the box's left face and is commanded 1 m further in +x along a
ramp at each speed, one target per env step, then held. `lag_m` is the command-finger distance in the
second half of the ramp (median), `box_err_at_stop_m` the box's shortfall from its final target when
the command stops, then the error after holding for 2, 5 and 20 s.
"""

from __future__ import annotations

import os
import time

import numpy as np

from lerobot_gcs_push.sim.env import GcsPushEnv

# Scene.validate_state rejects any negative gap, and box - contact_distance can round to -4e-16.
_CLEARANCE = 1e-9


def _rate(env, commands, box, finger) -> tuple[float, float]:
    """Env steps per second of wall-clock time and of this process's CPU time (renderer threads included;
    unlike wall-clock time it does not drop when other processes share the cores)."""
    env.reset(options={"box": box, "finger": finger})
    wall, cpu = time.perf_counter(), time.process_time()
    for command in commands:
        env.step(command)
    return len(commands) / (time.perf_counter() - wall), len(commands) / (time.process_time() - cpu)


def _workloads(env, steps: int) -> dict:
    s = env.scene
    t = np.arange(1, steps + 1) / env.fps
    box = np.array([-3.0, 0.0])
    finger = box - [s.contact_distance + _CLEARANCE, 0.0]
    push = finger + np.outer(0.2 * t, [1.0, 0.0])
    centre, radius = np.array([-3.0, -3.0]), 1.5
    free = centre + radius * np.stack([np.cos(0.5 * t), np.sin(0.5 * t)], axis=1)
    rng = np.random.default_rng(0)
    targets = rng.uniform(-s.finger_limit, s.finger_limit, size=(steps // env.fps + 1, 2))
    random = targets[(np.arange(steps) // env.fps)]
    return {
        "push": (push, box, finger),
        "free": (free, np.array([3.0, 3.0]), centre + [radius, 0.0]),
        "random": (random, np.array([0.0, 0.0]), np.array([-4.0, -4.0])),
    }


def tracking(env, speeds=(0.2, 0.5, 1.0), distance: float = 1.0) -> dict:
    s = env.scene
    out = {}
    for v in speeds:
        box = np.array([-1.0, 0.0])
        finger = box - [s.contact_distance + _CLEARANCE, 0.0]
        env.reset(options={"box": box, "finger": finger})
        n = int(np.ceil(distance / v * env.fps))
        lags = []
        for k in range(1, n + 1):
            command = finger + [distance * k / n, 0.0]
            _, _, _, _, info = env.step(command)
            lags.append(command[0] - info["finger"][0])
        target = box[0] + distance
        result = {
            "lag_m": float(np.median(lags[n // 2 :])),
            "max_lag_m": float(np.max(lags)),
            "box_err_at_stop_m": float(info["box"][0] - target),
        }
        held = 0.0
        for hold_s in (2.0, 5.0, 20.0):
            while held < hold_s - 1e-9:
                _, _, _, _, info = env.step(finger + [distance, 0.0])
                held += 1 / env.fps
            result[f"box_err_after_{hold_s:g}s_m"] = float(info["box"][0] - target)
        result["box_y_drift_m"] = float(abs(info["box"][1] - box[1]))
        out[f"{v:g}_m_per_s"] = result
    return out


def run(repeats: int = 3, steps: int = 300) -> dict:
    env = GcsPushEnv()  # pixels_agent_pos, 96x96, fps 10
    env.reset(seed=0)
    env.step(env.sim.finger_position())  # warm up the renderer
    rates, cpu_rates = {}, {}
    for name, workload in _workloads(env, steps).items():
        samples = np.array([_rate(env, *workload) for _ in range(repeats)])
        rates[name], cpu_rates[name] = (float(x) for x in np.median(samples, axis=0))

    def per_call_ms(fn, n=200):
        start = time.perf_counter()
        for i in range(n):
            fn(i)
        return (time.perf_counter() - start) / n * 1e3

    reset_ms = float(np.median([per_call_ms(lambda i: env.reset(seed=i)) for _ in range(repeats)]))

    def moved(i):  # a new state without simulating (reset costs ~0.05 ms), to time rendering alone
        env.sim.reset(np.zeros(2), np.array([-4.0 + 1e-3 * (i % 100), -4.0]))

    image_ms = float(np.median([per_call_ms(lambda i: (moved(i), env.sim.image())) for _ in range(repeats)]))
    render_ms = float(np.median([per_call_ms(lambda i: (moved(i), env.render()), n=30) for _ in range(repeats)]))
    result = {
        "env_steps_per_s": rates["push"],
        "real_time_factor": rates["push"] / env.fps,
        "env_steps_per_s_free": rates["free"],
        "env_steps_per_s_random": rates["random"],
        "env_steps_per_cpu_s": cpu_rates,
        "load_average_1min": os.getloadavg()[0],
        "reset_ms": reset_ms,
        "image_96_ms": image_ms,
        "render_384_ms": render_ms,
        "tracking": tracking(env),
    }
    env.close()
    return result
