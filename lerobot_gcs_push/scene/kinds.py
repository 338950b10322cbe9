"""One object per slider kind: what every consumer of a scene would otherwise branch on.

Three kinds, chosen by the scene (`Scene.kind`): the paper's box, which cannot turn (`FixedBox`); a slider
that turns in the Drake sim, the box on a yaw joint or the T (`TurningSlider`); gym-pusht's own T, driven in
its pixels (`GymPushT`). Each owns its state's layout, its success rule and reward, what a run's record keeps
of it, the samplers and planner methods it accepts, and its expert: speeds, replan rule, planner.

Every env reports the same `info` layout: `slider_pose` is always [x, y, heading] (heading 0 for the box, as
gym-pusht always reports its block's pose), beside `box` (x, y) and `finger`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from lerobot_gcs_push.planning import Speeds
    from lerobot_gcs_push.planning.rules import ReplanRule
    from lerobot_gcs_push.scene import Scene

TASK = "Push the red box onto the green goal."  # the box's language instruction, stored with every frame


class SliderKind:
    """What a scene's consumers ask of its slider. Its answers are the paper's box's (`FixedBox`); the kinds
    that turn override them."""

    name = ""
    pose_size = 2  # the planner's slider state: [x, y]; a slider that turns adds its heading
    state_names = ("box_x", "box_y")  # the slider's columns of a dataset's state, after the finger's
    trajectory_keys = ("finger", "box")  # what a run's saved trajectory holds, one row per step
    # Its planner, by name (`planning.factory.PLANNERS` builds it: the planners read the scene, so the scene
    # names them and does not import them), and the methods it accepts.
    planner = "box_gcs"
    methods = ("relaxation", "micp")
    default_expert = "open-loop"  # the paper's: one plan, executed
    cost_to_go = True  # the box planner scores any state (regret, active data)
    hard_starts = True  # the hard samplers' families (`scene.HARD_SAMPLERS`) are drawn for it
    goals_anywhere = True  # a plan may go to any goal position, not only the scene's
    own_resets = False  # starts come from `scene.sample_initial_conditions`, not from the env's resets
    pixel_starts = False  # initial conditions may be gym-pusht's own state vectors (px)
    disturbable = True
    records_coverage = False  # its runs' records hold the share of the goal it covers
    drake_env = True  # its env is this package's Drake env (`sim.env.GcsPushEnv`), registered here
    lerobot_pusht_data = False  # datasets with lerobot/pusht's features (else this package's own)
    drawn_as_outline = False  # figures draw its outline at its pose (the box: squares, with no heading to show)
    # Behaviour the expert keeps (`planning.expert.PlanExpert`): from a far finger plan straight to the goal;
    # replace a plan that detours around the slider.
    stage_first = False
    replace_detours = True

    # The state.
    def slider(self, box, heading: float = 0.0) -> list:
        """The planner's slider state at position `box` (the box: [x, y]; a heading is not its to have)."""
        return list(box)

    def pose(self, slider) -> list:
        """[x, y, heading] of a planner's slider state."""
        return [*slider, 0.0]

    def state(self, pose) -> np.ndarray:
        """The planner's slider state at `pose` [x, y, heading] (an env's `info["slider_pose"]`)."""
        return np.asarray(pose, float)[:2]

    def refuses_heading(self, heading: float) -> bool:
        return heading != 0.0

    def extent(self, scene: Scene) -> float:
        """How far the slider reaches from its centre towards a wall (`Scene.slider_extent`)."""
        return scene.box_half

    def yaw_damping(self, scene: Scene) -> float | None:
        """The sim's yaw joint's damping; None: no yaw joint."""
        return None

    def twist(self, scene: Scene):
        """The shape a disturbance's push also twists (`sim.env.DisturbanceSchedule`); None: it cannot turn."""
        return None

    def task(self, scene: Scene) -> str:
        return TASK

    # Success, reward and records.
    def judge(self, scene: Scene, pose: np.ndarray, distance: float) -> dict:
        """The env's success and the slider's keys of its `info`, at `pose` [x, y, heading]."""
        return {"is_success": bool(distance <= scene.success_threshold), "slider_pose": pose}

    def reward(self, scene: Scene, info: dict) -> float:
        return -info["box_goal_distance"]

    def summary(self, info: dict) -> dict:
        """What a run's record keeps of the slider beyond the box's position (`rollout.rollout`)."""
        return {}

    def success_measures(self, scene: Scene, thresholds) -> tuple[str, str, str, str, str]:
        """`evaluation.success.SuccessMeasures`' fields: the paper's radius and a looser one."""
        thr1, thr2 = thresholds
        return (
            f"success (box within {thr1:g} m)",
            f"success {thr1:g} m",
            f"success_{thr2:g}",
            f"success {thr2:g} m",
            f"success per initial condition ({thr1:g} m / {thr2:g} m)",
        )

    # Text for `gcs-push plan`.
    def solve_time_text(self, seconds: float) -> str:
        return f"{seconds * 1e3:.1f} ms"

    def final_text(self, final) -> str:
        return f"box ends at {final}"

    # Its expert's settings live with the expert (`planning.rules`), which reads the scene.
    def speeds(self, commands: str = "position") -> Speeds:
        from lerobot_gcs_push.planning import Speeds

        return Speeds()

    def replan_rule(self, commands: str = "position") -> ReplanRule:
        from lerobot_gcs_push.planning.rules import BOX_RULE

        return BOX_RULE

    def fine_within(self, scene: Scene) -> float:
        """How near its goal the expert corrects the slider by single pushes: never for the box."""
        return 0.0

    def wrap_expert(self, expert, scene: Scene, config):
        """The policy the env is driven by, around the expert over the scene's metres."""
        return expert


class FixedBox(SliderKind):
    """The paper's box: it slides on x and y and cannot turn; it succeeds within a distance of its goal."""

    name = "box"


class TurningSlider(SliderKind):
    """A slider that turns in the Drake sim (the box on a yaw joint, or the T); it succeeds by covering its
    goal outline, and plans through contact (`contact.ContactPlanner`, the relaxation only)."""

    name = "turning"
    pose_size = 3
    state_names = ("slider_x", "slider_y", "slider_heading")
    trajectory_keys = ("finger", "box", "slider_pose")
    planner = "contact"
    methods = ("relaxation",)
    # Replanned from the measured pose: its plans chain pushes, and a push may end elsewhere.
    default_expert = "closed-loop"
    # No GCS cost-to-go yet: V at every chunk of every rollout means thousands of plans through contact,
    # at 0.4-3 s each.
    cost_to_go = False
    hard_starts = False  # the hard families align the finger with axis-aligned faces: the box's
    goals_anywhere = False  # its relaxation plans to the scene's goal pose only
    drawn_as_outline = True
    records_coverage = True

    def slider(self, box, heading: float = 0.0) -> list:
        return [*box, float(heading)]

    def pose(self, slider) -> list:
        return list(slider)

    def state(self, pose) -> np.ndarray:
        return np.asarray(pose, float)

    def refuses_heading(self, heading: float) -> bool:
        return False

    def extent(self, scene: Scene) -> float:
        # It may point its farthest outline point at any wall, so the workspace grows with it.
        return scene.shape.r_max

    def yaw_damping(self, scene: Scene) -> float | None:
        return scene.rot_damping

    def twist(self, scene: Scene):
        return scene.shape

    def task(self, scene: Scene) -> str:
        return f"Push the red {'T' if scene.slider == 'tee' else 'box'} onto the green outline."

    def judge(self, scene: Scene, pose: np.ndarray, distance: float) -> dict:
        coverage = scene.coverage(pose)
        return {
            "is_success": bool(coverage >= scene.success_coverage),
            "coverage": coverage,
            "position_error": distance,
            "heading_error": scene.heading_error(pose[2]),
            "heading": float(pose[2]),
            "slider_pose": pose,
            "goal_pose": scene.goal_pose,
        }

    def reward(self, scene: Scene, info: dict) -> float:
        return min(info["coverage"] / scene.success_coverage, 1.0)

    def summary(self, info: dict) -> dict:
        return {
            "slider_pose_final": np.asarray(info["slider_pose"]).tolist(),
            "coverage": float(info["coverage"]),
            "heading_error": float(info["heading_error"]),
        }

    def success_measures(self, scene: Scene, thresholds) -> tuple[str, str, str, str, str]:
        # Beside the rule, the mean final coverage: how close the failures came.
        rule = f"coverage >= {scene.success_coverage:g}"
        return f"success ({rule})", "success", "coverage", "mean coverage", f"success ({rule}) / mean coverage"

    def solve_time_text(self, seconds: float) -> str:
        return f"{seconds:.2f} s"

    def final_text(self, final) -> str:
        return f"slider ends at {final} (x, y, heading)"

    def speeds(self, commands: str = "position") -> Speeds:
        from lerobot_gcs_push.planning.rules import TURNING_SPEEDS

        return TURNING_SPEEDS

    def replan_rule(self, commands: str = "position") -> ReplanRule:
        from lerobot_gcs_push.planning.rules import TURNING_RULE

        return TURNING_RULE

    def fine_within(self, scene: Scene) -> float:
        """A slider of several convex parts (the T): 0.25. Near the goal the T's rounding returned plans at 100
        times their bound that took it away and back. With corrections, gym-pusht's episodes were 4 % shorter
        on 40 starts, and the Drake T went 50 / 50 on a fresh set. A convex one (the rotating box): none. Its
        plans there are good, and on 50 starts (seed 5160, side by side) corrections made its episodes 0.9 s
        longer on average, 50 / 50 either way."""
        from lerobot_gcs_push.planning.rules import TEE_FINE_WITHIN

        return TEE_FINE_WITHIN if len(scene.shape.parts) > 1 else 0.0


class GymPushT(TurningSlider):
    """gym-pusht's own T, in its pixels (`scene.frame`): its own resets and starts, no disturbances,
    lerobot/pusht's dataset features, and an expert whose plans become its agent's pixel commands."""

    name = "gym-pusht"
    own_resets = True
    # Its resets may put the agent inside the T, so such a start is valid; and a start may be its state vector.
    pixel_starts = True
    disturbable = False
    lerobot_pusht_data = True
    drake_env = False  # gym-pusht's own, wrapped (`pusht.env.GymPushTTarget`)
    # Its agent starts anywhere, far from the T: planned from near it first (`PlanExpert._plan`). Its
    # detouring replans are kept: replaced, they cost 10 % of its demonstrations an hour (`make bench`'s pusht
    # row, 837 against 929, run back to back) for no failure seen there; the Drake T's went 46 -> 49 of 50.
    stage_first = True
    replace_detours = False

    def speeds(self, commands: str = "position") -> Speeds:
        from lerobot_gcs_push.planning.rules import PUSHT_POSITION_SPEEDS, PUSHT_SPEEDS

        return PUSHT_POSITION_SPEEDS if commands == "position" else PUSHT_SPEEDS

    def replan_rule(self, commands: str = "position") -> ReplanRule:
        from lerobot_gcs_push.planning.rules import PUSHT_POSITION_RULE, TURNING_RULE

        return PUSHT_POSITION_RULE if commands == "position" else TURNING_RULE

    def wrap_expert(self, expert, scene: Scene, config):
        from lerobot_gcs_push.pusht.agent import PixelActions

        return PixelActions(expert, scene.frame, config.commands, config.lead())


FIXED_BOX, TURNING_SLIDER, GYM_PUSHT = FixedBox(), TurningSlider(), GymPushT()


def kind_of(scene: Scene) -> SliderKind:
    """The scene's kind: the one place that reads which slider a scene has."""
    if not scene.rotates:
        return FIXED_BOX
    return TURNING_SLIDER if scene.frame is None else GYM_PUSHT
